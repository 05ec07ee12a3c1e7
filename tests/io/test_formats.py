"""monovo's output files (io/formats.py): the units and number formats they are written in."""

from __future__ import annotations

import csv

import numpy as np

from monovo_cli.io.formats import tum_text
from tests.helpers.cli import run


def test_covariance_is_in_degrees_like_every_other_output(small_drive, tmp_path):
    out = tmp_path / "out"
    code, output = run("track", small_drive, "-o", out, "-q", "--covariance", out / "cov.csv")
    assert code == 0, output
    rows = list(csv.reader((out / "cov.csv").open()))[1:]
    with (out / "motion.csv").open() as f:
        motion = list(csv.DictReader(f))
    axes = ("tx", "ty", "tz", "rx", "ry", "rz")
    stds = np.array([[float(m[f"std_{a}"]) for a in axes] for m in motion])
    cov_std = np.array([np.sqrt(np.diag(np.array(r[1:], float).reshape(6, 6))) for r in rows])
    np.testing.assert_allclose(cov_std, stds, rtol=1e-9)  # std_rx.. are in degrees


def _decimals(field: str) -> int:
    assert "e" not in field.lower(), field  # fixed-point, never scientific
    return len(field.split(".")[1]) if "." in field else 0


def test_frame_0_is_exactly_the_identity_and_timestamps_share_one_format(synth_drive, tmp_path):
    # a drive whose smoothed frame 0 came out 1e-16 off the identity
    seq = synth_drive(preset="drive", frames=14, size=(128, 128), seed=5)
    out = tmp_path / "out"
    code, output = run("track", seq, "-o", out, "-q")
    assert code == 0, output
    tum = (out / "trajectory.tum").read_text().splitlines()
    assert len(tum) == 14
    first = tum[0].split(" ")
    assert [float(v) for v in first[1:]] == [0, 0, 0, 0, 0, 0, 1]  # exactly, not -6.66e-17
    assert len({_decimals(line.split(" ")[0]) for line in tum}) == 1, [ln[:8] for ln in tum]
    with (out / "trajectory.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [float(rows[0][c]) for c in ("tx", "ty", "tz", "qx", "qy", "qz", "qw")] == \
        [0, 0, 0, 0, 0, 0, 1]
    assert len({_decimals(r["timestamp"]) for r in rows}) == 1
    # the same times as before, only written alike
    np.testing.assert_array_equal([float(ln.split(" ")[0]) for ln in tum], np.arange(14.0))


def test_timestamps_keep_their_precision_in_one_format():
    ts = [0.0, 0.05, 1403636579.7635555, 2.5]
    text = tum_text(ts, [np.eye(4)] * len(ts))
    fields = [line.split(" ")[0] for line in text.splitlines()]
    assert fields == ["0.0000000", "0.0500000", "1403636579.7635555", "2.5000000"]
    assert [float(v) for v in fields] == ts
    near = np.eye(4)
    near[:3, 3] = [-6.66e-17, 1e-16, 0.0]
    assert tum_text([0.0], [near]) == "0.0 0 0 0 0 0 0 1.0\n"  # the rounding of compositions
    assert tum_text([1 / 3], [np.eye(4)]).startswith("0.333333333 ")  # at most ns
