"""monovo eval: zero against itself, known perturbations give known errors, evo agrees."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.evaluate import ate, evaluate, match_timestamps, relative_motion_errors, umeyama_se3
from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import pose_from_vectors, se3_inv, so3_log
from monovo_cli.io.formats import read_tum, tum_text


def _drive(n=50, seed=3):
    """A smooth random trajectory T_0_k (n, 4, 4), frame 0 the identity."""
    rng = np.random.default_rng(seed)
    poses = [np.eye(4)]
    for _ in range(n - 1):
        step = pose_from_vectors(np.r_[0.0, 0.0, 0.05] + rng.normal(0, 0.005, 3),
                                 np.radians(rng.normal(0, 0.5, 3)))
        poses.append(poses[-1] @ step)
    return np.arange(n, dtype=float), np.array(poses)


def test_against_itself_everything_is_zero():
    ts, gt = _drive()
    ev = evaluate(ts, gt, ts, gt, align=True)
    assert ev.poses == 50
    np.testing.assert_allclose(ev.relative_mean, 0.0, atol=1e-12)
    np.testing.assert_allclose(ev.relative_std, 0.0, atol=1e-12)
    assert ev.ate_rmse == 0.0 and ev.ate_rmse_aligned < 1e-9
    assert ev.final_drift_m < 1e-12 and ev.final_drift_pct < 1e-9
    assert ev.final_rotation_deg < 1e-6
    assert ev.distance_m == pytest.approx(2.45, rel=0.05)


def test_known_per_axis_perturbation_gives_known_table():
    ts, gt = _drive()
    d_t, d_r = 0.004, 0.03  # m along x, deg about z, in every relative motion
    rel = [se3_inv(gt[k - 1]) @ gt[k] for k in range(1, len(gt))]
    est = [np.eye(4)]
    for k, T in enumerate(rel):
        t = T[:3, 3] + np.r_[d_t, 0.0, 0.0] * (1 if k % 2 else -1)
        r = so3_log(T[:3, :3]) + np.radians([0.0, 0.0, d_r])
        est.append(est[-1] @ pose_from_vectors(t, r))
    ev = evaluate(ts, np.array(est), ts, gt)
    np.testing.assert_allclose(ev.relative_mean, [d_t, 0, 0, 0, 0, d_r], atol=1e-9)
    np.testing.assert_allclose(ev.relative_std, 0.0, atol=1e-9)
    signed = relative_motion_errors(np.array(est), gt)
    np.testing.assert_allclose(signed[::2, 0], -d_t, atol=1e-12)
    np.testing.assert_allclose(signed[1::2, 0], d_t, atol=1e-12)


def test_world_offset_shows_in_ate_not_in_relative_errors_and_alignment_removes_it():
    ts, gt = _drive()
    offset = pose_from_vectors(np.r_[0.3, -0.1, 0.2], np.radians([2.0, -5.0, 10.0]))
    est = offset @ gt
    ev = evaluate(ts, est, ts, gt, align=True)
    np.testing.assert_allclose(ev.relative_mean, 0.0, atol=1e-9)
    assert ev.ate_rmse > 0.2
    assert ev.ate_rmse_aligned < 1e-9
    np.testing.assert_allclose(ev.alignment, se3_inv(offset), atol=1e-9)
    assert ev.final_drift_m < 1e-9  # drift is measured from each trajectory's own first pose


def test_pure_translation_offset_gives_ate_equal_to_offset():
    ts, gt = _drive()
    est = gt.copy()
    est[:, :3, 3] += [0.0, 0.02, 0.0]
    errors, T = ate(est, gt)
    np.testing.assert_allclose(errors, 0.02, atol=1e-12)
    assert evaluate(ts, est, ts, gt).ate_rmse == pytest.approx(0.02, abs=1e-12)


def test_scale_error_gives_known_drift():
    n = 21
    ts = np.arange(n, dtype=float)
    gt = np.array([pose_from_vectors(np.r_[0.0, 0.0, 0.1 * k], np.zeros(3)) for k in range(n)])
    est = gt.copy()
    est[:, :3, 3] *= 1.01
    ev = evaluate(ts, est, ts, gt)
    assert ev.distance_m == pytest.approx(2.0)
    assert ev.final_drift_m == pytest.approx(0.02)
    assert ev.final_drift_pct == pytest.approx(1.0)
    assert ev.relative_mean[2] == pytest.approx(0.001)


def test_rotation_drift_per_metre():
    n = 11
    ts = np.arange(n, dtype=float)
    gt = np.array([pose_from_vectors(np.r_[0.1 * k, 0.0, 0.0], np.zeros(3)) for k in range(n)])
    est = np.array([pose_from_vectors(np.r_[0.1 * k, 0.0, 0.0], np.radians([0, 0.05 * k, 0]))
                    for k in range(n)])
    ev = evaluate(ts, est, ts, gt)
    assert ev.final_rotation_deg == pytest.approx(0.5)
    assert ev.rotation_drift_deg_per_m == pytest.approx(0.5)


def test_umeyama_recovers_a_rigid_transform():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(30, 3))
    T = pose_from_vectors(np.r_[1.0, -2.0, 0.5], np.r_[0.3, -0.2, 1.1])
    dst = src @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(umeyama_se3(src, dst), T, atol=1e-12)


def test_frames_are_matched_by_timestamp_in_any_order():
    ts, gt = _drive(10)
    order = np.random.default_rng(1).permutation(10)
    ev = evaluate(ts[order], gt[order], ts + 1e-7, gt)
    assert ev.ate_rmse == 0.0 and ev.poses == 10
    ie, ig = match_timestamps(ts[order], ts)
    np.testing.assert_array_equal(ts[order][ie], ts[ig])


def test_differing_timestamp_sets_are_refused():
    ts, gt = _drive(10)
    with pytest.raises(InputError, match=r"1 ground truth timestamp\(s\) have no estimate pose"):
        evaluate(ts[:-1], gt[:-1], ts, gt)
    with pytest.raises(InputError, match="have no ground truth pose .first 0.5"):
        evaluate(np.r_[ts[:-1], 0.5], gt, ts, gt)
    with pytest.raises(InputError, match="given more than once"):
        evaluate(np.r_[ts[:-1], 3.0], gt, ts, gt)
    with pytest.raises(InputError, match="at least 2"):
        evaluate(ts[:1], gt[:1], ts[:1], gt[:1])


@pytest.fixture()
def tum_pair(tmp_path):
    ts, gt = _drive()
    est = gt.copy()
    est[:, :3, 3] += np.random.default_rng(2).normal(0, 0.01, (len(gt), 3))
    (tmp_path / "gt.tum").write_text(tum_text(ts, gt))
    (tmp_path / "est.tum").write_text(tum_text(ts, est))
    return tmp_path / "est.tum", tmp_path / "gt.tum"


def test_cli_eval_prints_tables(tum_pair):
    est, gt = tum_pair
    r = CliRunner().invoke(main, ["eval", str(est), str(gt), "--align"])
    assert r.exit_code == 0, r.output
    for text in ("Table 10.1", "Table 10.2", "|E_Tx|", "|E_wz|", "ATE RMSE, no alignment",
                 "ATE RMSE, SE(3) aligned", "final drift", "deg/m"):
        assert text in r.output


def test_cli_eval_json(tum_pair):
    est, gt = tum_pair
    r = CliRunner().invoke(main, ["eval", str(est), str(gt), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["poses"] == 50 and d["relative_motions"] == 49
    assert set(d["relative_errors"]) == {"tx", "ty", "tz", "rx", "ry", "rz"}
    assert d["ate_rmse_aligned_m"] is None
    ts_e, e = read_tum(est)
    ts_g, g = read_tum(gt)
    assert d["ate_rmse_m"] == pytest.approx(evaluate(ts_e, e, ts_g, g).ate_rmse)
    r = CliRunner().invoke(main, ["eval", str(est), str(est), "--json", "--align"])
    d = json.loads(r.output)
    assert d["ate_rmse_m"] == 0.0 and d["final_drift_m"] == 0.0


def test_cli_eval_bad_input_is_one_line_exit_2(tum_pair, tmp_path):
    est, gt = tum_pair
    bad = tmp_path / "bad.tum"
    bad.write_text("0 0 0 0 0 0 0 1\n1 0 0 oops 0 0 0 1\n")
    r = CliRunner().invoke(main, ["eval", str(bad), str(gt)])
    assert r.exit_code == 2
    assert "bad.tum: line 2: expected numbers" in r.output
    assert "Traceback" not in r.output
    short = tmp_path / "short.tum"
    short.write_text("".join(est.read_text().splitlines(keepends=True)[:10]))
    r = CliRunner().invoke(main, ["eval", str(short), str(gt)])
    assert r.exit_code == 2
    assert "40 " in r.output and "have no" in r.output and r.output.count("\n") == 1
    r = CliRunner().invoke(main, ["eval", str(tmp_path / "missing.tum"), str(gt)])
    assert r.exit_code == 2 and "missing.tum" in r.output


def test_ate_matches_evo(tum_pair):
    """Cross-check against evo (GPL; a dev-only extra, skipped where it is not installed),
    through the same comparison benchmarks/overlay_accuracy.py prints."""
    pytest.importorskip("evo")
    from benchmarks.overlay_accuracy import evo_check

    rows = evo_check(*tum_pair)
    assert [r[0] for r in rows] == ["none", "SE(3) aligned"]
    for _, mine, theirs in rows:
        assert abs(theirs - mine) < 1e-6
