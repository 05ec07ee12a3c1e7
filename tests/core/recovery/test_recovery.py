"""Never lost for good (issue 13): recovery after unusable frames, reasons, exit status 3."""

import csv
import logging
import shutil
from dataclasses import replace

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from benchmarks.common import keyframe_tilt_errors
from monovo_cli import iter_track, track_frames
from monovo_cli.cli import main
from monovo_cli.core.odometry import Odometry
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.write import synthesize


@pytest.fixture(scope="module")
def drive(synth_drive):
    return synth_drive(preset="drive", frames=24, size=(160, 160), noise_var=10.0, seed=11)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _noise_frames(seq, frames, seed=0):
    rng = np.random.default_rng(seed)
    for k in frames:
        path = sorted((seq / "frames").glob("*.png"))[k]
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(path), rng.integers(0, 256, img.shape, dtype=np.uint8))


def test_noise_in_the_middle_is_lost_with_a_reason_and_tracking_resumes(drive, tmp_path):
    """Three frames of pure noise: lost (each with its reason), never re-initialised on noise;
    the frames after them are tracked again and the drive ends near the truth."""
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _noise_frames(seq, [9, 10, 11])
    res = list(iter_track(seq))
    for r in res[9:12]:
        assert r.status == FrameStatus.LOST and r.reason
    assert all(r.status != FrameStatus.LOST for r in res[12:])
    assert all(r.status != FrameStatus.REINIT for r in res)  # the drive's keyframe is recovered
    _, truth = read_tum(seq / "groundtruth.tum")
    err = np.linalg.norm(res[-1].world_from_cam[:3, 3] - truth[-1][:3, 3])
    path = np.sum(np.linalg.norm(np.diff([t[:3, 3] for t in truth], axis=0), axis=1))
    assert err < 0.05 * path  # the three predicted frames bridge the gap; the rest is tracked


def test_a_jump_is_bridged_by_a_fresh_keyframe(drive, tmp_path):
    """Frames 8..23 replaced by a part of the drive the keyframe never saw (frames shifted by
    a jump the predictor cannot follow) are not lost for more than ``reinit_after`` in a row."""
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    paths = sorted((seq / "frames").glob("*.png"))
    assert len(paths) == 24
    far = tmp_path / "far"
    synthesize(far, preset="drive", frames=24, size=(160, 160), noise_var=10.0, seed=12)
    for k, p in enumerate(paths[8:], start=8):
        shutil.copyfile(sorted((far / "frames").glob("*.png"))[k], p)
    res = list(iter_track(seq))
    run = longest = 0
    for r in res:
        run = run + 1 if r.status == FrameStatus.LOST else 0
        longest = max(longest, run)
    assert longest <= TrackOptions().reinit_after
    assert res[-1].status in (FrameStatus.OK, FrameStatus.REANCHORED)
    reinit = [r for r in res if r.status == FrameStatus.REINIT]
    assert reinit and all("re-initialised after" in r.reason for r in reinit)


def _first(seq, n):
    """``seq`` cut to its first ``n`` frames (a lost frame runs every capture attempt: a
    sequence of noise costs by its length and shows nothing more for it)."""
    for path in sorted((seq / "frames").glob("*.png"))[n:]:
        path.unlink()
    return seq


def test_noise_sequence_exits_3_every_frame_lost_with_a_reason(drive, tmp_path):
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _first(seq, 8)
    _noise_frames(seq, range(1, 8))  # (7 lost in a row, past reinit_after: none re-initialised)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q"])
    assert r.exit_code == 3, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "7 of 7 frames lost" in lines[0] and str(out) in lines[0]
    rows = _rows(out / "motion.csv")
    assert list(rows[0])[-1] == "reason"
    assert len(rows) == 7 and all(x["status"] == "lost" and x["reason"] for x in rows)
    for name in ("trajectory.csv", "trajectory.tum"):
        assert (out / name).is_file()  # outputs kept


def test_batch_marks_a_mostly_lost_sequence_failed(drive, tmp_path):
    root = tmp_path / "archive"
    shutil.copytree(drive, root / "good")
    shutil.copytree(drive, root / "noise")
    _first(root / "good", 8)
    _first(root / "noise", 8)
    _noise_frames(root / "noise", range(1, 8))
    r = CliRunner().invoke(main, ["batch", str(root), "-o", str(tmp_path / "o"), "-q",
                                  "--workers", "1"])
    rows = {x["sequence"]: x for x in _rows(tmp_path / "o" / "summary.csv")}
    assert rows["good"]["status"] == "ok"
    assert rows["noise"]["status"] == "failed" and "frames lost" in rows["noise"]["error"]
    assert r.exit_code != 0


