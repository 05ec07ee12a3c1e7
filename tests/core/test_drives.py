"""Long-drive machinery: loss and recovery, photometric model, mask, prior, covariance."""

import csv
import shutil

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.estimator.estimate import KeyLevel, estimate_motion
from monovo_cli.core.estimator.ground import rectangle_corners, select_points
from monovo_cli.core.odometry import Odometry, OdometryState, estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.image.pyramid import build_pyramid
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.write import synthesize


@pytest.fixture(scope="module")
def drive(synth_drive):
    return synth_drive(preset="drive", frames=40, size=(192, 192), noise_var=10.0, seed=21)


def _track(seq, images=None, options=None, priors=None):
    cfg = load_init(seq / "init.yaml")
    fr = open_frames(seq / "frames")
    imgs = images if images is not None else [f.image for f in fr]
    plane = cfg.plane
    return list(estimate_frames(((k, float(k), im) for k, im in enumerate(imgs)), cfg.camera, plane,
                      cfg.region, options or TrackOptions(), priors=priors))


def _pos_err(res, gt):
    return np.array([np.linalg.norm(r.world_from_cam[:3, 3] - g[:3, 3]) for r, g in zip(res, gt)])


def test_faults_are_flagged_and_tracking_resumes(drive):
    fr = open_frames(drive / "frames")
    imgs = [f.image for f in fr]
    imgs[12] = np.zeros_like(imgs[12])                          # blank
    imgs[20] = imgs[19].copy()                                  # duplicate
    imgs[28] = np.full_like(imgs[28], 255.0)                    # saturated
    rng = np.random.default_rng(0)
    imgs[33] = rng.uniform(0, 255, imgs[33].shape).astype(np.float32)  # pure noise
    res = _track(drive, imgs)
    _, gt = read_tum(drive / "groundtruth.tum")
    status = [r.status for r in res]
    for k in (12, 20, 28, 33):
        assert status[k] == FrameStatus.LOST, (k, status[k], res[k].reason)
    assert status.count(FrameStatus.LOST) == 4
    err = _pos_err(res, gt)
    # back on track at the very next frame, every time
    for k in (13, 21, 29, 34):
        assert err[k] < 0.01, (k, err[k])
    # every row, lost ones and the ones after them included, within 4 of its std on every axis
    _, motions, _ = read_motion_csv(drive / "groundtruth_motion.csv")
    for r, G in zip(res[1:], motions):
        T = r.prev_from_cur
        e = np.abs(np.r_[T[:3, 3] - G[:3, 3], so3_log(T[:3, :3] @ G[:3, :3].T)])
        assert np.all(e <= 4.0 * r.std), (r.index, r.status, e / r.std)
    for r in res:
        assert np.all(np.isfinite(r.world_from_cam)) and np.isfinite(r.msd)


def test_a_lost_frame_sends_the_tracker_recovering_until_it_re_anchors(drive):
    """The state machine: starting -> tracking; a lost frame -> recovering (its next guess
    from the rotation search); the next good frame anchors a new keyframe -> tracking."""
    cfg = load_init(drive / "init.yaml")
    imgs = [f.image for f in open_frames(drive / "frames")][:6]
    imgs[3] = np.zeros_like(imgs[3])
    odo = Odometry(cfg.camera, cfg.plane, cfg.region)
    assert odo.state is OdometryState.STARTING
    assert odo.start(0, 0.0, imgs[0]).status is FrameStatus.OK
    assert odo.state is OdometryState.STARTING
    seen = [(odo.step(k, float(k), imgs[k]).status, odo.state) for k in range(1, 6)]
    assert seen == [(FrameStatus.OK, OdometryState.TRACKING)] * 2 + [
        (FrameStatus.LOST, OdometryState.RECOVERING),
        (FrameStatus.REANCHORED, OdometryState.TRACKING),
        (FrameStatus.OK, OdometryState.TRACKING)]
    assert odo.keyframe.index == 4


