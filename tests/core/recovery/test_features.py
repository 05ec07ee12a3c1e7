"""The feature-based motion hypothesis (monovo_cli.core.recovery.features) against rendered ground truth.

MER spacing: a mast camera 1.5 m above the ground, pitched 45 deg down, 45 deg field of view,
0.6-0.75 m forward steps and 12-18 deg turns in place -- motions far outside the direct
estimator's capture range. Frames are rendered by monovo_cli.synth with noise (variance 10).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from benchmarks.common import mer_pose, mer_renderer
from monovo_cli.core.options import FeatureOptions, TrackOptions
from monovo_cli.core.recovery.features import (
    detect_features,
    feature_motion,
    ground_mask,
    pose_from_homography,
)
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, se3_inv, so3_exp, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.synth.motion import DRIVE_MAST_HEIGHT
from monovo_cli.synth.render import GroundRenderer, ground_in_camera
from monovo_cli.synth.rover import mer_camera

SIZE = 384
START = (1.0, 1.0, 30.0)  # x, y (m), heading (deg) of the keyframe


def errors(est: np.ndarray, gt: np.ndarray) -> tuple[float, float]:
    """(translation error m, rotation error deg) of two 4x4 poses."""
    E = est @ se3_inv(gt)
    return (float(np.linalg.norm(est[:3, 3] - gt[:3, 3])),
            float(np.degrees(np.linalg.norm(so3_log(E[:3, :3])))))


def noisy(image: np.ndarray, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(np.rint(image + rng.normal(0.0, math.sqrt(10.0), image.shape)), 0, 255).astype(np.uint8)


def forward(step: float, heading_deg: float = START[2]) -> np.ndarray:
    a = math.radians(START[2])
    return mer_pose(START[0] + step * math.cos(a), START[1] + step * math.sin(a), heading_deg)


@pytest.fixture(scope="module")
def scene():
    cam, renderer = mer_renderer(SIZE)
    g0 = mer_pose(*START)
    return cam, renderer, g0, noisy(renderer.render(g0), 0), Plane(*ground_in_camera(g0))


# --------------------------------------------------------------------------- pose from H


def test_pose_from_exact_homography_is_exact():
    """Any scale and sign of H_n = c (R + t n^T / d): the pose comes back to 1e-9."""
    rng = np.random.default_rng(5)
    cam = mer_camera(SIZE, SIZE)
    for _ in range(20):
        n = np.array([0.0, math.cos(math.radians(45)), math.sin(math.radians(45))])
        n = so3_exp(rng.uniform(-0.3, 0.3, 3)) @ n
        plane = Plane(n / np.linalg.norm(n), rng.uniform(0.5, 3.0))
        T = make_pose(so3_exp(rng.uniform(-0.4, 0.4, 3)), rng.uniform(-0.5, 0.5, 3))
        if plane.in_frame(T).distance <= 0.1:
            continue
        uv = rng.uniform(0, SIZE - 1, (50, 2))
        rays = cam.rays(uv)
        rays = rays[rays @ plane.normal > 0.05]
        X = plane.intersect(rays)
        if np.any(X @ T[2, :3] + T[2, 3] <= 0.05):  # keep only pairs that see the points
            continue
        H_n = T[:3, :3] + np.outer(T[:3, 3], plane.normal) / plane.distance
        for c in (1.0, 3.7, -0.02):
            got = pose_from_homography(c * H_n, plane, rays)
            assert got is not None
            est, consistency = got
            assert np.abs(est - T).max() < 1e-9
            assert abs(consistency - 1.0) < 1e-9


def test_pose_from_homography_refuses_the_far_side_of_the_plane():
    """A camera that sees the plane's points in front of it, but from below the ground, is
    not a pose of a camera above it: the plane's side decides."""
    plane = Plane(np.array([0.0, 0.0, 1.0]), 1.0)  # looking straight down from 1 m
    # current camera 1 m beyond the plane (key z = 2), looking back up: R = diag(1, -1, -1)
    R = np.diag([1.0, -1.0, -1.0])
    T = make_pose(R, -R @ np.array([0.0, 0.0, 2.0]))
    rays = mer_camera(64, 64).rays(np.array([[10.0, 10.0], [50.0, 20.0], [30.0, 60.0]]))
    X = plane.intersect(rays)
    assert np.all(X @ T[2, :3] + T[2, 3] > 0)  # in front of both cameras
    H_n = T[:3, :3] + np.outer(T[:3, 3], plane.normal) / plane.distance
    assert pose_from_homography(H_n, plane, rays) is None
    assert pose_from_homography(np.full((3, 3), np.nan), plane, rays) is None
    assert pose_from_homography(np.zeros((3, 3)), plane, rays) is None


# --------------------------------------------------------------------------- rendered pairs