def test_verbose_logs_each_lost_frame_with_its_reason(drive, tmp_path, caplog):
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _noise_frames(seq, [5])
    with caplog.at_level(logging.INFO, logger="monovo_cli"):
        r = CliRunner().invoke(main, ["track", str(seq), "-o", str(tmp_path / "o"), "-v"])
    assert r.exit_code == 0, r.output
    assert any(m.startswith("frame 5 lost: ") for m in caplog.messages)


class _FailingOn(Odometry):
    """An odometry whose direct fit is refused on the frames in ``fail``: the recovery path
    runs there whatever the images."""

    def __init__(self, *args, fail=(), **kwargs):
        super().__init__(*args, **kwargs)
        self._fail, self._now = set(fail), -1

    def step(self, index, timestamp, image, prior_motion=None):
        self._now = index
        return super().step(index, timestamp, image, prior_motion)

    def _failure(self, est, key):
        return "refused by the test" if self._now in self._fail else super()._failure(est, key)


def _run(odo, seq):
    out = []
    for f in open_frames(seq / "frames"):
        out.append(odo.start(f.index, f.timestamp, f.image) if not out else
                   odo.step(f.index, f.timestamp, f.image))
    return out


def _pose_errors(res, truth):
    """(position error m, rotation error deg) of each frame's world_from_cam."""
    out = []
    for r, t in zip(res, truth):
        e = se3_inv(t) @ r.world_from_cam
        out.append((np.linalg.norm(e[:3, 3]), np.degrees(np.linalg.norm(so3_log(e[:3, :3])))))
    return np.array(out)


def test_frames_lost_at_a_turn_in_place_are_bridged_by_the_features(tmp_path):
    """MER spacing (seed 2: frames 4 and 5 turn in place by 18 and 17 deg after 0.7 m steps).
    With the direct fit refused on frames 4-6, the constant-velocity prediction would carry
    0.7 m steps through the turn (0.8 m / 17 deg off at frame 4, 1.8 m / 30 deg at the
    re-initialisation on frame 6). The features' hypothesis, chained from lost frame to lost
    frame, keeps them and the fresh keyframe within 2 cm and 0.6 deg (the homography's error
    over the keyframe's plane, which the frames before the loss refine: 0.41-0.56 deg at frame
    6 and 0.43-0.57 deg at frame 8 over five settings of the estimator's steps that move those
    frames by 0.002 deg, a diagnostic run)."""
    seq = tmp_path / "mer"
    synthesize(seq, preset="mer", frames=9, size=(256, 256), noise_var=10.0, seed=2)
    cfg = load_init(seq / "init.yaml")
    _, truth = read_tum(seq / "groundtruth.tum")
    res = _run(_FailingOn(cfg.camera, cfg.plane, cfg.region, fail={4, 5, 6}), seq)
    assert [r.status for r in res[4:]] == [FrameStatus.LOST, FrameStatus.LOST,
                                           FrameStatus.REINIT, FrameStatus.REANCHORED,
                                           FrameStatus.REANCHORED]
    err = _pose_errors(res, truth)
    assert np.all(err[4:7, 0] < 0.02) and np.all(err[4:7, 1] < 0.6), err
    assert err[-1, 0] < 0.03 and err[-1, 1] < 0.6, err  # tracking goes on from there


def test_a_lost_frame_keeps_the_prediction_the_features_confirm(drive):
    """On a smooth drive the prediction is as good as the features' hypothesis: a lost frame
    keeps it (its motion is exactly the previous frame's), and the next frame is tracked."""
    cfg = load_init(drive / "init.yaml")
    odo = _FailingOn(cfg.camera, cfg.plane, cfg.region, fail={8})
    res = []
    for f in open_frames(drive / "frames"):
        res.append(odo.start(f.index, f.timestamp, f.image) if not res else
                   odo.step(f.index, f.timestamp, f.image))
        if f.index == 8:
            hyp = odo._recovery.current[1]
    assert hyp is not None and hyp.motion.inliers >= 50  # the features had their say
    assert res[8].status == FrameStatus.LOST
    np.testing.assert_allclose(res[8].prev_from_cur, res[7].prev_from_cur, atol=1e-12)
    assert res[9].status == FrameStatus.REANCHORED
    # the hypothesis' own pose reprojects its inliers with its own RMS
    assert hyp.reprojection_px(hyp.cur_from_key, cfg.camera) == pytest.approx(hyp.motion.rms_px,
                                                                              rel=1e-9)


