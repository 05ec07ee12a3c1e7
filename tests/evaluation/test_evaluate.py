"""monovo eval: zero against itself, known perturbations give known errors, evo agrees."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.errors import InputError
from monovo_cli.evaluation.metrics import (
    ate,
    evaluate,
    relative_motion_errors,
    umeyama,
    umeyama_se3,
)
from monovo_cli.evaluation.report import format_report
from monovo_cli.evaluation.sync import match_timestamps
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


def test_partial_estimate_is_evaluated_over_the_overlap():
    ts, gt = _drive()
    part = slice(10, 30)  # a run over frames 10..29: its world is camera 10's
    est = se3_inv(gt[10]) @ gt[part]
    ev = evaluate(ts[part], est, ts, gt, align="se3")
    assert (ev.poses, ev.estimate_poses, ev.groundtruth_poses) == (20, 20, 50)
    np.testing.assert_allclose(ev.relative_mean, 0.0, atol=1e-9)
    assert ev.final_drift_m < 1e-9 and ev.ate_rmse_aligned < 1e-9
    assert ev.ate_rmse > 0.4 and ev.start_offset_m == pytest.approx(np.linalg.norm(gt[10][:3, 3]))
    report = format_report(ev)
    assert "20 poses matched within 0.02 s (of 20 estimated, 50 true)" in report
    assert "partial match" in report
    unaligned = format_report(evaluate(ts[part], est, ts, gt))
    assert "start 0.5" in unaligned and "aligning them compares their shapes" in unaligned


def test_poses_match_the_nearest_true_pose_within_max_dt():
    ts, gt = _drive()
    jitter = np.random.default_rng(5).uniform(-0.015, 0.015, len(ts))
    ev = evaluate(ts + jitter, gt, ts, gt)  # within the default 0.02 s
    assert ev.poses == 50 and ev.max_dt == 0.02 and ev.ate_rmse == 0.0
    with pytest.raises(InputError, match=r"none of the 50 timestamps of estimate "
                                         r"\(0\.03\.\.49\.03 s\) is within 0\.02 s.*max_dt sets"):
        evaluate(ts + 0.03, gt, ts, gt)
    assert evaluate(ts + 0.03, gt, ts, gt, max_dt=0.05).poses == 50
    # a ground truth sampled ten times faster than the frames
    fine_ts = np.arange(0.0, 49.05, 0.1)
    fine = np.repeat(gt, 10, axis=0)[:len(fine_ts)]
    fine[::10] = gt
    ev = evaluate(ts, gt, fine_ts, fine)
    assert (ev.poses, ev.groundtruth_poses) == (50, 491) and ev.ate_rmse < 1e-12
    # frames closer than 0.04 s: half their interval
    fast = ts * 0.01
    assert evaluate(fast, gt, fast, gt).max_dt == pytest.approx(0.005)


def test_a_true_pose_goes_to_the_nearest_estimate_only():
    ts, gt = _drive(10)
    ie, ig = match_timestamps(np.r_[0.0, 0.9, 1.2, 3.0], ts, max_dt=0.5)
    # 0.9 and 1.2 are both nearest to 1.0: 0.9 is closer; 1.2 is left out
    np.testing.assert_array_equal(ie, [0, 1, 3])
    np.testing.assert_array_equal(ig, [0, 1, 3])


def test_bad_timestamp_sets_are_refused():
    ts, gt = _drive(10)
    with pytest.raises(InputError, match="given more than once"):
        evaluate(np.r_[ts[:-1], 3.0], gt, ts, gt)
    with pytest.raises(InputError, match="only 1 pose.*at least 2"):
        evaluate(ts[:1], gt[:1], ts, gt)
    with pytest.raises(InputError, match="only 1 pose.*at least 2"):
        evaluate(np.r_[0.0, 100.0], gt[:2], ts, gt)


def test_sim3_alignment_recovers_the_scale_of_an_up_to_scale_run():
    ts, gt = _drive()
    offset = pose_from_vectors(np.r_[0.3, -0.1, 0.2], np.radians([2.0, -5.0, 10.0]))
    est = offset @ gt
    est[:, :3, 3] *= 0.4  # translations in units of some other distance
    ev = evaluate(ts, est, ts, gt, align="sim3")
    assert ev.scale == pytest.approx(2.5, rel=1e-9)
    assert ev.ate_rmse_aligned < 1e-9
    np.testing.assert_allclose(ev.relative_mean, 0.0, atol=1e-9)
    assert ev.final_drift_m < 1e-9
    rigid = evaluate(ts, est, ts, gt, align="se3")
    assert rigid.scale == 1.0 and rigid.ate_rmse_aligned > 0.3 and rigid.final_drift_m > 1.0
    assert "Sim(3) aligned" in format_report(ev) and "scaled by 2.5" in format_report(ev)


def test_umeyama_with_scale_recovers_a_similarity():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(30, 3))
    T = pose_from_vectors(np.r_[1.0, -2.0, 0.5], np.r_[0.3, -0.2, 1.1])
    dst = 3.0 * src @ T[:3, :3].T + T[:3, 3]
    S, c = umeyama(src, dst, with_scale=True)
    assert c == pytest.approx(3.0)
    np.testing.assert_allclose(S[:3, :3], 3.0 * T[:3, :3], atol=1e-12)
    np.testing.assert_allclose(S[:3, 3], T[:3, 3], atol=1e-12)
    with pytest.raises(InputError, match="does not move"):
        umeyama(np.zeros((5, 3)), dst[:5], with_scale=True)


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
    shifted = tmp_path / "shifted.tum"
    shifted.write_text("".join(f"{float(line.split()[0]) + 0.5} {line.split(' ', 1)[1]}"
                               for line in est.read_text().splitlines(keepends=True)))
    r = CliRunner().invoke(main, ["eval", str(shifted), str(gt)])
    assert r.exit_code == 2
    assert "within 0.02 s" in r.output and "--max-dt" in r.output and r.output.count("\n") == 1
    r = CliRunner().invoke(main, ["eval", str(tmp_path / "missing.tum"), str(gt)])
    assert r.exit_code == 2 and "missing.tum" in r.output
    # monovo's CSVs are read as what they are (tests/io/test_trajectories.py); told to read
    # one as TUM, the reader still says what it is
    for name, header in (("trajectory.csv", "frame,timestamp,tx,ty,tz,qx,qy,qz,qw"),
                         ("motion.csv", "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status")):
        (tmp_path / name).write_text(header + "\n0,0,0,0,0,0,0,0,1\n")
        r = CliRunner().invoke(main, ["eval", str(tmp_path / name), str(gt), "--format", "tum"])
        assert r.exit_code == 2 and r.output.count("\n") == 1, r.output
        assert f"{name}: is a" in r.output and "use trajectory.tum" in r.output


def test_cli_eval_partial_run_and_alignments(tum_pair, tmp_path):
    est, gt = tum_pair
    short = tmp_path / "short.tum"
    short.write_text("".join(est.read_text().splitlines(keepends=True)[5:15]))
    r = CliRunner().invoke(main, ["eval", str(short), str(gt)])
    assert r.exit_code == 0, r.output
    assert "10 poses matched within 0.02 s (of 10 estimated, 50 true)" in r.output
    runs = {}
    for align in ([], ["--align"], ["--align", "se3"], ["--align", "sim3"], ["--align=none"]):
        r = CliRunner().invoke(main, ["eval", str(est), str(gt), "--json", "--max-dt", "0.1",
                                      *align])
        assert r.exit_code == 0, r.output
        runs[" ".join(align)] = json.loads(r.output)
    assert runs[""]["alignment"] is None and runs["--align=none"]["alignment"] is None
    assert runs["--align"] == runs["--align se3"] and runs["--align"]["alignment"] == "se3"
    assert runs["--align sim3"]["alignment"] == "sim3"
    assert runs["--align sim3"]["scale"] == pytest.approx(1.0, abs=0.02)  # a metric run
    assert runs[""]["max_dt_s"] == 0.1 and runs[""]["groundtruth_poses"] == 50


def test_ate_matches_evo(tum_pair):
    """Cross-check against evo (GPL; in the test extra, so CI runs it; skipped where it is
    not installed), through the same comparison benchmarks/overlay_accuracy.py prints."""
    pytest.importorskip("evo")
    from benchmarks.overlay_accuracy import evo_check

    rows = evo_check(*tum_pair)
    assert [r[0] for r in rows] == ["none", "SE(3) aligned"]
    for _, mine, theirs in rows:
        assert abs(theirs - mine) < 1e-6
