"""SE(3)/SO(3)/quaternion round trips and the pinhole camera."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import (
    matrix_from_quat,
    orthonormalize,
    quat_from_matrix,
    se3_exp,
    se3_inv,
    se3_log,
    so3_exp,
    so3_log,
)
from monovo_cli.geometry.plane import Plane

twists = st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6).map(np.array)


@settings(max_examples=200, deadline=None)
@given(twists, st.sampled_from([1.0, 1e-3, 1e-7, 1e-9]))
def test_se3_exp_is_the_matrix_exponential(xi, scale):
    """Closed form against the power series of the 4x4 twist matrix, down to tiny angles."""
    xi = xi * scale
    M = np.zeros((4, 4))
    M[:3, :3] = [[0.0, -xi[5], xi[4]], [xi[5], 0.0, -xi[3]], [-xi[4], xi[3], 0.0]]
    M[:3, 3] = xi[:3]
    term, series = np.eye(4), np.eye(4)
    for k in range(1, 60):
        term = term @ M / k
        series = series + term
    np.testing.assert_allclose(se3_exp(xi), series, atol=1e-12 * max(1.0, np.abs(series).max()))


@settings(max_examples=300, deadline=None)
@given(twists)
def test_se3_exp_log_round_trip(xi):
    if np.linalg.norm(xi[3:]) >= np.pi - 1e-3:
        xi = xi.copy()
        xi[3:] *= (np.pi - 1e-2) / np.linalg.norm(xi[3:])
    T = se3_exp(xi)
    np.testing.assert_allclose(se3_log(T), xi, atol=1e-8)
    np.testing.assert_allclose(se3_exp(se3_log(T)), T, atol=1e-10)


@settings(max_examples=300, deadline=None)
@given(twists)
def test_quaternion_round_trip_and_sign(xi):
    R = so3_exp(xi[3:])
    q = quat_from_matrix(R)
    assert q[3] >= 0
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(matrix_from_quat(q), R, atol=1e-12)


def test_so3_log_near_pi():
    w = np.array([0.3, -0.5, 0.81])
    w = w / np.linalg.norm(w) * (np.pi - 1e-7)
    np.testing.assert_allclose(so3_log(so3_exp(w)), w, atol=1e-6)


def test_inverse_and_orthonormalize():
    rng = np.random.default_rng(0)
    T = se3_exp(rng.normal(size=6))
    np.testing.assert_allclose(se3_inv(T) @ T, np.eye(4), atol=1e-12)
    bent = T.copy()
    bent[:3, :3] *= 1.001
    fixed = orthonormalize(bent)
    np.testing.assert_allclose(fixed[:3, :3].T @ fixed[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(fixed, T, atol=1e-9)


def test_quaternion_of_known_rotation():
    q = quat_from_matrix(so3_exp([0, 0, np.pi / 2]))
    np.testing.assert_allclose(q, [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)


@pytest.mark.parametrize("level", [1, 2, 3])
def test_scaled_camera_matches_cv2_pyrdown(level):
    """A bright dot seen at level 0 is where the scaled camera projects it at level l."""
    import cv2

    from monovo_cli.image.pyramid import build_pyramid

    cam = PinholeCamera(160, 128, 150.0, 140.0, 79.5, 63.5)
    X = np.array([[0.1, -0.05, 1.0]])
    u, v = cam.project(X)[0]
    ys, xs = np.mgrid[0:128, 0:160]
    img = 200.0 * np.exp(-((xs - u) ** 2 + (ys - v) ** 2) / (2 * 6.0 ** 2))
    top = build_pyramid(img.astype(np.float32), level + 1)[level].astype(np.float64)
    m = cv2.moments(top)
    centroid = np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])
    np.testing.assert_allclose(centroid, cam.scaled(level).project(X)[0], atol=0.02)


def test_plane_transform_and_ray_intersection():
    rng = np.random.default_rng(3)
    plane = Plane(np.array([0.0, np.sqrt(0.5), np.sqrt(0.5)]), 1.5)
    cam = PinholeCamera(64, 48, 50.0, 50.0, 31.5, 23.5)
    X = plane.intersect(cam.rays(rng.uniform(0, 40, (20, 2))))
    np.testing.assert_allclose(X @ plane.normal, 1.5, atol=1e-12)
    T = se3_exp(rng.normal(size=6) * 0.2)
    moved = plane.in_frame(T)
    Xb = X @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(Xb @ moved.normal, moved.distance, atol=1e-12)


@pytest.mark.parametrize("pitch, roll", [(45.0, 0.0), (30.0, -7.5), (89.0, 12.0), (10.0, 170.0)])
def test_pitch_roll_of_a_normal_round_trip(pitch, roll):
    from monovo_cli.geometry.plane import normal_from_pitch_roll, pitch_roll_deg

    got = pitch_roll_deg(normal_from_pitch_roll(pitch, roll))
    np.testing.assert_allclose(got, (pitch, roll), atol=1e-9)
