"""Lens distortion: handled by undistorting point coordinates, tested on a distorted drive."""

import cv2
import numpy as np
import pytest

from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.synth.motion import drive_poses
from monovo_cli.synth.render import GroundRenderer, default_camera, ground_in_camera
from monovo_cli.synth.texture import GroundTexture, procedural_texture

DIST = (-0.22, 0.06, 0.0008, -0.0006, 0.0)


@pytest.fixture(scope="module")
def distorted_drive():
    """A 25-frame 192x192 drive seen through a barrel-distorted lens (plus its truth)."""
    w = h = 192
    pad = 64
    cam = default_camera(w, h)
    dcam = PinholeCamera(w, h, cam.fx, cam.fy, cam.cx, cam.cy, DIST)
    big = PinholeCamera(w + 2 * pad, h + 2 * pad, cam.fx, cam.fy, cam.cx + pad, cam.cy + pad)
    tex = GroundTexture(procedural_texture(1024, 3), 0.006)
    renderer = GroundRenderer(big, tex)
    rng = np.random.default_rng(4)
    poses = drive_poses(25, rng, peak_step=0.065, origin=(1.0, 1.0))
    # where each distorted pixel looks, in the undistorted (big) image
    ys, xs = np.mgrid[0:h, 0:w]
    rays = dcam.rays(np.stack([xs.ravel(), ys.ravel()], 1).astype(float))
    mx = (big.fx * rays[:, 0] + big.cx).reshape(h, w).astype(np.float32)
    my = (big.fy * rays[:, 1] + big.cy).reshape(h, w).astype(np.float32)
    frames = []
    for k, g in enumerate(poses):
        img = cv2.remap(renderer.render(g), mx, my, cv2.INTER_CUBIC)
        img = img + rng.normal(0, np.sqrt(10.0), img.shape)
        frames.append((k, float(k), np.clip(np.round(img), 0, 255).astype(np.float32)))
    n, d = ground_in_camera(poses[0])
    truth = [se3_inv(poses[0]) @ g for g in poses]
    return dcam, Plane(np.asarray(n), float(d)), frames, truth


def _final_error(camera, plane, frames, truth):
    res = list(estimate_frames(iter(frames), camera, plane, (0, 0, camera.width, camera.height),
                     TrackOptions(max_points=6000)))
    est = res[-1].world_from_cam
    return (np.linalg.norm(est[:3, 3] - truth[-1][:3, 3]),
            np.degrees(np.linalg.norm(so3_log(est[:3, :3].T @ truth[-1][:3, :3]))),
            [r.status for r in res])


def test_distorted_drive_is_tracked_when_the_lens_is_modelled(distorted_drive):
    cam, plane, frames, truth = distorted_drive
    dist = sum(np.linalg.norm(truth[k][:3, 3] - truth[k - 1][:3, 3]) for k in range(1, len(truth)))
    err, rot, status = _final_error(cam, plane, frames, truth)
    assert FrameStatus.LOST not in status
    assert err < 0.01 * dist, (err, dist)
    assert rot < 0.2
    # ignoring the distortion is visibly worse: the handling is what makes it work
    pinhole = PinholeCamera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
    err0, _, _ = _final_error(pinhole, plane, frames, truth)
    assert err0 > 3 * err, (err0, err)
    print(f"distorted drive: error {err:.5f} m of {dist:.3f} m modelled, {err0:.5f} m ignored")