def _blanked(seq, frames):
    for k in frames:
        path = sorted((seq / "frames").glob("*.png"))[k]
        cv2.imwrite(str(path), np.zeros_like(cv2.imread(str(path), cv2.IMREAD_UNCHANGED)))


def test_the_gap_after_blank_frames_is_re_solved_from_the_last_good_frame(synth_drive, tmp_path):
    """MER spacing at 256², frames 13 and 14 blank as the rover ends a turn in place and
    drives off: frame 15 cannot be captured from the last lost frame and is re-initialised.
    Re-solved from frame 12 (a keyframe built on it, the prediction's pose, then the
    capture's starts), the fresh keyframe is placed within a centimetre where the prediction
    put it 1.2 m and 30 deg off, and the drive ends within 0.2 % of its path instead of 15 %
    (17 frames, two after the re-initialised one: measured 0.05 %; 0.02 % and 16 % over
    20); the lost frames are moved toward the truth in the trajectory written, and the
    re-initialised row's std covers its motion from the predicted previous pose."""
    seq = tmp_path / "mer"
    shutil.copytree(synth_drive(preset="mer", frames=17, size=(256, 256), noise_var=10.0,
                                seed=1), seq)
    _blanked(seq, [13, 14])
    _, truth = read_tum(seq / "groundtruth.tum")
    truth = se3_inv(truth[0]) @ truth
    path = np.sum(np.linalg.norm(np.diff(truth[:, :3, 3], axis=0), axis=1))
    runs = {}
    for resolve in (True, False):
        runs[resolve] = track_frames(seq, options=replace(TrackOptions(), resolve_gaps=resolve))
    run = runs[True]
    assert [run.status[k] for k in (13, 14, 15)] == [FrameStatus.LOST, FrameStatus.LOST,
                                                    FrameStatus.REINIT]
    assert run.reason[15].endswith("the gap re-solved from frame 12"), run.reason[15]
    assert [k for k, _ in run.gaps] == [15] and not runs[False].gaps
    err = {r: np.linalg.norm(runs[r].trajectory[:, :3, 3] - truth[:, :3, 3], axis=1) for r in runs}
    assert err[True][15] < 0.01 and err[False][15] > 1.0, (err[True][15], err[False][15])
    assert err[True][-1] < 0.002 * path and err[False][-1] > 0.1 * path, (err, path)
    assert max(err[True][13:15]) < 0.75 * max(err[False][13:15]), (err[True][13:15],
                                                                    err[False][13:15])
    T = run.prev_from_cur[15]
    G = se3_inv(truth[14]) @ truth[15]
    e = np.abs(np.r_[T[:3, 3] - G[:3, 3], so3_log(T[:3, :3] @ G[:3, :3].T)])
    assert np.all(e <= 4.0 * run.std[15]), (e, run.std[15])


def test_a_frame_the_coarse_features_miss_is_bridged_at_full_resolution(synth_drive, tmp_path):
    """MER spacing at 1024² (seed 15): frame 12, the first drive step after three turns in
    place, blank. Frame 13 is then 1.2 m and a turn from the keyframe: the features at the
    tracker's 256 and 512 px levels find no hypothesis, at full resolution they do. Without
    that last try frames 12-13 were lost, frame 14 re-initialised 14 deg off and the drive
    ended 43 % off (40 frames; 29 % on 16 frames); with it frame 13 is tracked and the
    drive to it ends within 1 % of its path (measured on these 14 frames: 0.02 %; 19 %
    without the last try, frame 13 lost)."""
    seq = tmp_path / "mer"
    shutil.copytree(synth_drive(preset="mer", frames=14, size=(1024, 1024), noise_var=10.0,
                                seed=15), seq)
    _blanked(seq, [12])
    run = track_frames(seq)
    assert run.status[12] == FrameStatus.LOST
    assert FrameStatus.LOST not in run.status[13:] and FrameStatus.REINIT not in run.status
    _, truth = read_tum(seq / "groundtruth.tum")
    truth = se3_inv(truth[0]) @ truth
    path = np.sum(np.linalg.norm(np.diff(truth[:, :3, 3], axis=0), axis=1))
    err = np.linalg.norm(run.trajectory[-1][:3, 3] - truth[-1][:3, 3])
    assert err < 0.01 * path, (err, path)


