"""benchmarks.peers reads monovo's failures from motion.csv's status column.

A lost row holds the motion monovo predicted when it gave up, a finite pose like any other:
only its status says it is no estimate. The drive table counts it as a failure, as a peer's
missing homography, and leaves it out of the mean error; reinit rows are counted beside.
"""

from __future__ import annotations

import shutil

import numpy as np

from benchmarks import peers


def _fake_track(lost: set[int], reinit: set[int]):
    """A stand-in for ``track_sequence`` writing the ground truth as its result, the rows of
    ``lost`` replaced by the previous frame's motion (a constant-velocity prediction) and
    marked lost, those of ``reinit`` marked reinit."""

    def track(seq, params, out, options, **kw):
        out.mkdir(parents=True)
        lines = (seq / "groundtruth_motion.csv").read_text().splitlines()
        head, rows = lines[0], [line.split(",") for line in lines[1:]]
        for i, row in enumerate(rows):
            frame = int(row[0])
            if frame in lost:
                row[1:7] = rows[i - 1][1:7]
                row[10] = "lost"
            elif frame in reinit:
                row[10] = "reinit"
        (out / "motion.csv").write_text("\n".join([head] + [",".join(r) for r in rows]) + "\n")
        shutil.copy(seq / "groundtruth.tum", out / "trajectory.tum")

    return track


def test_monovo_on_drive_counts_lost_rows_as_failures(small_drive, tmp_path, monkeypatch):
    monkeypatch.setattr(peers, "track_sequence", _fake_track(lost={3, 4}, reinit={5}))
    r = peers.monovo_on_drive(small_drive, tmp_path / "out")
    assert r.count == 10
    assert r.failed == 2
    assert r.reinit == 1
    assert np.isnan(r.errors[[2, 3], 0]).all() and not np.isnan(np.delete(r.errors, [2, 3], 0)).any()
    # the other rows are the truth: the predictions' errors are not in the mean
    np.testing.assert_allclose(r.mean_abs(), 0.0, atol=1e-9)
    assert "| 2; 1 reinit |" in peers.drive_table([r])
