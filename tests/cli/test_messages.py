"""What the command line tells a user: -q, the help of every option, the advice it gives.

The library calls are replaced by fakes where the words are all that is checked; the resume
test tracks a 10-frame drive.
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
    # no summary, no bar; the warning on stderr
    assert r.output == "monovo: WARNING: gt.tum: matches only 60 of 80 frames\n"
    assert [rec.getMessage() for rec in caplog.records if rec.levelno == logging.WARNING] == [
        "gt.tum: matches only 60 of 80 frames"]


def _option_help(command: str, option: str) -> str:
    """The help of ``monovo command``'s ``option``, on one line."""
    r = CliRunner().invoke(main, [command, "--help"], terminal_width=400)
    assert r.exit_code == 0, r.output
    lines = [line.strip() for line in r.output.splitlines()]
    start = next(i for i, line in enumerate(lines) if line.startswith(option))
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("-")), len(lines))
    return " ".join(lines[start:end])


def test_synth_frames_help_states_the_minimum_the_check_applies(tmp_path):
    text = _option_help("synth", "--frames")
    assert "x>=1" not in text and "at least 2" in text and "at least 1" in text, text
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "d"), "--frames", "1", "-q"])
    assert r.exit_code == 2 and ">= 2" in r.output and len(r.output.splitlines()) == 1, r.output
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "p"), "--preset", "pairs", "--frames", "0",
                                  "-q"])
    assert r.exit_code == 2 and ">= 1" in r.output, r.output
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "p"), "--preset", "pairs", "--frames", "1",
                                  "--size", "64x64", "-q"])
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "p").rglob("*.png"))) == 2


def test_init_refuses_the_tracking_choices_a_model_does_not_hold(monkeypatch, tmp_path):
    """A model holds frame 0's points (--levels, --threshold, --max-points); --robust and
    --reanchor-fraction are choices of the tracking, which 'track --model' takes itself."""
    def fake_init(*args, **kwargs):
        raise AssertionError("init ran")

    monkeypatch.setattr(track, "init_model", fake_init)
    for args in (["--robust", "tukey"], ["--reanchor-fraction", "0.3"], ["--no-photometric"]):
        r = CliRunner().invoke(main, ["init", "seq", "-o", str(tmp_path / "m.npz"), *args])
        assert r.exit_code == 2, r.output
        assert f"{args[0]} for init: it is a tracking choice" in r.output and "monovo track" in r.output
    text = CliRunner().invoke(main, ["init", "--help"]).output
    assert "--robust" not in text and "--reanchor-fraction" not in text
    assert "--robust" in CliRunner().invoke(main, ["track", "--help"]).output


def test_every_choice_option_shows_all_its_choices_in_help():
    import re

    import click

    checked = 0
    for name, command in main.commands.items():
        ctx = click.Context(command, info_name=name)
        for p in command.params:
            if isinstance(p, click.Option) and isinstance(p.type, click.Choice):
                shown = " ".join(p.get_help_record(ctx))
                words = set(re.findall(r"[\w-]+", shown))
                missing = [c for c in p.type.choices if c not in words]
                assert not missing, f"monovo {name} {p.opts[0]}: help omits {missing}: {shown}"
                checked += 1
    assert checked >= 8


def test_align_before_the_files_says_where_it_goes():
    r = CliRunner().invoke(main, ["eval", "--align", "out", "gt.tum"])
    assert r.exit_code == 2, r.output
    assert "expected none, se3 or sim3, got 'out'; --align alone (se3) goes after the files" in \
        r.output


def test_every_option_has_help():
    import click

    for name, command in main.commands.items():
        for p in command.params:
            if isinstance(p, click.Option) and p.name != "help":
                assert (p.help or "").strip(), f"monovo {name} {p.opts[0]} has no help"


def test_max_step_shows_its_default_and_max_points_its_minimum():
    from monovo_cli.core.options import TrackOptions

    assert TrackOptions().max_step_m is None  # the default the help states
    for command in ("track", "batch"):
        assert "[default: no limit]" in _option_help(command, "--max-step")
        least = TrackOptions().min_points
        assert f"at least {least}" in _option_help(command, "--max-points")
    assert f"at least {TrackOptions().min_points}" in _option_help("init", "--max-points")