@pytest.fixture
def mer17(synth_drive, tmp_path):
    """MER spacing at 768² (seed 17), 16 frames, frame 12 blank: frame 13 is 1.3 m and an
    11 deg turn from the keyframe (frame 10), 1.3 m from the last good frame (11)."""
    seq = tmp_path / "mer"
    shutil.copytree(synth_drive(preset="mer", frames=16, size=(768, 768), noise_var=10.0,
                                seed=17), seq)
    _blanked(seq, [12])
    return seq


def test_the_plane_after_a_loss_is_measured_again_not_carried(mer17):
    """Captured against the keyframe (the gap not re-solved), frame 13 is fitted on a sixth
    of the points. When that fit was 0.25 deg off (at 1024², as this test was written), the
    keyframe plane anchored on it was 0.17 deg off, and carried with the motion's formal
    covariance that tilt stayed so on the next keyframes (every row's rotation 40-70 std
    off); known only to the bobbing's width, the next frame measures it again and the
    keyframes after it are within 0.03 deg. (Measured now: frame 13's plane 0.007 deg off,
    the keyframes after it 0.012 and 0.015 deg; at 1024² 0.005, 0.007 and 0.010 deg: the
    capture no longer puts the plane that far off at either size.)"""
    run = track_frames(mer17, options=replace(TrackOptions(), resolve_gaps=False))
    tilt = keyframe_tilt_errors(run, mer17)
    assert run.status[12] == FrameStatus.LOST and 13 in tilt, (run.status, tilt)
    after = [t for k, t in tilt.items() if k > 13]
    assert after and max(after) < 0.03, tilt


def test_a_frame_the_keyframe_sees_little_of_is_measured_from_the_last_good_frame(mer17):
    """By default frame 13 is measured from frame 11 instead, which sees it on 4.6 times the
    points (104 000, msd 20, against the keyframe's 23 000 and msd 23; 185 000 and 41 000
    at 1024²): re-initialised there with the gap re-solved, its plane within 0.01 deg and
    the drive within 0.1 % of its path (measured: 0.005 deg and 0.07 %; captured instead,
    0.007 deg and 0.01 %). As this test was written, at 1024², the keyframe's fit was 0.15
    deg off even from the true pose, the capture put the plane 0.17 deg off and the drive
    ended 0.11 % off (the 40-frame drive 0.25 % against 0.04 % re-solved)."""
    run = track_frames(mer17)
    assert run.status[12] == FrameStatus.LOST and run.status[13] == FrameStatus.REINIT
    assert run.reason[13].endswith("the gap re-solved from frame 11"), run.reason[13]
    assert keyframe_tilt_errors(run, mer17)[13] < 0.01
    _, truth = read_tum(mer17 / "groundtruth.tum")
    truth = se3_inv(truth[0]) @ truth
    path = np.sum(np.linalg.norm(np.diff(truth[:, :3, 3], axis=0), axis=1))
    assert np.linalg.norm(run.trajectory[-1][:3, 3] - truth[-1][:3, 3]) < 0.001 * path


def test_a_predicted_previous_pose_reaches_the_motion_through_its_lever():
    """The motion measured from a pose known only to a prediction: sampled, the previous
    pose's rotation error moves a 0.7 m step's translation by ``t x w``, which the covariance
    added to the row holds (the per-axis variance alone missed it: 4.3 std on MER seed 15's
    first frame after a loss, a turn predicted where the rover drove)."""
    from monovo_cli.core.frame_std import from_predicted as _from_predicted
    from monovo_cli.geometry.lie import se3_exp

    rng = np.random.default_rng(3)
    T = se3_exp(np.r_[0.05, -0.5, 0.5, 0.02, 0.2, 0.15])  # a MER step and a 15 deg turn
    variance = np.r_[np.full(3, 1e-4), np.full(3, 1e-4)]
    errors = []
    for _ in range(4000):
        delta = rng.normal(0.0, np.sqrt(variance))  # the previous pose, off in its own frame
        est = se3_exp(-delta) @ T
        errors.append(np.r_[est[:3, 3] - T[:3, 3], so3_log(est[:3, :3] @ T[:3, :3].T)])
    sampled = np.cov(np.array(errors).T)
    model = _from_predicted(variance, T)
    np.testing.assert_allclose(np.diag(sampled), np.diag(model), rtol=0.1)
    assert np.diag(sampled)[0] > 1.3 * variance[0]  # the lever counts: the per-axis sum misses it
