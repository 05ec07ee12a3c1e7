"""The sample sequences track to the committed outputs.

Refactors must not move a number. When a change to the estimator is meant to move them,
regenerate the files with `python tests/test_golden.py` and say why in the commit.

Not byte for byte: OpenCV and numpy pick their SIMD kernels by CPU, so another machine rounds
differently (measured between two AMD EPYC machines, AVX2 and AVX-512: a pair's point count
160489 against 160488; over the 60-frame drives each motion within 2.2e-5 m and 0.001 deg,
the composed poses within 0.3 mm, the iterations by one). So: the same frames, statuses and
reasons; each motion within 5e-5 m + 1e-4 of its translation and 0.002 deg; points within
0.1 %, iterations within 1, msd within 1 %; the trajectories' positions within 0.1 mm + 0.05 %
of the path so far and their quaternions within 3e-4. The reported stds only within a factor
of 3: the keyframe plane's covariance is calibrated by medians over the re-anchors so far
(motion_covariance.PlaneCovarianceCalibration), a single sample after the first, in which a rounding
shows (measured: std_rz 2.5x on the exposure drive's frame 19, 1.5-2x until frame 32).
"""

import csv
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "data" / "golden"
SEQUENCES = ("navcam_drive", "exposure_drive", "paper_pairs/pair_0000", "paper_pairs/pair_0001",
             "paper_pairs/pair_0002")
FILES = ("motion.csv", "trajectory.csv", "trajectory.tum")


def _track(seq: str, out: Path) -> None:
    r = CliRunner().invoke(main, ["track", str(ROOT / "sample_sequences" / seq), "-o", str(out),
                                  "-q", "--overwrite"])
    assert r.exit_code == 0, r.output


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _column(rows: list[dict[str, str]], names) -> np.ndarray:
    return np.array([[float(r[c]) if r[c] else np.nan for c in names] for r in rows])


def _compare_motion(got: Path, want: Path) -> None:
    g, w = _rows(got), _rows(want)
    assert [(r["frame"], r["status"], r["reason"]) for r in g] == \
        [(r["frame"], r["status"], r["reason"]) for r in w]
    tg, tw = _column(g, ("tx", "ty", "tz")), _column(w, ("tx", "ty", "tz"))
    np.testing.assert_allclose(tg, tw, rtol=1e-4, atol=5e-5)
    np.testing.assert_allclose(_column(g, ("rx", "ry", "rz")), _column(w, ("rx", "ry", "rz")),
                               rtol=0, atol=2e-3)
    np.testing.assert_allclose(_column(g, ("points",)), _column(w, ("points",)), rtol=1e-3)
    np.testing.assert_allclose(_column(g, ("iterations",)), _column(w, ("iterations",)), atol=1)
    np.testing.assert_allclose(_column(g, ("msd",)), _column(w, ("msd",)), rtol=1e-2)
    std = ("std_tx", "std_ty", "std_tz", "std_rx", "std_ry", "std_rz")
    ratio = _column(g, std) / _column(w, std)
    ok = np.isfinite(ratio)
    assert np.array_equal(ok, np.isfinite(_column(w, std)))
    assert np.all((ratio[ok] > 1 / 3) & (ratio[ok] < 3.0))


def _compare_tum(got: Path, want: Path) -> None:
    g, w = np.loadtxt(got, ndmin=2), np.loadtxt(want, ndmin=2)
    assert g.shape == w.shape
    np.testing.assert_array_equal(g[:, 0], w[:, 0])
    path = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(w[:, 1:4], axis=0), axis=1))]
    assert np.all(np.linalg.norm(g[:, 1:4] - w[:, 1:4], axis=1) <= 1e-4 + 5e-4 * path)
    np.testing.assert_allclose(g[:, 4:], w[:, 4:], rtol=0, atol=3e-4)


def _compare_trajectory_csv(got: Path, want: Path) -> None:
    g, w = _rows(got), _rows(want)
    assert [(r["frame"], r["timestamp"]) for r in g] == [(r["frame"], r["timestamp"]) for r in w]


@pytest.mark.parametrize("seq", SEQUENCES)
def test_sample_outputs_match_the_golden_files(seq, tmp_path):
    _track(seq, tmp_path)
    golden = GOLDEN / seq.replace("/", "_")
    _compare_motion(tmp_path / "motion.csv", golden / "motion.csv")
    _compare_tum(tmp_path / "trajectory.tum", golden / "trajectory.tum")
    _compare_trajectory_csv(tmp_path / "trajectory.csv", golden / "trajectory.csv")
    # trajectory.csv holds the poses of trajectory.tum, with frame numbers
    tum = np.loadtxt(tmp_path / "trajectory.tum", ndmin=2)
    rows = _column(_rows(tmp_path / "trajectory.csv"), ("tx", "ty", "tz", "qx", "qy", "qz", "qw"))
    np.testing.assert_allclose(rows, tum[:, 1:], rtol=0, atol=1e-9)


if __name__ == "__main__":  # regenerate: python tests/test_golden.py
    for seq in SEQUENCES:
        out = GOLDEN / seq.replace("/", "_")
        tmp = out.with_name(out.name + ".tmp")
        _track(seq, tmp)
        out.mkdir(parents=True, exist_ok=True)
        for name in FILES:
            shutil.copyfile(tmp / name, out / name)
        shutil.rmtree(tmp)
    sys.exit(0)
