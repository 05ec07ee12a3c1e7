"""Errors by travelled distance against the KITTI odometry devkit's definition, by hand.

The drive: the truth moves 1 m along x per frame, never turning (frames 0..5, path
lengths 0, 1, ..., 5 m). The estimate moves 1.1 m per frame along x and rolls about x by
a = 0.001 rad per frame: ``E_k = [Rx(a k) | 1.1 k e_x]``. Between frames i and j = i + d:

* truth: ``inv(G_i) G_j = [I | d e_x]``;
* estimate: ``inv(E_i) E_j = [Rx(a d) | Rx(-a i) 1.1 d e_x] = [Rx(a d) | 1.1 d e_x]``
  (a rotation about x leaves e_x alone);
* error ``inv(estimate) truth = [Rx(-a d) | Rx(-a d)(d - 1.1 d) e_x]``: translation
  ``0.1 d``, rotation angle ``a d``.

The devkit's last frame of a segment of length L from i is the first j whose path length
exceeds ``dist[i] + L`` strictly: for L = 1 m that is j = i + 2 (i + 1 is at exactly 1 m),
for L = 2 m j = i + 3. Errors per metre: L = 1: 0.1 * 2 / 1 = 0.2 and 2a / 1;
L = 2: 0.1 * 3 / 2 = 0.15 and 3a / 2. First frames: for L = 1, i = 0..3 (j <= 5), 4 pairs;
for L = 2, i = 0..2, 3 pairs.
"""

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.evaluation.segments import distances, segment_errors

A = 0.001  # rad of roll per frame


def _poses():
    gt, est = [], []
    for k in range(6):
        G = np.eye(4)
        G[0, 3] = 1.0 * k
        c, s = math.cos(A * k), math.sin(A * k)
        E = np.eye(4)
        E[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
        E[0, 3] = 1.1 * k
        gt.append(G)
        est.append(E)
    return np.array(est), np.array(gt)


def test_segments_by_hand():
    est, gt = _poses()
    np.testing.assert_array_equal(distances(gt), [0, 1, 2, 3, 4, 5])
    seg = segment_errors(est, gt, (1.0, 2.0))
    np.testing.assert_array_equal(seg.first, [0, 0, 1, 1, 2, 2, 3])
    np.testing.assert_array_equal(seg.last, [2, 3, 3, 4, 4, 5, 5])
    np.testing.assert_allclose(seg.translation, [0.2, 0.15, 0.2, 0.15, 0.2, 0.15, 0.2], atol=1e-12)
    np.testing.assert_allclose(seg.rotation, [2 * A, 1.5 * A, 2 * A, 1.5 * A, 2 * A, 1.5 * A,
                                              2 * A], rtol=1e-6)
    s = seg.summary()
    assert s["segments"] == 7
    assert s["translation_pct"] == pytest.approx(100 * (4 * 0.2 + 3 * 0.15) / 7)  # 17.857 %
    assert s["rotation_deg_per_m"] == pytest.approx(math.degrees((4 * 2 * A + 3 * 1.5 * A) / 7),
                                                    rel=1e-6)
    one, two = s["by_length"]
    assert (one["length_m"], one["segments"], two["segments"]) == (1.0, 4, 3)
    assert one["translation_pct"] == pytest.approx(20.0)
    assert two["translation_pct"] == pytest.approx(15.0)
    # the devkit's step: first frames 0, 2, 4 -> L = 1: i = 0, 2; L = 2: i = 0, 2
    stepped = segment_errors(est, gt, (1.0, 2.0), step=2).summary()
    assert stepped["segments"] == 4
    assert stepped["translation_pct"] == pytest.approx(100 * (2 * 0.2 + 2 * 0.15) / 4)
    # a length longer than the drive has no segment
    assert segment_errors(est, gt, (10.0,)).summary()["by_length"][0]["translation_pct"] is None


def test_kitti_pose_files_through_the_command(tmp_path):
    est, gt = _poses()
    for name, poses in (("est.txt", est), ("gt.txt", gt)):
        (tmp_path / name).write_text("".join(" ".join(repr(float(v)) for v in T[:3].ravel())
                                             + "\n" for T in poses))
    r = CliRunner().invoke(main, ["eval", str(tmp_path / "est.txt"), str(tmp_path / "gt.txt"),
                                  "--segments", "2,1", "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["inputs"]["estimate"]["format"] == "kitti" and d["pairing"] == "frame"
    assert d["segments"]["segments"] == 7
    assert d["segments"]["translation_pct"] == pytest.approx(100 * 1.25 / 7)
    assert [m["length_m"] for m in d["segments"]["by_length"]] == [1.0, 2.0]
    r = CliRunner().invoke(main, ["eval", str(tmp_path / "est.txt"), str(tmp_path / "gt.txt"),
                                  "--segments", "1,2"])
    assert r.exit_code == 0, r.output
    assert "6 poses paired by frame number (of 6 estimated, 6 true)" in r.output
    assert "17.8571" in r.output  # the pooled translation error, %
