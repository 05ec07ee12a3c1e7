"""A repetitive texture's periods (monovo_cli.core.aliases): found in the image, carried onto
the ground, and tested against a fit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from monovo_cli.core.aliases import ground_periods, image_periods, shifted
from monovo_cli.core.estimator.ground import rectangle_corners
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.pyramid import build_pyramid


def checker(h: int, w: int, square: int) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    return (((x // square) + (y // square)) % 2 * 200.0 + 20.0).astype(np.float32)


def noise(h: int, w: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.normal(128, 40, (h, w)).astype(np.float32), (5, 5), 1.5)


def test_a_checkerboards_lattice_is_found():
    """Squares of 8 px: the same colour repeats along the diagonals, (8, 8) and (-8, 8)."""
    found = image_periods(checker(200, 240, 8))
    assert sorted((round(du), round(dv)) for du, dv, _ in found) == [(-8, 8), (8, 8)]
    assert all(height > 0.95 for *_, height in found)


@pytest.mark.parametrize("seed", range(5))
def test_a_random_texture_has_no_period(seed):
    assert image_periods(noise(200, 240, seed)) == []


def test_a_period_on_the_ground_is_its_length_in_metres():
    """A camera 2 m above the ground looking straight down (f = 400 px): a square of 8 px is
    4 cm, so the diagonal period is 4 cm along each axis of the ground."""
    cam = PinholeCamera(256, 256, 400.0, 400.0, 127.5, 127.5)
    plane = Plane(np.array([0.0, 0.0, 1.0]), 2.0)
    corners = rectangle_corners(cam, plane, (0, 0, 256, 256))
    periods = ground_periods(build_pyramid(checker(256, 256, 8), 3), cam, plane, corners)
    assert periods.shape == (2, 3)
    np.testing.assert_allclose(np.sort(np.abs(periods[:, :2]), axis=0), 0.04, atol=1e-6)
    np.testing.assert_allclose(periods[:, 2], 0.0, atol=1e-9)  # along the plane


def test_a_textured_ground_has_no_period():
    cam = PinholeCamera(256, 256, 400.0, 400.0, 127.5, 127.5)
    plane = Plane(np.array([0.0, 0.0, 1.0]), 2.0)
    corners = rectangle_corners(cam, plane, (0, 0, 256, 256))
    assert ground_periods(build_pyramid(noise(256, 256), 3), cam, plane, corners).shape == (0, 3)


def test_a_shifted_pose_sees_the_point_one_period_along():
    T = np.eye(4)
    T[:3, 3] = (0.1, -0.2, 1.0)
    X = np.array([0.3, 0.4, 2.0])
    period = np.array([0.04, 0.0, 0.0])
    moved = shifted(T, period)
    np.testing.assert_allclose(moved[:3, :3] @ X + moved[:3, 3], T[:3, :3] @ (X + period) + T[:3, 3])


def test_a_model_written_without_periods_gets_those_of_its_frame():
    """``monovo init``'s model holds no periods: tracking finds them in frame 0, as a
    keyframe built there has them."""
    from dataclasses import replace

    from monovo_cli.core.aliases import with_periods
    from monovo_cli.core.keyframe import build_keyframe
    from monovo_cli.core.options import TrackOptions

    cam = PinholeCamera(256, 256, 400.0, 400.0, 127.5, 127.5)
    plane = Plane(np.array([0.0, 0.0, 1.0]), 2.0)
    image = checker(256, 256, 8)
    key = build_keyframe(0, image, cam, plane, (0, 0, 256, 256), np.eye(4), TrackOptions())
    assert key.periods.shape == (2, 3)
    np.testing.assert_array_equal(with_periods(replace(key, periods=None), image, cam).periods,
                                  key.periods)


def test_a_textured_ground_leaves_no_rival_minimum():
    """A fit on a fine random texture: every start around it comes back to it or fits
    worse, so no rival widens the row."""
    from monovo_cli.core.aliases import rivals
    from monovo_cli.core.estimator.estimate import estimate_motion
    from monovo_cli.core.keyframe import build_keyframe
    from monovo_cli.core.options import TrackOptions

    cam = PinholeCamera(256, 256, 400.0, 400.0, 127.5, 127.5)
    plane = Plane(np.array([0.0, 0.0, 1.0]), 2.0)
    image = noise(256, 256, 3)
    opts = TrackOptions()
    key = build_keyframe(0, image, cam, plane, (0, 0, 256, 256), np.eye(4), opts)
    pyr = build_pyramid(image, len(key.levels))
    est = estimate_motion(key.levels, pyr, np.eye(4), options=opts.estimator)
    assert rivals(key, pyr, est, opts.estimator) == []