def test_brightness_model_recovers_gain_and_bias(drive):
    cfg = load_init(drive / "init.yaml")
    fr = open_frames(drive / "frames")
    i0, i1 = fr.read(0).image, fr.read(1).image
    plane = cfg.plane
    corners = rectangle_corners(cfg.camera, plane, cfg.region)
    pyr0, pyr1 = build_pyramid(i0, 3), build_pyramid(1.2 * i1 - 10.0, 3)
    levels = [KeyLevel.from_points(select_points(pyr0[lv], cfg.camera.scaled(lv), plane, corners,
                                                 level=lv, threshold=5.0, max_points=8000))
              for lv in range(3)]
    est = estimate_motion(levels, pyr1, np.eye(4))
    # The mean brightness is matched exactly; the split into gain and bias is attenuated a
    # little (bilinear sampling smooths the fine detail of the current frame, ~5 %).
    mean = float(levels[0].points.intensity.mean())
    assert abs(est.gain * mean + est.bias - (1.2 * mean - 10.0)) < 1.0
    assert abs(est.gain - 1.2) < 0.08, (est.gain, est.bias)
    _, gt, _ = read_motion_csv(drive / "groundtruth_motion.csv")
    assert np.linalg.norm(se3_inv(est.cur_from_key)[:3, 3] - gt[0][:3, 3]) < 0.002


def test_prior_replaces_constant_velocity(drive):
    """Frames 21..29 dropped: frame 30 follows frame 20, ten steps (0.5 m) on where the constant
    velocity expects one. With the capture range narrowed to the rotation search (no feature
    hypothesis), the estimate started from the constant velocity's guess fails and the frame
    is lost, its pose the prediction, half a metre off; the prior (the true motion, as wheel
    odometry would give it) starts the estimate at the truth, and every frame is tracked to
    the millimetre."""
    order = [*range(21), 30, 31]
    frames = [f.image for f in open_frames(drive / "frames")]
    imgs = [frames[k] for k in order]
    _, T = read_tum(drive / "groundtruth.tum")
    truth = T[order]
    priors = {i: se3_inv(truth[i - 1]) @ truth[i] for i in range(1, len(order))}
    narrow = TrackOptions(feature_hypothesis=False)
    velocity = _track(drive, imgs, narrow)
    assert velocity[21].status == FrameStatus.LOST
    assert _pos_err(velocity, truth)[21] > 0.3
    res = _track(drive, imgs, narrow, priors=priors)
    assert [r.index for r in res if r.status == FrameStatus.LOST] == []
    assert _pos_err(res, truth).max() < 0.002


def test_max_step_marks_large_steps_lost(drive):
    """Every step is beyond the bound: no frame is accepted; after ``reinit_after`` lost frames
    in a row a fresh keyframe is anchored (status reinit), and the reason says why."""
    res = _track(drive, options=TrackOptions(max_step_m=0.01))
    statuses = [r.status for r in res[1:]]
    assert set(statuses) == {FrameStatus.LOST, FrameStatus.REINIT}
    assert all("beyond the maximum step 0.01 m" in r.reason for r in res[1:])
    run = 0
    for s in statuses:  # never more than reinit_after lost frames in a row
        run = run + 1 if s == FrameStatus.LOST else 0
        assert run <= TrackOptions().reinit_after
    assert all(np.all(np.isfinite(r.world_from_cam)) for r in res)


def test_cli_mask_prior_covariance(drive, tmp_path):
    mask = np.zeros((192, 192), np.uint8)
    mask[150:] = 255                                   # bottom rows never used
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    shutil.copy(drive / "groundtruth_motion.csv", tmp_path / "prior.csv")
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["track", str(drive), "-o", str(out), "-q",
                                  "--mask", str(tmp_path / "mask.png"),
                                  "--prior", str(tmp_path / "prior.csv"),
                                  "--covariance", str(tmp_path / "cov.csv"),
                                  "--max-step", "0.5,10"])
    assert r.exit_code == 0, r.output
    rows = list(csv.reader((tmp_path / "cov.csv").open()))
    assert len(rows) == 40 and len(rows[0]) == 37
    for row in rows[1:]:
        C = np.array([float(v) for v in row[1:]]).reshape(6, 6)
        np.testing.assert_allclose(C, C.T, atol=1e-15)
        assert np.all(np.linalg.eigvalsh(C) > 0)
    with (out / "motion.csv").open() as f:
        motion = list(csv.DictReader(f))
    stds = np.array([[float(m[f"std_{a}"]) for a in ("tx", "ty", "tz")] for m in motion])
    cov_std = np.array([np.sqrt(np.diag(np.array([float(v) for v in row[1:]]).reshape(6, 6))[:3])
                        for row in rows[1:]])
    np.testing.assert_allclose(stds, cov_std, rtol=1e-9)
    # a mask of the wrong size is bad input
    cv2.imwrite(str(tmp_path / "small.png"), mask[:100])
    r = CliRunner().invoke(main, ["track", str(drive), "-o", str(tmp_path / "o2"),
                                  "--mask", str(tmp_path / "small.png")])
    assert r.exit_code == 2 and "mask" in r.output