@pytest.mark.parametrize("name, g1, tol_m, tol_deg", [
    ("0.75 m forward", forward(0.75), 0.02, 0.3),
    ("0.6 m forward", forward(0.6), 0.02, 0.3),
    ("18 deg left", mer_pose(*START[:2], START[2] + 18.0), 0.02, 0.3),
    ("12 deg right", mer_pose(*START[:2], START[2] - 12.0), 0.02, 0.3),
    ("0.6 m forward turning 15 deg", forward(0.6, START[2] + 15.0), 0.02, 0.3),
])
def test_mer_spacing_motions_are_recovered(scene, name, g1, tol_m, tol_deg):
    cam, renderer, g0, img0, plane = scene
    gt = se3_inv(g1) @ g0  # cur_from_key
    fm = feature_motion(img0, noisy(renderer.render(g1), 1), cam, plane)
    assert fm is not None, name
    dt, dr = errors(fm.cur_from_key, gt)
    assert dt < tol_m and dr < tol_deg, (name, dt, dr)
    assert fm.inliers >= 100 and fm.inlier_ratio > 0.5
    assert fm.rms_px < 2.0 and fm.planarity > 0.9
    # the inliers are true matches: the true motion carries each key ray onto its cur ray
    assert len(fm.key_rays) == len(fm.cur_rays) == fm.inliers
    Xc = plane.intersect(fm.key_rays) @ gt[:3, :3].T + gt[:3, 3]
    miss = (Xc[:, :2] / Xc[:, 2:] - fm.cur_rays[:, :2]) * cam.fx
    assert np.sqrt(np.mean(np.sum(miss ** 2, axis=1))) < 2.0
    # the homography maps keyframe pixels where the true motion puts the ground (in view)
    g = np.arange(8.0, SIZE, 32.0)
    uv0 = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    X = plane.intersect(cam.rays(uv0))
    truth = cam.project(X @ gt[:3, :3].T + gt[:3, 3])
    seen = np.all((truth >= 0) & (truth <= SIZE - 1), axis=1)
    assert seen.sum() >= 30
    T = fm.cur_from_key
    assert np.abs(cam.project(X[seen] @ T[:3, :3].T + T[:3, 3]) - truth[seen]).max() < 2.0
    h = np.c_[uv0[seen], np.ones(seen.sum())] @ fm.homography.T  # RANSAC's, 8 parameters
    assert np.abs(h[:, :2] / h[:, 2:] - truth[seen]).max() < 5.0


TRACKING = TrackOptions().features  # the tracker's: a level chosen by the frame size


@pytest.mark.parametrize("options", [TRACKING, FeatureOptions(level=1, features=1000)])
def test_cheap_modes_are_close_enough_for_the_direct_search(scene, options):
    """Fewer features, or detected at half resolution (keypoints scaled back to full)."""
    cam, renderer, g0, img0, plane = scene
    g1 = forward(0.75)
    fm = feature_motion(img0, noisy(renderer.render(g1), 1), cam, plane, options=options)
    assert fm is not None
    dt, dr = errors(fm.cur_from_key, se3_inv(g1) @ g0)
    assert dt < 0.05 and dr < 1.0


def test_cheap_level_keeps_the_shorter_side_near_256_px():
    levels = [TRACKING.level_for(PinholeCamera(w, h, 100.0, 100.0, w / 2, h / 2))
              for w, h in ((256, 256), (384, 384), (512, 512), (1024, 1024), (1241, 376), (2048, 600))]
    assert levels == [0, 0, 1, 2, 0, 1]
    assert FeatureOptions().level_for(PinholeCamera(1024, 1024, 1.0, 1.0, 0.0, 0.0)) == 0


def test_standing_start_gives_no_motion(scene):
    cam, renderer, g0, img0, plane = scene
    fm = feature_motion(img0, noisy(renderer.render(g0), 2), cam, plane)
    assert fm is not None
    dt, dr = errors(fm.cur_from_key, np.eye(4))
    assert dt < 0.005 and dr < 0.1


def test_deterministic(scene):
    """Same inputs, same answer, whatever OpenCV's RNG was left at by others."""
    cam, renderer, g0, img0, plane = scene
    img1 = noisy(renderer.render(forward(0.7)), 3)
    a = feature_motion(img0, img1, cam, plane)
    cv2.setRNGSeed(12345)
    cv2.randu(np.zeros((10, 10)), 0, 1)
    b = feature_motion(img0, img1, cam, plane)
    assert a is not None and b is not None
    assert np.array_equal(a.cur_from_key, b.cur_from_key)
    assert np.array_equal(a.homography, b.homography)
    assert (a.inliers, a.matches) == (b.inliers, b.matches)


