"""Terrain beyond the plane, a first step: each observation point's depth refined along its ray.

A keyframe's observation points are lifted onto its plane. When the keyframe is left (a
re-anchor), the frame that replaces it sees them from a baseline of the keyframe's whole
life; :func:`refine_depths` then moves each point along its viewing ray to where the two
images agree: per point, a Gauss-Newton on its depth ``z`` (the point is ``z * ray``,
``ray = K^-1 (u, v, 1)``) minimising

    w(r) r(z)^2 / sigma_r^2 + (z - z_plane)^2 / sigma_z^2,
    r(z) = I_cur(pi(T z ray)) - (gain I_key + bias),

a prior toward the plane (``sigma_z``: a height departure ``sigma_h`` along the normal,
``sigma_h / (n . ray)`` along the ray) and Huber weights ``w`` (a point occluded in the
current frame, a rock's side, does not drag its depth far). The derivative of r along the
ray is the image gradient times the projection's Jacobian times ``R ray``: where the
texture's gradient is across the epipolar line the depth is measured; where it runs along
it the prior keeps the plane's depth, and the returned std says so. Gain and bias come from
a straight-line fit of the two images' intensities at the planar positions.

This is the semi-dense direct methods' depth filter reduced to one update per keyframe; it
feeds the terrain products (:mod:`monovo_cli.mapping.terrain_map`), not yet the tracking,
whose warp is still the plane's homography.

:func:`sweep_depths` is the terrain products' default: the ground is already on the
keyframe's relief (:mod:`monovo_cli.core.estimator.relief`), and what it misses are small objects, a
rock 5-20 cm high that a 0.4 m grid does not see, too far from the relief for one
Gauss-Newton step from it under a prior toward it. So it searches instead: each point's
height along its ray over a range above and below where it is (a plane sweep: every third
step, then single steps around the best), matched by
its 3 x 3 patch facing the camera, and moves it only where the images say so clearly: the
patch's squared difference drops by more than SWEEP_DROP noise variances, the best match is
as good as noise allows (below SWEEP_MATCH noise variances per pixel) and it is not at the
range's end. Only points whose patch disagrees by SWEEP_DROP noise variances where they are
can move, so only those are searched (4-6 % of the points on the terrain drives).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monovo_cli.core.estimator.jacobian import project_in_front
from monovo_cli.core.estimator.robust import mad_scale
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import sobel_gradient
from monovo_cli.image.sampling import sample_bilinear

HEIGHT_SIGMA = 0.05  # m: the prior's std of a point's height off its keyframe plane
HUBER_K = 1.345
MAX_STEP = 0.5  # a step moves a point by at most this many sigma_z
PATCH_RADIUS = 1  # a point is matched by its 3 x 3 patch (with the keyframe image)
SWEEP_HEIGHTS = (-0.10, 0.30, 0.01)  # m: sweep_depths' heights off the point, (lowest, highest, step)
SWEEP_DROP = 25.0  # noise variances the patch's squared difference must drop by to move a point
SWEEP_MATCH = 2.0  # and at most this many noise variances per patch pixel at the best height


@dataclass(frozen=True)
class Depths:
    """Refined points ``X`` (N, 3) in the keyframe camera (m), the depths' std ``std`` (N,)
    (m along the optical axis; the prior's where the images say nothing) and ``measured``
    (N,) bool: the point was in view of the current frame and its depth was updated."""

    X: np.ndarray
    std: np.ndarray
    measured: np.ndarray


def refine_depths(camera: PinholeCamera, plane: Plane, X: np.ndarray, intensity: np.ndarray,
                  image: np.ndarray, cur_from_key: np.ndarray, *,
                  key_image: np.ndarray | None = None, radius: int = PATCH_RADIUS,
                  height_sigma: float = HEIGHT_SIGMA, iterations: int = 6) -> Depths:
    """Refine the depths of points ``X`` (N, 3) lying on ``plane`` (keyframe camera) with
    keyframe ``intensity`` (N,), from the current frame ``image`` (H, W) float32 at
    ``cur_from_key`` (4x4) (module docstring). With the keyframe's ``key_image`` each point
    is matched by its (2 radius + 1)^2 patch, all at the point's depth (a patch facing the
    camera), instead of by its own pixel. A pinhole camera without distortion."""
    X = np.asarray(X, dtype=np.float64)
    n = len(X)
    rays = X / X[:, 2:3]
    z_plane = X[:, 2].copy()
    sigma_z = height_sigma / np.clip(rays @ plane.normal, 1e-6, None)
    R, t = cur_from_key[:3, :3], cur_from_key[:3, 3]
    gx_img, gy_img = sobel_gradient(np.ascontiguousarray(image, dtype=np.float32))
    if key_image is not None and radius > 0:
        offs = [(dx, dy) for dy in range(-radius, radius + 1) for dx in range(-radius, radius + 1)]
        u0 = camera.fx * rays[:, 0] + camera.cx
        v0 = camera.fy * rays[:, 1] + camera.cy
        patch_rays = np.concatenate([np.column_stack([(u0 + dx - camera.cx) / camera.fx,
                                                      (v0 + dy - camera.cy) / camera.fy,
                                                      np.ones(n)]) for dx, dy in offs])
        I_key = np.concatenate([sample_bilinear(key_image, u0 + dx, v0 + dy)[0]
                                for dx, dy in offs]).astype(np.float64)
    else:
        offs, patch_rays = [(0, 0)], rays
        I_key = np.asarray(intensity, dtype=np.float64)
    m = len(offs)
    Rr = patch_rays @ R.T  # d Xc / d z, per patch pixel (m n, 3), offset-major

    def sample(z):
        zz = np.tile(z, m)
        Xc = Rr * zz[:, None] + t
        u, v, front = project_in_front(camera, Xc)
        vals, ok = sample_bilinear(image, u, v)
        return Xc, u, v, vals.astype(np.float64), ok & front

    def per_point(a):  # (m n,) -> (n,): sum over each point's patch
        return a.reshape(m, n).sum(axis=0)

    z = z_plane.copy()
    _, _, _, vals, ok = sample(z)
    if np.count_nonzero(ok) < 20:
        return Depths(X.copy(), sigma_z, np.zeros(n, bool))
    A = np.column_stack([I_key[ok], np.ones(np.count_nonzero(ok))])
    gain, bias = np.linalg.lstsq(A, vals[ok], rcond=None)[0]
    r = vals - (gain * I_key + bias)
    sigma_r = max(float(mad_scale(r.astype(np.float32), ok)), 1e-3)
    info = np.zeros(n)
    inside = np.zeros(n, bool)
    for _ in range(iterations):
        Xc, u, v, vals, ok = sample(z)
        gx, _ = sample_bilinear(gx_img, u, v)
        gy, _ = sample_bilinear(gy_img, u, v)
        iz = np.where(ok, 1.0 / np.where(ok, Xc[:, 2], 1.0), 0.0)
        du = camera.fx * iz * (Rr[:, 0] - Xc[:, 0] * iz * Rr[:, 2])
        dv = camera.fy * iz * (Rr[:, 1] - Xc[:, 1] * iz * Rr[:, 2])
        J = np.where(ok, gx * du + gy * dv, 0.0)
        r = np.where(ok, vals - (gain * I_key + bias), 0.0)
        a = np.abs(r) / sigma_r
        w = np.where(a <= HUBER_K, 1.0, HUBER_K / np.maximum(a, 1e-12))
        inside = ok.reshape(m, n).all(axis=0)
        info = np.where(inside, per_point(w * J * J), 0.0) / sigma_r ** 2
        H = info + 1.0 / sigma_z ** 2
        g = np.where(inside, per_point(w * J * r), 0.0) / sigma_r ** 2 + (z - z_plane) / sigma_z ** 2
        step = np.clip(-g / H, -MAX_STEP * sigma_z, MAX_STEP * sigma_z)
        z = z + np.where(inside, step, 0.0)
    std = 1.0 / np.sqrt(info + 1.0 / sigma_z ** 2)
    return Depths(rays * z[:, None], std, inside)


def sweep_depths(camera: PinholeCamera, plane: Plane, X: np.ndarray, key_image: np.ndarray,
                 image: np.ndarray, cur_from_key: np.ndarray, *,
                 heights: tuple[float, float, float] = SWEEP_HEIGHTS, drop: float = SWEEP_DROP,
                 match: float = SWEEP_MATCH) -> tuple[np.ndarray, np.ndarray]:
    """Points ``X`` (N, 3) of a keyframe (its camera, normal ``plane.normal``; on its relief)
    moved along their rays by the height (``heights``: lowest, highest, step, m along the
    normal, up positive) where the keyframe's ``key_image`` and the current ``image`` agree
    (pose ``cur_from_key``), where the images say so clearly (module docstring). A pinhole
    camera without distortion. Returns ``(X moved (N, 3), moved (N,) bool)``."""
    X = np.asarray(X, dtype=np.float64)
    n = len(X)
    moved = np.zeros(n, bool)
    if n == 0:
        return X.copy(), moved
    R, t = cur_from_key[:3, :3], cur_from_key[:3, 3]
    u0 = camera.fx * X[:, 0] / X[:, 2] + camera.cx
    v0 = camera.fy * X[:, 1] / X[:, 2] + camera.cy
    offs = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
    I_key = np.stack([sample_bilinear(key_image, u0 + dx, v0 + dy)[0] for dx, dy in offs])
    # each patch pixel's ray turned into the current camera (a patch facing the camera: every
    # pixel at the point's depth z, so its position there is z Rr + t)
    Rr = np.stack([np.column_stack([(u0 + dx - camera.cx) / camera.fx,
                                    (v0 + dy - camera.cy) / camera.fy, np.ones(n)]) @ R.T
                   for dx, dy in offs])  # (9, N, 3)
    nX = X @ plane.normal  # the points' distances along the normal (> 0: in front)

    def sample(z: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Xc = (rays * z[None, :, None] + t).reshape(-1, 3)
        u, v, front = project_in_front(camera, Xc)
        vals, ok = sample_bilinear(image, u, v)
        m = rays.shape[1]
        return vals.reshape(9, m).astype(np.float64), (ok & front).reshape(9, m).all(axis=0)

    vals0, ok0 = sample(X[:, 2], Rr)
    if np.count_nonzero(ok0) < 20:
        return X.copy(), moved
    A = np.column_stack([I_key[:, ok0].ravel(), np.ones(9 * np.count_nonzero(ok0))])
    gain, bias = np.linalg.lstsq(A, vals0[:, ok0].ravel(), rcond=None)[0]
    ref = gain * I_key + bias
    sigma2 = max(float(mad_scale((vals0[4] - ref[4]).astype(np.float32), ok0)) ** 2, 1e-6)
    cost0 = np.where(ok0, ((vals0 - ref) ** 2).sum(axis=0), 0.0)
    idx = np.nonzero(ok0 & (cost0 > drop * sigma2))[0]  # only these can drop by that much
    if not len(idx):
        return X.copy(), moved
    lo, hi, step = heights
    rays, ref_i, z_i, nX_i = Rr[:, idx], ref[:, idx], X[idx, 2], nX[idx]

    def cost(dh: np.ndarray) -> np.ndarray:
        """The candidates' patch costs (m,) raised by ``dh`` (m,) (inf out of view or range)."""
        vals, ok = sample(z_i * (nX_i - dh) / nX_i, rays)
        ok &= (dh >= lo - 1e-9) & (dh <= hi + 1e-9)
        return np.where(ok, ((vals - ref_i) ** 2).sum(axis=0), np.inf)

    # coarse to fine: every 3rd height, then the 2 steps either side of the best one
    coarse = np.arange(lo, hi + 0.5 * step, 3 * step)
    best_c = np.argmin([cost(np.full(len(idx), h)) for h in coarse], axis=0)
    near = coarse[best_c][None, :] + step * np.arange(-2, 3)[:, None]  # (5, m)
    costs = np.array([cost(h) for h in near])
    k = np.argmin(costs, axis=0)
    dh_best = near[k, np.arange(len(idx))]
    c_best = costs[k, np.arange(len(idx))]
    ok = (cost0[idx] - c_best > drop * sigma2) & (c_best < 9 * match * sigma2) \
        & (dh_best > lo + 0.5 * step) & (dh_best < hi - 0.5 * step)
    moved[idx[ok]] = True
    dh = np.zeros(n)
    dh[idx[ok]] = dh_best[ok]
    return X * ((nX - dh) / nX)[:, None], moved