def test_masked_pixels_are_never_observation_points(drive):
    cfg = load_init(drive / "init.yaml")
    img = open_frames(drive / "frames").read(0).image
    plane = cfg.plane
    corners = rectangle_corners(cfg.camera, plane, cfg.region)
    usable = np.ones_like(img, bool)
    usable[100:] = False
    pts = select_points(img, cfg.camera, plane, corners, level=0, threshold=3.0,
                        max_points=5000, mask=usable)
    assert len(pts) > 500 and pts.uv[:, 1].max() < 100


def _reanchors(res) -> int:
    return [r.status for r in res].count(FrameStatus.REANCHORED)


def test_a_shadow_fixed_in_the_image_does_not_re_anchor_every_few_frames(tmp_path):
    """The rover's own shadow (a dark band over the image's bottom 15 %) mismatches the
    keyframe wherever the ground slides under it; the robust weights take those points out,
    and the fit's degradation is judged on the bulk of the points (their robust scale), so
    the shadow does not re-anchor. Measured over 60 frames: 3 re-anchors with the shadow, 4
    without; 19 when the degradation was judged on the mean squared difference."""
    counts = {}
    for name, kw in (("clean", {}), ("shadow", {"shadow": 0.15})):
        synthesize(tmp_path / name, preset="drive", frames=60, size=(192, 192), noise_var=10.0,
                   seed=21, **kw)
        counts[name] = _reanchors(_track(tmp_path / name))
    assert counts["shadow"] <= counts["clean"] + 2, counts


def test_a_fit_that_degrades_everywhere_re_anchors(drive):
    """A lens losing focus (every frame blurrier than the last) degrades the fit at all
    points: the keyframe is renewed when the robust msd doubles (measured: 7 re-anchors over
    40 frames, 3 without the rule)."""
    imgs = [f.image for f in open_frames(drive / "frames")]
    blurred = [im if k == 0 else cv2.GaussianBlur(im, (0, 0), 0.12 * k) for k, im in enumerate(imgs)]
    with_rule = _reanchors(_track(drive, blurred))
    without = _reanchors(_track(drive, blurred, TrackOptions(reanchor_msd_ratio=float("inf"))))
    assert with_rule >= without + 3, (with_rule, without)


def test_a_change_the_images_refute_the_prediction_of_keeps_its_own_std(synth_drive):
    """MER spacing (seed 2): frame 4 is the first turn in place after three 0.7 m steps, a
    change of 0.7 m and 17 deg the recent motions did not foresee. The estimator started at
    the prediction fails the checks there (a step where the rover turned fits near chance),
    the capture finds the turn, so the images refute the prediction: the row keeps its
    estimate (within a centimetre and 0.1 deg), is not lost, and its std stays its own,
    within 4 std of the truth. (Its std was widened to cover the prediction as well, 0.7 m
    and 17 deg, the turn's rows 100-1000 times their error: issue 40's std too large.)"""
    seq = synth_drive(preset="mer", frames=8, size=(256, 256), noise_var=10.0, seed=2)
    res = _track(seq)
    _, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    r, before, G = res[4], res[3], motions[3]
    assert r.status != FrameStatus.LOST
    T = r.prev_from_cur
    e = np.r_[T[:3, 3] - G[:3, 3], so3_log(T[:3, :3] @ G[:3, :3].T)]
    assert np.linalg.norm(e[:3]) < 0.01
    assert np.degrees(np.linalg.norm(e[3:])) < 0.1
    assert np.all(np.abs(e) <= 4.0 * r.std), e / r.std
    P = before.prev_from_cur
    change = np.abs(np.r_[T[:3, 3] - P[:3, 3], so3_log(T[:3, :3]) - so3_log(P[:3, :3])])
    assert change[3:].max() > np.radians(10)
    assert np.all(r.std[3:] < 0.01 * change[3:].max()), np.degrees(r.std)
