"""monovo's output files (io/formats.py): the units they are written in."""

from __future__ import annotations

import csv

import numpy as np

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
