"""The estimator's pieces against ground truth: Jacobian vs finite differences, sampler."""

import numpy as np
import pytest

from monovo_cli.core.estimator.jacobian import distortion_jacobian, observation_matrix
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_exp
from monovo_cli.image.sampling import sample_bilinear


def _linear_image(h=40, w=50, a=3.0, b=-2.0, c=7.0):
    ys, xs = np.mgrid[0:h, 0:w]
    return (a * xs + b * ys + c).astype(np.float32)


@pytest.mark.parametrize("distortion", [(0.0,) * 5, (-0.25, 0.08, 0.001, -0.002, 0.01)])
def test_observation_matrix_matches_finite_differences(distortion):
    """o_i = d I(pi(exp(xi) X_i)) / d xi at xi = 0, for a linear intensity I(u, v) = g . (u, v)."""
    rng = np.random.default_rng(1)
    cam = PinholeCamera(640, 480, 600.0, 610.0, 319.5, 239.5, distortion)
    X = np.column_stack([rng.uniform(-2, 2, 50), rng.uniform(-1, 2, 50), rng.uniform(2, 9, 50)])
    grad = rng.normal(size=(50, 2)).astype(np.float32) * 20

    def intensity(xi):
        T = se3_exp(xi)
        uv = cam.project(X @ T[:3, :3].T + T[:3, 3])
        return (uv * grad.astype(np.float64)).sum(axis=1)

    D = distortion_jacobian(cam, X) if cam.has_distortion else None
    O = observation_matrix(X, grad, cam.fx, cam.fy, D)
    eps = 1e-6
    for j in range(6):
        e = np.zeros(6)
        e[j] = eps
        fd = (intensity(e) - intensity(-e)) / (2 * eps)
        np.testing.assert_allclose(O[:, j], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("offset", [1e-3, 1.0 / 64, 0.01, 0.5 + 1.0 / 1000, 0.999])
def test_bilinear_sampler_is_exact_below_1_32_px(offset):
    """On a linear image bilinear interpolation is exact: no 1/32 px quantisation."""
    img = _linear_image()
    rng = np.random.default_rng(2)
    u = rng.integers(1, 45, 100) + offset
    v = rng.integers(1, 35, 100) + offset * 0.5
    vals, valid = sample_bilinear(img, u, v)
    assert valid.all()
    np.testing.assert_allclose(vals, 3.0 * u - 2.0 * v + 7.0, atol=2e-4)


def test_bilinear_sampler_flags_points_outside():
    img = _linear_image()
    u = np.array([-0.01, 0.0, 49.0, 49.01, 10.0, np.nan])
    v = np.array([5.0, 5.0, 39.0, 5.0, -1.0, 3.0])
    _, valid = sample_bilinear(img, u, v)
    assert valid.tolist() == [False, True, True, False, False, False]


def test_stacked_planes_sample_as_each_plane_alone():
    """An image and its gradients sampled in one remap give each plane's own samples and
    validity bit for bit, at positions inside, on and beyond the border."""
    import cv2

    rng = np.random.default_rng(5)
    planes = [(rng.random((40, 50)) * 255).astype(np.float32) for _ in range(3)]
    planes[1] -= 128.0  # (signed, as gradients are)
    u = np.r_[rng.random(3000) * 53 - 1.5, 0.0, 49.0, -1e-4, np.nan]
    v = np.r_[rng.random(3000) * 43 - 1.5, 0.0, 39.0, 5.0, 3.0]
    vals, valid = sample_bilinear(cv2.merge(planes), u, v)
    assert 0 < np.count_nonzero(valid) < len(u)
    for c, plane in enumerate(planes):
        alone, ok = sample_bilinear(plane, u, v)
        assert np.array_equal(ok, valid)
        assert np.array_equal(alone, vals[:, c])


def _grid(u, v):
    from monovo_cli.image.sampling import pixel_grid

    return pixel_grid(np.asarray(u, float), np.asarray(v, float))


@pytest.mark.parametrize("interpolation,px", [("linear", 1e-4), ("cubic", 0.05), ("lanczos4", 0.035)])
def test_remap_sampler_follows_a_linear_image(interpolation, px):
    """Bilinear interpolation reproduces a ramp; OpenCV's bicubic kernel (Keys, a = -0.75)
    and its Lanczos-4 (tabulated at 1/32 px) read it up to 0.048 / 0.03 px off, by the
    sample's fraction, unbiased on average."""
    from monovo_cli.image.sampling import INTERPOLATION, sample_at

    img = _linear_image(60, 70)
    rng = np.random.default_rng(2)
    u, v = rng.uniform(6, 62, 3000), rng.uniform(6, 52, 3000)
    vals, valid = sample_at(img, _grid(u, v), len(u), INTERPOLATION[interpolation])
    assert valid.all()
    err = vals - (3.0 * u - 2.0 * v + 7.0)
    assert np.abs(err).max() <= (3.0 + 2.0) * px + 1e-3
    assert abs(err.mean()) < 0.01


@pytest.mark.parametrize("interpolation,reach", [("linear", 1), ("cubic", 3), ("lanczos4", 4)])
def test_remap_sampler_flags_points_outside_and_near_the_border(interpolation, reach):
    """Valid inside, with the kernel's support (``reach`` px) clear of the border; outside
    the image, NaN, inf and the grid's padding are invalid, and invalid points read 0."""
    from monovo_cli.image.sampling import INTERPOLATION, sample_at

    img = _linear_image(40, 50) + 100.0
    u = [reach, 49.0 - reach, 25.5, -0.01, 49.01, 25.0, 25.0, np.nan, np.inf, 20.0]
    v = [20.0, 20.0, 20.25, 20.0, 20.0, -0.5, 39.5, 5.0, 5.0, -np.inf]
    vals, valid = sample_at(img, _grid(u, v), len(u), INTERPOLATION[interpolation])
    assert valid.tolist() == [True] * 3 + [False] * 7
    assert np.all(vals[~valid] == 0.0)


@pytest.mark.parametrize("interpolation,reach", [("linear", (0, 0)), ("cubic", (1, 2))])
def test_sampler_validity_means_no_pixel_outside_was_weighted(interpolation, reach):
    """Near the border, with fractions at 0, a hair above 0 and a hair below 1: a valid sample
    equals the sample under two different borders (it weighted no pixel outside), and every
    sample whose kernel reach is inside the image is valid."""
    import cv2

    from monovo_cli.image.sampling import INTERPOLATION, sample_at

    rng = np.random.default_rng(5)
    img = rng.uniform(0, 255, (40, 50)).astype(np.float32)
    base = rng.integers(-2, 4, 4000).astype(float)
    frac = rng.choice([0.0, 1e-6, 1e-3, 1 - 1e-6, 0.5], 4000)
    u = np.where(rng.random(4000) < 0.5, base + frac, 49.0 - base - frac)
    v = rng.uniform(-3, 43, 4000)
    flag = INTERPOLATION[interpolation]
    grid = _grid(u, v)
    vals, valid = sample_at(img, grid, len(u), flag)
    for border in (cv2.BORDER_REPLICATE, cv2.BORDER_REFLECT_101):
        other = cv2.remap(img, grid, None, flag, borderMode=border).reshape(-1)[:len(u)]
        assert np.array_equal(vals[valid], other[valid])
    lo, hi = reach
    inside = (u >= lo) & (u <= 49 - hi) & (v >= lo) & (v <= 39 - hi)
    assert valid[inside].all() and inside.sum() > 500
    assert np.all(vals[~valid] == 0.0) and (~valid).sum() > 500


def test_cubic_sampler_beats_bilinear_on_fine_texture():
    """On a band-limited texture with detail down to 3 px, cubic interpolation's error is
    < 1/2 of bilinear interpolation's (the reason it samples the finest level)."""
    from monovo_cli.image.sampling import INTERPOLATION, sample_at

    rng = np.random.default_rng(11)
    waves = [(rng.uniform(-1 / 3, 1 / 3), rng.uniform(-1 / 3, 1 / 3), rng.uniform(0, 2 * np.pi))
             for _ in range(12)]

    def f(x, y):
        return 120 + sum(8 * np.cos(2 * np.pi * (a * x + b * y) + p) for a, b, p in waves)

    ys, xs = np.mgrid[0:80, 0:90].astype(np.float64)
    img = f(xs, ys).astype(np.float32)
    u, v = _interior(rng, 3000, 12, 77, 67)
    truth = f(u, v)
    err = {}
    for name in ("linear", "cubic", "lanczos4"):
        vals, _ = sample_at(img, _grid(u, v), len(u), INTERPOLATION[name])
        err[name] = np.sqrt(np.mean((vals - truth) ** 2))
    assert err["linear"] > 1.0  # the texture is fine enough to matter
    assert err["cubic"] < 0.5 * err["linear"]
    assert err["lanczos4"] < err["cubic"]


def _interior(rng, n, lo, hi_u, hi_v):
    return rng.uniform(lo, hi_u, n), rng.uniform(lo, hi_v, n)


def test_spline_gradient_is_exact_on_a_cubic_polynomial():
    """The observation matrix at the finest level uses the interpolating cubic B-spline's
    derivative at the keyframe pixels: exact on a cubic polynomial away from the borders."""
    from monovo_cli.image.gradients import spline_gradient

    ys, xs = np.mgrid[0:50, 0:60].astype(np.float64)
    img = (0.02 * xs ** 2 - 0.01 * xs * ys + 1e-4 * ys ** 3 + 3 * xs).astype(np.float32)
    gx, gy = spline_gradient(img)
    sl = (slice(12, 38), slice(12, 48))
    np.testing.assert_allclose(gx[sl], (0.04 * xs - 0.01 * ys + 3)[sl], atol=2e-3)
    np.testing.assert_allclose(gy[sl], (-0.01 * xs + 3e-4 * ys ** 2)[sl], atol=2e-3)


def _plane_level(cam, rng, n=400):
    """A KeyLevel of random keyframe pixels lifted onto a tilted plane in front of ``cam``."""
    from monovo_cli.core.estimator.estimate import KeyLevel
    from monovo_cli.core.estimator.ground import LevelPoints
    from monovo_cli.geometry.plane import Plane

    plane = Plane(np.array([0.0, -0.6, 0.8]) / np.linalg.norm([0.0, -0.6, 0.8]), 4.0)
    uv = np.column_stack([rng.uniform(20, cam.width - 20, n), rng.uniform(20, cam.height - 20, n)])
    X = plane.intersect(cam.rays(uv))
    pts = LevelPoints(0, cam, uv, X, np.full(n, 100.0, np.float32),
                      rng.normal(size=(n, 2)).astype(np.float32), np.zeros((4, 3)))
    return KeyLevel.from_points(pts)


@pytest.mark.parametrize("seed", range(5))
def test_homography_warp_equals_moving_and_projecting_the_points(seed):
    """The plane's homography on the keyframe pixels lands where the moved 3-D points project."""
    rng = np.random.default_rng(seed)
    cam = PinholeCamera(640, 480, 600.0, 610.0, 319.5, 239.5)
    level = _plane_level(cam, rng)
    T = se3_exp(np.r_[rng.normal(0, 0.3, 3), rng.normal(0, 0.05, 3)])
    grid = level.warp_grid(T).reshape(-1, 2)[:len(level.points)]
    expected = cam.project(level.points.X @ T[:3, :3].T + T[:3, 3])
    np.testing.assert_allclose(grid, expected, atol=2e-3)


def test_points_behind_the_camera_are_invalid():
    """A pose that puts part of the plane behind the camera: those points are not sampled."""
    from monovo_cli.core.estimator.estimate import residuals

    rng = np.random.default_rng(8)
    cam = PinholeCamera(640, 480, 600.0, 610.0, 319.5, 239.5)
    level = _plane_level(cam, rng)
    T = np.eye(4)
    T[2, 3] = -float(np.median(level.points.X[:, 2]))  # half the points end up behind
    behind = level.points.X[:, 2] + T[2, 3] <= 0
    assert 0 < behind.sum() < len(behind)
    img = rng.uniform(0, 255, (480, 640)).astype(np.float32)
    r, valid = residuals(level, img, T)
    assert not valid[behind].any()
    assert np.all(r[~valid] == 0.0)
