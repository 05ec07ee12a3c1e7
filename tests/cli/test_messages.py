"""What the command line tells a user: -q, the help of every option, the advice it gives.

The library calls are replaced by fakes where the words are all that is checked, so these
tests run in well under a second each.
"""

from __future__ import annotations

import logging
from types import SimpleNamespace

from click.testing import CliRunner

import monovo_cli.pipeline.track as track
from monovo_cli.cli import main


def test_quiet_hides_progress_and_summary_but_not_warnings(monkeypatch, tmp_path, caplog):
    def fake_track(seq, params, out_dir, options, *, progress=None, **kw):
        logging.getLogger("monovo_cli.pipeline.preflight").warning(
            "gt.tum: matches only 60 of 80 frames")
        progress(1, 2)
        return SimpleNamespace(frames=2, seconds=1.0, fps=2.0, mean_msd=0.5, reanchored=0,
                               reinit=0, lost=0, path_length=0.1, mostly_lost=False)

    monkeypatch.setattr(track, "track_sequence", fake_track)
    caplog.set_level(logging.DEBUG)
    r = CliRunner().invoke(main, ["track", "seq", "-o", str(tmp_path / "o"), "-q"])
    assert r.exit_code == 0, r.output
    assert r.output == ""  # no summary, no bar
    assert [rec.getMessage() for rec in caplog.records if rec.levelno == logging.WARNING] == [
        "gt.tum: matches only 60 of 80 frames"]