def test_nothing_to_go_on_gives_none(scene):
    cam, renderer, g0, img0, plane = scene
    rng = np.random.default_rng(7)
    blank = np.full((SIZE, SIZE), 128, np.uint8)
    noise = rng.integers(0, 256, (SIZE, SIZE)).astype(np.uint8)
    noise2 = rng.integers(0, 256, (SIZE, SIZE)).astype(np.uint8)
    assert feature_motion(img0, blank, cam, plane) is None
    assert feature_motion(blank, img0, cam, plane) is None
    assert feature_motion(blank, blank, cam, plane) is None
    assert feature_motion(noise, noise2, cam, plane) is None
    assert feature_motion(img0, noise, cam, plane) is None
    assert feature_motion(img0.astype(np.float32), np.full((SIZE, SIZE), np.nan, np.float32),
                          cam, plane) is None
    # the plane behind the camera: nowhere to look for features
    assert feature_motion(img0, img0, cam, Plane(-plane.normal, plane.distance)) is None


def test_lens_distortion_is_removed_from_the_keypoints():
    """A barrel lens: with the camera's distortion the motion is found; ignoring it, it is not."""
    w = h = 256
    pad = 64
    dist = (-0.25, 0.06, 0.0, 0.0, 0.0)
    base = mer_camera(w, w)
    dcam = PinholeCamera(w, h, base.fx, base.fy, base.cx, base.cy, dist)
    big = PinholeCamera(w + 2 * pad, h + 2 * pad, base.fx, base.fy, base.cx + pad, base.cy + pad)
    _, r = mer_renderer(w)
    renderer = GroundRenderer(big, r.texture, supersample=2)
    ys, xs = np.mgrid[0:h, 0:w]
    rays = dcam.rays(np.stack([xs.ravel(), ys.ravel()], 1).astype(float))
    mx = (big.fx * rays[:, 0] + big.cx).reshape(h, w).astype(np.float32)
    my = (big.fy * rays[:, 1] + big.cy).reshape(h, w).astype(np.float32)
    g0, g1 = mer_pose(*START), mer_pose(*START[:2], START[2] + 12.0)
    imgs = [noisy(cv2.remap(renderer.render(g), mx, my, cv2.INTER_CUBIC), s)
            for s, g in enumerate((g0, g1))]
    plane = Plane(*ground_in_camera(g0))
    gt = se3_inv(g1) @ g0
    fm = feature_motion(*imgs, dcam, plane)
    assert fm is not None
    dt, dr = errors(fm.cur_from_key, gt)
    assert dt < 0.02 and dr < 0.3
    naive = feature_motion(*imgs, base, plane)  # the same pixels taken for a pinhole's
    assert naive is None or max(errors(naive.cur_from_key, gt)[0] / 0.02,
                                errors(naive.cur_from_key, gt)[1] / 0.3) > 2 * max(dt / 0.02, dr / 0.3)


# --------------------------------------------------------------------------- masks


def test_ground_mask_is_the_ground_below_the_horizon():
    """A level camera sees the ground below the image centre row only; region and mask cut it."""
    cam = PinholeCamera(200, 100, 100.0, 100.0, 99.5, 49.5)
    plane = Plane(np.array([0.0, 1.0, 0.0]), DRIVE_MAST_HEIGHT)  # level: horizon through cy
    m = ground_mask(cam, plane, min_depression_deg=0.0)
    rows = np.nonzero(m.any(axis=1))[0]
    assert m.dtype == np.uint8 and set(np.unique(m)) == {0, 255}
    assert abs(rows[0] - 50) <= 1 and rows[-1] == 99 and m[rows[0] + 1:].all()
    m10 = ground_mask(cam, plane, min_depression_deg=10.0)
    first = 49.5 + 100.0 * math.tan(math.radians(10.0))
    assert abs(np.nonzero(m10.any(axis=1))[0][0] - first) <= 1.0
    usable = np.ones((100, 200), bool)
    usable[:, :100] = False
    m = ground_mask(cam, plane, region=(20, 0, 180, 90), usable=usable)
    assert not m[:, :100].any() and not m[90:].any() and not m[:, 180:].any()
    assert m[60:90, 101:180].all()
    m1 = ground_mask(cam, plane, level=1, region=(20, 0, 180, 90))
    assert m1.shape == (50, 100) and not m1[:, :10].any() and not m1[45:].any()


def test_features_come_only_from_usable_ground(scene):
    cam, _, _, img0, plane = scene
    usable = np.ones((SIZE, SIZE), bool)
    usable[:, : SIZE // 2] = False
    for opt in (FeatureOptions(), FeatureOptions(level=1)):
        f = detect_features(img0, cam, options=opt,
                            mask=ground_mask(cam, plane, level=opt.level_for(cam), usable=usable,
                                             region=(0, 100, SIZE, SIZE)))
        assert len(f) > 100
        assert f.uv[:, 0].min() >= SIZE // 2 - 1 and f.uv[:, 1].min() >= 99
