"""The terrain products' depth sweep: observation points moved along their rays to where two
images agree.

A keyframe's finest observation points lie on its terrain grid (:mod:`monovo_cli.core.estimator.terrain_grid`,
a height field on a coarse grid). What the terrain grid misses are small objects, a rock the grid
does not see, too far from the terrain grid for a Gauss-Newton step under a prior toward it; so
:func:`sweep_depths` searches each point's height along its ray instead (a plane sweep)
against a second image at a known pose, and moves the point only where the images say so
clearly (docs/algorithm.md section 9, "What the terrain grid misses: rocks"). It feeds the terrain
products (:mod:`monovo_cli.mapping.terrain_map`), not the tracking.
"""

from __future__ import annotations

import numpy as np

from monovo_cli.core.estimator.jacobian import project_in_front
from monovo_cli.core.estimator.robust import mad_scale
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.sampling import sample_bilinear

SWEEP_HEIGHTS = (-0.10, 0.30, 0.01)  # m: sweep_depths' heights off the point, (lowest, highest, step)
SWEEP_DROP = 25.0  # noise variances the patch's squared difference must drop by to move a point
SWEEP_MATCH = 2.0  # and at most this many noise variances per patch pixel at the best height


def sweep_depths(camera: PinholeCamera, plane: Plane, X: np.ndarray, key_image: np.ndarray,
                 image: np.ndarray, cur_from_key: np.ndarray, *,
                 heights: tuple[float, float, float] = SWEEP_HEIGHTS, drop: float = SWEEP_DROP,
                 match: float = SWEEP_MATCH) -> tuple[np.ndarray, np.ndarray]:
    """Points ``X`` (N, 3) of a keyframe (m, its camera; on its terrain grid, ``plane`` its plane)
    moved along their rays to the height where the keyframe's ``key_image`` and the current
    ``image`` (H, W) float32 at pose ``cur_from_key`` (4x4) agree, where they say so clearly.

    Each point is matched by its 3 x 3 patch in ``key_image``, every pixel of it at the
    point's depth (a patch facing the camera), against ``image``, the brightness fitted as
    a straight line over all points and the noise variance taken from the residuals' median
    absolute deviation. Heights ``heights = (lowest, highest, step)`` m off the point along
    the plane's normal (up positive) are searched every third step, then in single steps
    around the best. A point moves only if its patch's squared difference drops by more
    than ``drop`` noise variances, the best is within ``match`` noise variances per patch
    pixel and it is inside the range; only points whose patch already disagrees by ``drop``
    can pass, so only those are searched. A pinhole camera without distortion.

    Returns ``(X moved (N, 3), moved (N,) bool)``.
    """
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
