"""How much of a keyframe's gradient energy is the texture's, and how much its noise's.

The estimate's covariance ``sigma^2 (O^T W O)^-1`` takes the keyframe's gradients as exact.
On low texture under heavy noise they are mostly noise: the points are picked where the
gradient is largest, and there the noise's is (seed 40's soak scenario 399, 384 px of a
texture of 8.5 grey levels' std at noise variance 29.6: 294 (grey levels per px)^2 at the
points where the noise-free frames give 2.4). The normal matrix then holds about a hundred
times the information the texture gives, and the first row's std was 26 times too small.

The current frame is a second, independent look at the same texture: at the fit, its
gradients warped into the keyframe's pixels share the texture's part with the keyframe's and
not the noise. ``f = sum w |g_key|^2 / sum w g_key . A^T g_cur`` (A the warp's 2x2 Jacobian
at each point) is then the normal matrix's information over the texture's, and the estimate's
noise std is ``f`` times the one computed (the estimating equations' slope is the texture's
information, their noise the whole normal matrix's: a sandwich of both). A change of view
moves f too, without noise: 0.92-1.05 on the sample drive navcam_drive; only an excess
beyond VIEW_SLACK counts (:func:`noise_factor`), and textured frames keep their std.
"""

from __future__ import annotations

import cv2
import numpy as np

from monovo_cli.core.estimator.estimate import KeyLevel
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import spline_gradient

MAX_POINTS = 4096  # the ratio is summed over at most this many of the points, evenly spread
MAX_FACTOR = 100.0  # a texture the two frames do not share at all: at most this factor
VIEW_SLACK = 1.2  # f's own spread with the change of view (navcam_drive: 0.92-1.05) is not noise
BORDER_PX = 3  # points warped closer to the frame's edge than this are left out
STEP_PX = 0.5  # the finite difference of the warp's Jacobian


def noise_factor(level: KeyLevel, plane: Plane, image: np.ndarray, cur_from_key: np.ndarray,
                 weights: np.ndarray | None) -> float:
    """The factor (>= 1) by which noise in the keyframe's gradients widens the noise std of a
    fit ``cur_from_key`` (4x4) of ``image`` (the current frame at ``level``'s resolution)
    against ``level`` (points near ``plane``, keyframe camera), its robust ``weights`` (N,;
    None: all 1): the module docstring's f over VIEW_SLACK where that is above 1, capped at
    MAX_FACTOR.

    A frame darker or brighter than the keyframe has its gradients scaled by the change: the
    shared part is divided by the ratio of the two frames' intensity spreads at the points
    (the same camera's noise on both sides: the fit's gain, a regression slope, shrinks with
    the keyframe's noise just as the gradients' share does, and would undo the factor)."""
    pts = level.points
    n = len(pts)
    if n == 0:
        return 1.0
    take = np.arange(0, n, max(1, -(-n // MAX_POINTS)))
    uv, X, g_key = pts.uv[take], pts.X[take], pts.grad[take].astype(np.float64)
    w = np.ones(len(take)) if weights is None or len(weights) != n else \
        np.asarray(weights, np.float64)[take]
    cam, R, t = pts.camera, cur_from_key[:3, :3], cur_from_key[:3, 3]
    on_plane = plane.intersect(cam.rays(uv))
    with np.errstate(invalid="ignore", divide="ignore"):
        p0 = cam.project(X @ R.T + t)
        cols = [(cam.project((X + plane.intersect(cam.rays(uv + d)) - on_plane) @ R.T + t) - p0)
                / STEP_PX for d in ((STEP_PX, 0.0), (0.0, STEP_PX))]
    gx, gy = spline_gradient(image)
    h, wd = image.shape
    inside = np.all(np.isfinite(p0), 1) & np.all(np.isfinite(cols[0]), 1) \
        & np.all(np.isfinite(cols[1]), 1)
    p = np.where(inside[:, None], p0, -1.0)
    inside &= (p[:, 0] > BORDER_PX) & (p[:, 1] > BORDER_PX) \
        & (p[:, 0] < wd - 1 - BORDER_PX) & (p[:, 1] < h - 1 - BORDER_PX) & (w > 0)
    if not inside.any():
        return 1.0
    p = p[inside].astype(np.float32)
    # (the points as one row: cv2.remap takes maps of fewer than 32767 columns, and MAX_POINTS
    # are; a column of one point per row costs it 27x the time, for the same values)
    u, v = np.ascontiguousarray(p[None, :, 0]), np.ascontiguousarray(p[None, :, 1])
    i_cur, gcx, gcy = (cv2.remap(g, u, v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)[0]
                       for g in (image, gx, gy))
    g_cur = np.stack([gcx, gcy], 1)
    i_key = pts.intensity[take][inside]
    gain = float(np.std(i_cur)) / max(float(np.std(i_key)), 1e-6)
    ax, ay = cols[0][inside], cols[1][inside]
    g_warp = np.stack([(ax * g_cur).sum(1), (ay * g_cur).sum(1)], 1)  # A^T g_cur
    gk, ww = g_key[inside], w[inside]
    shared = float(ww @ (gk * g_warp).sum(1)) / max(gain, 1e-6)
    total = float(ww @ (gk * gk).sum(1))
    if shared * MAX_FACTOR * VIEW_SLACK <= total:
        return MAX_FACTOR
    return max(1.0, total / shared / VIEW_SLACK)