def test_batch_advises_resume_with_skip_bad_frames_not_overwrite(monkeypatch, tmp_path, caplog):
    """A bad frame's advice in a batch: --resume --skip-bad-frames redoes the failed sequence
    and keeps the complete ones; --overwrite is more than needed (and excludes --resume)."""
    import monovo_cli.pipeline.batch as batch

    error = ("s1/frames/frame_000003.png: cannot read the image; rerun recording unreadable "
             "frames as lost and replacing these outputs")

    def fake_batch(root, out, options, **kw):
        logging.getLogger("monovo_cli.pipeline.batch").warning("%s: %s", "s1", error)
        failed = {"sequence": "s1", "status": "failed", "error": error, "error_kind": "input"}
        return batch.BatchSummary([failed], 0.1, tmp_path / "summary.csv", "local", 1)

    monkeypatch.setattr(batch, "run_batch", fake_batch)
    r = CliRunner().invoke(main, ["batch", "root", "-o", str(tmp_path / "b"), "-q"])
    assert r.exit_code == 2, r.output
    [warned] = [m for m in caplog.messages if m.startswith("s1: ")]
    assert warned.endswith("rerun the batch with --resume --skip-bad-frames to record bad "
                           "frames as lost and go on"), warned
    assert "--overwrite" not in warned


def _interrupted(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_names_resume(monkeypatch, tmp_path):
    import monovo_cli.pipeline.batch as batch

    monkeypatch.setattr(track, "track_sequence", _interrupted)
    monkeypatch.setattr(batch, "run_batch", _interrupted)
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["track", "seq", "-o", str(out)])
    assert r.exit_code == 130, r.output
    assert r.output.strip().splitlines()[-1] == (
        f"monovo: interrupted; the frames done so far are in {out}; continue with the same "
        "command and --resume")
    r = CliRunner().invoke(main, ["track", "seq", "-o", str(out), "--checkpoint-every", "0"])
    assert r.exit_code == 130 and "--resume" not in r.output, r.output  # nothing to continue
    r = CliRunner().invoke(main, ["track", "seq", "-o", "-"])
    assert r.exit_code == 130 and "--resume" not in r.output, r.output
    r = CliRunner().invoke(main, ["batch", "root", "-o", str(out)])
    assert r.exit_code == 130, r.output
    assert "continue with the same command and --resume" in r.output


def test_a_resumed_run_says_where_it_continues(small_drive, tmp_path):
    from monovo_cli.core.options import TrackOptions

    out = tmp_path / "out"

    def stop_after_six(done, total):
        if done == 6:
            raise KeyboardInterrupt

    try:
        track.track_sequence(small_drive, None, out, TrackOptions(), checkpoint_every=4,
                             progress=stop_after_six)
    except KeyboardInterrupt:
        pass
    args = ["track", str(small_drive), "-o", str(out), "--checkpoint-every", "4", "--resume"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert f"monovo: resuming at frame 4 of 10 from the checkpoint in {out}" in r.output
    r = CliRunner().invoke(main, ["track", str(small_drive), "-o", str(tmp_path / "new"),
                                  "--resume", "-q"])
    assert r.exit_code == 0 and r.output == "", r.output  # -q: nothing but warnings
    r = CliRunner().invoke(main, ["track", str(small_drive), "-o", str(tmp_path / "new2"),
                                  "--resume"])
    assert f"monovo: no checkpoint in {tmp_path / 'new2'}; starting at frame 0 of 10" in r.output


def _fake_synthesize(out, *, progress=None, **kwargs):
    progress(1, 2)
    logging.getLogger("monovo_cli.synth.write").warning("a warning between two frames")
    progress(2, 2)
    return SimpleNamespace(sequences=1, frames_per_sequence=2)


def test_no_progress_bar_when_stderr_is_not_a_terminal(monkeypatch, tmp_path):
    import monovo_cli.synth.write as write

    monkeypatch.setattr(write, "synthesize", _fake_synthesize)
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "s")])  # CliRunner: no terminal
    assert r.exit_code == 0, r.output
    assert "\r" not in r.output and "frame/s" not in r.output, repr(r.output)
    assert r.output.endswith(f"wrote 1 sequence(s) of 2 frames to {tmp_path / 's'}\n")


def test_on_a_terminal_log_lines_go_above_the_bar(monkeypatch, tmp_path):
    import monovo_cli.cli.group as group
    import monovo_cli.synth.write as write

    monkeypatch.setattr(write, "synthesize", _fake_synthesize)
    monkeypatch.setattr(group, "_stderr_is_terminal", lambda: True)
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "s")])
    assert r.exit_code == 0, r.output
    assert "0/2" in r.output, repr(r.output)  # the bar is drawn
    # the warning is a whole line of its own: tqdm clears the bar's line, writes it, redraws
    assert "\rmonovo: WARNING: a warning between two frames\n" in r.output, repr(r.output)
