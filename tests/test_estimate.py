"""The estimator's pieces against ground truth: Jacobian vs finite differences, sampler."""

import numpy as np
import pytest

from monovo_cli.estimate import distortion_jacobian, observation_matrix, sample_bilinear
from monovo_cli.geometry import PinholeCamera, se3_exp


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


def test_packed_sampler_equals_plain_sampler():
    from monovo_cli.estimate import QuadImage

    rng = np.random.default_rng(5)
    img = rng.uniform(0, 255, (37, 53)).astype(np.float32)
    u = rng.uniform(-1, 54, 2000)
    v = rng.uniform(-1, 38, 2000)
    u[:5] = [0, 52, 52, 0, 26.5]
    v[:5] = [0, 36, 0, 36, 36]
    a, va = sample_bilinear(img, u, v)
    b, vb = sample_bilinear(QuadImage(img), u, v)
    assert np.array_equal(va, vb)
    np.testing.assert_array_equal(a[va], b[vb])


def _interior(rng, n, lo, hi_u, hi_v):
    return rng.uniform(lo, hi_u, n), rng.uniform(lo, hi_v, n)


def test_cubic_sampler_passes_through_the_pixels():
    """The prefilter makes the B-spline interpolate: at pixel centres it returns the pixels."""
    from monovo_cli.estimate import CubicImage

    rng = np.random.default_rng(7)
    img = rng.uniform(0, 255, (60, 70)).astype(np.float32)
    ys, xs = np.mgrid[0:60, 0:70]
    vals, valid = CubicImage(img).sample(xs.ravel().astype(float), ys.ravel().astype(float))
    assert valid.all()
    # Interior: only the truncation of the prefilter (0.27^9 of the contrast); the borders
    # are mirrored, so they interpolate too.
    np.testing.assert_allclose(vals, img.ravel(), atol=0.05)


@pytest.mark.parametrize("offset", [1e-3, 1.0 / 64, 0.5 + 1.0 / 1000, 0.999])
def test_cubic_sampler_reproduces_cubic_polynomials(offset):
    """A cubic B-spline reproduces polynomials up to degree 3 away from the borders."""
    from monovo_cli.estimate import CubicImage

    ys, xs = np.mgrid[0:60, 0:70].astype(np.float64)

    def f(x, y):
        return 20 + 1.5 * x - 0.8 * y + 0.02 * x * x + 0.01 * x * y - 1e-4 * y ** 3

    img = f(xs, ys).astype(np.float32)
    rng = np.random.default_rng(3)
    u = rng.integers(12, 55, 200) + offset
    v = rng.integers(12, 45, 200) + 0.7 * offset
    vals, valid = CubicImage(img).sample(u, v)
    assert valid.all()
    np.testing.assert_allclose(vals, f(u, v), atol=2e-3)


def test_cubic_sampler_beats_bilinear_on_fine_texture():
    """On a band-limited texture with detail down to 3 px, the spline's error is < 1/4 of
    bilinear interpolation's (the reason it samples the finest level)."""
    from monovo_cli.estimate import CubicImage

    rng = np.random.default_rng(11)
    waves = [(rng.uniform(-1 / 3, 1 / 3), rng.uniform(-1 / 3, 1 / 3), rng.uniform(0, 2 * np.pi))
             for _ in range(12)]

    def f(x, y):
        return 120 + sum(8 * np.cos(2 * np.pi * (a * x + b * y) + p) for a, b, p in waves)

    ys, xs = np.mgrid[0:80, 0:90].astype(np.float64)
    img = f(xs, ys).astype(np.float32)
    u, v = _interior(rng, 3000, 12, 77, 67)
    truth = f(u, v)
    cub, _ = CubicImage(img).sample(u, v)
    lin, _ = sample_bilinear(img, u, v)
    e_cub = np.sqrt(np.mean((cub - truth) ** 2))
    e_lin = np.sqrt(np.mean((lin - truth) ** 2))
    assert e_lin > 1.0  # the texture is fine enough to matter
    assert e_cub < 0.25 * e_lin


def test_cubic_sampler_flags_points_outside_like_bilinear():
    from monovo_cli.estimate import CubicImage

    img = _linear_image()
    u = np.array([-0.01, 0.0, 49.0, 49.01, 10.0, np.nan])
    v = np.array([5.0, 5.0, 39.0, 5.0, -1.0, 3.0])
    vals, valid = CubicImage(img).sample(u, v)
    assert valid.tolist() == [False, True, True, False, False, False]
    # At the borders the mirrored spline still reproduces the linear ramp.
    np.testing.assert_allclose(vals[1:3], [3.0 * 0 - 2.0 * 5 + 7, 3.0 * 49 - 2.0 * 39 + 7], atol=0.05)


def test_spline_gradient_is_the_derivative_of_the_sampled_spline():
    """The observation matrix at the finest level uses the spline's own derivative: equal to
    a finite difference of the cubic sampler, and exact on a cubic polynomial."""
    from monovo_cli.estimate import CubicImage
    from monovo_cli.ground import spline_gradient

    ys, xs = np.mgrid[0:50, 0:60].astype(np.float64)
    img = (0.02 * xs ** 2 - 0.01 * xs * ys + 1e-4 * ys ** 3 + 3 * xs).astype(np.float32)
    gx, gy = spline_gradient(img)
    sl = (slice(12, 38), slice(12, 48))
    np.testing.assert_allclose(gx[sl], (0.04 * xs - 0.01 * ys + 3)[sl], atol=2e-3)
    np.testing.assert_allclose(gy[sl], (-0.01 * xs + 3e-4 * ys ** 2)[sl], atol=2e-3)

    rng = np.random.default_rng(4)
    tex = rng.uniform(0, 255, (50, 60)).astype(np.float32)
    gx, gy = spline_gradient(tex)
    cub = CubicImage(tex)
    u, v = rng.integers(10, 50, 100).astype(float), rng.integers(10, 40, 100).astype(float)
    h = 1e-2
    fdx = (cub.sample(u + h, v)[0] - cub.sample(u - h, v)[0]) / (2 * h)
    fdy = (cub.sample(u, v + h)[0] - cub.sample(u, v - h)[0]) / (2 * h)
    iu, iv = u.astype(int), v.astype(int)
    np.testing.assert_allclose(gx[iv, iu], fdx, atol=0.05)
    np.testing.assert_allclose(gy[iv, iu], fdy, atol=0.05)
