"""evaluate_drive: the coverage rule, APE/RPE, the pairing by frame, the reported std's band."""

import numpy as np
import pytest

from monovo_cli.errors import InputError
from monovo_cli.evaluation.drive import ReportedMotions, StdBand, evaluate_drive, std_band
from monovo_cli.evaluation.metrics import error_stats, relative_pose_errors
from monovo_cli.evaluation.sync import check_coverage, coverage
from monovo_cli.geometry.lie import pose_from_vectors, se3_inv, so3_log
from tests.evaluation.test_evaluate import _drive


def test_a_sparse_truth_is_refused_unless_partial():
    ts, gt = _drive(60)
    fast = ts / 10.0  # a 10 fps run of 5.9 s ...
    sparse = np.arange(0.0, 6.0, 1.0)  # ... against 1 Hz ground truth: 6 poses match
    gt_sparse = gt[::10][:6]
    with pytest.raises(InputError, match=r"only 6 of its 60 poses match ground truth \(within "
                                         r"0\.02 s; max_dt sets the tolerance\), spanning 5 of "
                                         r"its 5\.9 s; .*allow a partial match"):
        evaluate_drive(fast, gt, sparse, gt_sparse)
    dr = evaluate_drive(fast, gt, sparse, gt_sparse, partial=True)
    assert dr.partial and dr.evaluation.poses == 6
    assert dr.as_dict()["partial"] is True
    full = evaluate_drive(ts, gt, ts, gt)
    assert not full.partial and full.as_dict()["partial"] is False


def test_the_coverage_rule_counts_poses_and_span():
    keys = np.arange(10.0)
    assert coverage(keys, np.arange(5)) == (0.5, pytest.approx(4 / 9))
    with pytest.raises(InputError, match="only 5 of its 10 poses.*spanning 4 of its 9 s"):
        check_coverage(keys, np.arange(5), by_time=True, max_dt=0.1)
    check_coverage(keys, np.arange(0, 10, 2), by_time=True, max_dt=0.1)  # half, spanning 8 s
    with pytest.raises(InputError, match=r"only 4 of its 10 poses.*\(by frame number\).*frames"):
        check_coverage(keys, np.arange(0, 10, 3), by_time=False, max_dt=0.1)
    # a short run inside a long truth is a whole run: the rule is the estimate's
    ts, gt = _drive(50)
    assert evaluate_drive(ts[10:20], gt[10:20], ts, gt).evaluation.poses == 10


def test_rpe_and_ape_agree_with_their_definitions():
    ts, gt = _drive(30)
    est = gt.copy()
    est[:, :3, 3] *= 1.02  # 2 % too long
    t, r = relative_pose_errors(est, gt)
    steps = np.linalg.norm([(se3_inv(gt[k]) @ gt[k + 1])[:3, 3] for k in range(29)], axis=1)
    np.testing.assert_allclose(t, 0.02 * steps, rtol=1e-9)
    np.testing.assert_allclose(r, 0.0, atol=1e-6)
    dr = evaluate_drive(ts, est, ts, gt)
    np.testing.assert_allclose(dr.ape, 0.02 * np.linalg.norm(gt[:, :3, 3], axis=1), atol=1e-12)
    assert dr.as_dict()["ape"]["translation_m"]["max"] == pytest.approx(dr.ape.max())
    s = error_stats(np.r_[3.0, 4.0])
    assert s == {"rmse": pytest.approx(np.sqrt(12.5)), "mean": 3.5, "median": 3.5,
                 "std": 0.5, "min": 3.0, "max": 4.0}
    # sim3 takes the scale out of everything but the unaligned ATE
    sim = evaluate_drive(ts, est, ts, gt, align="sim3")
    assert sim.evaluation.scale == pytest.approx(1 / 1.02)
    assert sim.ape.max() < 1e-9 and sim.rpe_t.max() < 1e-9
    assert sim.segments.summary()["segments"] == 0 or sim.segments.translation.max() < 1e-9


def test_poses_without_timestamps_pair_by_frame():
    ts, gt = _drive(20)
    frames = np.arange(20)
    dr = evaluate_drive(frames[5:15], gt[5:15], frames, gt, by_time=False)
    assert not dr.by_time and dr.evaluation.poses == 10 and dr.ape.max() < 1e-12
    assert dr.as_dict()["pairing"] == "frame" and dr.as_dict()["max_dt_s"] is None
    with pytest.raises(InputError, match="frame 3 is given more than once"):
        evaluate_drive(np.r_[0, 1, 2, 3, 3], gt[:5], frames, gt, by_time=False)
    with pytest.raises(InputError, match=r"none of the frames 30\.\.34"):
        evaluate_drive(np.arange(30, 35), gt[:5], frames, gt, by_time=False)


def test_the_std_band_counts_errors_inside_three_sigma():
    ts, gt = _drive(201)
    rng = np.random.default_rng(7)
    std = np.tile(np.r_[0.001, 0.002, 0.001, 0.01, 0.02, 0.01], (200, 1))  # m, deg
    noise = rng.normal(0.0, 1.0, (200, 6)) * std
    noise[17, 1] = 10 * std[17, 1]  # one error far outside
    rel = [se3_inv(gt[k - 1]) @ gt[k] for k in range(1, 201)]
    moved = np.array([pose_from_vectors(T[:3, 3] + n[:3], so3_log(T[:3, :3]) + np.radians(n[3:]))
                      for T, n in zip(rel, noise)])
    motions = ReportedMotions(np.arange(1, 201), moved, std)
    band = std_band(np.arange(201), gt, motions)
    np.testing.assert_allclose(band.errors, noise, atol=1e-9)
    np.testing.assert_array_equal(band.pose, np.arange(1, 201))
    assert not band.inside()[17, 1]
    total, by_axis = band.fraction_inside()
    expected = np.abs(noise) <= 3 * std
    assert total == pytest.approx(expected.mean()) and total > 0.99
    np.testing.assert_allclose(by_axis, expected.mean(axis=0))
    # a gap in the matched frames drops the motions across it; NaN std are left out
    std_nan = std.copy()
    std_nan[5] = np.nan
    band = std_band(np.r_[np.arange(100), np.arange(101, 201)], gt[np.r_[0:100, 101:201]],
                    ReportedMotions(np.arange(1, 201), moved, std_nan))
    assert len(band.pose) == 200 - 2 - 1
    d = StdBand(np.arange(2), np.array([[1.0] * 6, [4.0] * 6]), np.ones((2, 6))).as_dict()
    assert d["inside_fraction"] == 0.5 and d["inside_fraction_by_axis"]["rz"] == 0.5
