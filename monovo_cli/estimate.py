"""One frame's motion: maximum likelihood on intensity differences (sections 10.2.3-10.2.4).

For observation points ``X_i`` (keyframe camera, on the ground plane) with keyframe
intensities ``I_i`` and gradients ``g_i``, the current frame's pose ``cur_from_key = T``
minimises  sum_i rho(I_cur(pi(T X_i)) - I_i)  (eqs. 10.1-10.3, 10.19 with U = sigma^2 I).

Linearisation (our derivation; it replaces eqs. 10.5-10.12, which carry a lost sign in
the projection derivative, eq. 10.6, and a C_X where C_Y belongs, eq. 10.9). For the
projection u = fx X/Z + cx, v = fy Y/Z + cy:

    d(u, v)/dX = [[fx/Z, 0, -fx X/Z^2],
                  [0, fy/Z, -fy Y/Z^2]]                      (eq. 10.6, corrected sign)

and for a small rigid motion exp(xi^) with xi = (v, w):  d(exp(xi^) X)/d xi = [I | -[X]x].
The observation row (the paper's o, eq. 10.12) is o = g^T d(u,v)/dX [I | -[X]x], i.e. with
a = (gx fx/Z, gy fy/Z, -(gx fx X + gy fy Y)/Z^2):

    o = (a1, a2, a3,  a3 Y - a2 Z,  a1 Z - a3 X,  a2 X - a1 Y).

It is evaluated once per keyframe at the keyframe's points (inverse compositional
Gauss-Newton: the paper's constant g, with a constant observation matrix O), and each
iteration solves the weighted normal equations (eq. 10.21 with robust weights W)

    xi = (O^T W O)^-1 O^T W FD,     FD_i = I_cur(pi(T X_i)) - I_i   (exact warp, eq. 10.7)

and composes on SE(3): T <- T exp(-xi^). Iterations stop when the mean squared
difference (eq. 10.3) falls by less than delta_2 (relative), the update moves the points
by less than ``step_tolerance_px``, or it rises (the step is then halved, then refused).
This runs coarse to fine over an image pyramid.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from monovo_cli.geometry import se3_exp
from monovo_cli.ground import LevelPoints


@dataclass(frozen=True)
class EstimatorOptions:
    """Gauss-Newton settings. ``min_msd_decrease`` is the paper's delta_2 (relative)."""

    max_iterations: int = 40
    min_msd_decrease: float = 1e-6
    step_tolerance_px: float = 5e-4
    robust: str = "huber"            # "huber", "tukey" or "none"
    huber_k: float = 1.345
    tukey_c: float = 4.685
    min_valid_points: int = 20


def observation_matrix(X: np.ndarray, grad: np.ndarray, fx: float, fy: float) -> np.ndarray:
    """The rows o_i (N, 6) of the observation matrix O at points ``X`` (N, 3) with gradients (N, 2).

    Derivative of the intensity at the projection of ``exp(xi^) X`` with respect to the twist
    ``xi = (v, w)`` at 0, grey levels per metre / per radian.
    """
    X = np.asarray(X, dtype=np.float64)
    x, y, z = X[:, 0], X[:, 1], X[:, 2]
    gx = grad[:, 0].astype(np.float64) * fx
    gy = grad[:, 1].astype(np.float64) * fy
    iz = 1.0 / z
    a1 = gx * iz
    a2 = gy * iz
    a3 = -(a1 * x + a2 * y) * iz
    return np.stack([a1, a2, a3, a3 * y - a2 * z, a1 * z - a3 * x, a2 * x - a1 * y], axis=1)


def sample_bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact bilinear interpolation of ``image`` (H, W) float32 at pixels (u, v) (N,) float64.

    Returns the values (N,) float32 and a validity mask (N,) bool (inside [0, W-1] x [0, H-1]).
    The fractional offsets are kept to float32 precision (no 1/32 px quantisation).
    """
    h, w = image.shape
    valid = (u >= 0.0) & (v >= 0.0) & (u <= w - 1.0) & (v <= h - 1.0)
    u = np.where(valid, u, 0.0)
    v = np.where(valid, v, 0.0)
    x0 = np.minimum(u.astype(np.int64), w - 2)
    y0 = np.minimum(v.astype(np.int64), h - 2)
    ax = (u - x0).astype(np.float32)
    ay = (v - y0).astype(np.float32)
    idx = y0 * w + x0
    flat = image.ravel()
    p00 = flat[idx]
    p01 = flat[idx + 1]
    p10 = flat[idx + w]
    p11 = flat[idx + w + 1]
    top = p00 + ax * (p01 - p00)
    bot = p10 + ax * (p11 - p10)
    return top + ay * (bot - top), valid


def robust_weights(r: np.ndarray, kind: str, *, huber_k: float, tukey_c: float) -> tuple[np.ndarray, float]:
    """IRLS weights (N,) for residuals ``r`` and the robust scale (MAD, grey levels)."""
    if kind == "none" or len(r) == 0:
        return np.ones_like(r), float(np.sqrt(np.mean(r * r))) if len(r) else 0.0
    scale = 1.4826 * float(np.median(np.abs(r)))
    scale = max(scale, 1e-3)
    a = np.abs(r) / scale
    if kind == "huber":
        w = np.where(a <= huber_k, 1.0, huber_k / np.maximum(a, 1e-12))
    elif kind == "tukey":
        q = np.clip(1.0 - (a / tukey_c) ** 2, 0.0, None)
        w = q * q
    else:
        raise ValueError(f"unknown robust estimator {kind!r}")
    return w.astype(np.float64), scale


@dataclass(frozen=True)
class KeyLevel:
    """A keyframe's points at one level with their constant observation matrix ``O`` (N, 6)."""

    points: LevelPoints
    O: np.ndarray

    @classmethod
    def from_points(cls, points: LevelPoints) -> KeyLevel:
        cam = points.camera
        return cls(points, observation_matrix(points.X, points.grad, cam.fx, cam.fy))


@dataclass(frozen=True)
class Estimate:
    """Result for one frame.

    ``cur_from_key`` 4x4; ``covariance`` (6, 6) of the twist ``xi`` (m, rad) with
    ``key_from_cur_true = exp(xi^) key_from_cur``; ``msd`` the final mean squared intensity
    difference at the finest level's valid points (grey levels^2).
    """

    cur_from_key: np.ndarray
    covariance: np.ndarray
    msd: float
    iterations: int
    points: int
    valid_fraction: float
    converged: bool
    condition: float


def residuals(level: KeyLevel, image: np.ndarray, T: np.ndarray):
    pts = level.points
    cam = pts.camera
    Xc = pts.X @ T[:3, :3].T + T[:3, 3]
    z = Xc[:, 2]
    in_front = z > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = cam.project(np.where(in_front[:, None], Xc, np.nan))
    vals, valid = sample_bilinear(image, uv[:, 0], uv[:, 1])
    valid &= in_front
    r = vals.astype(np.float64) - pts.intensity
    return r, valid, uv


def _solve_level(level: KeyLevel, image: np.ndarray, T: np.ndarray, opts: EstimatorOptions,
                 step_tol: float, final: bool):
    """Gauss-Newton iterations at one level. Returns (T, iterations, msd, valid, H, r, w)."""
    O = level.O
    r, valid, uv = residuals(level, image, T)
    iterations = 0
    H = np.eye(6)
    w_full = np.zeros(len(r))
    prev_msd = np.inf
    for _ in range(opts.max_iterations):
        nv = int(valid.sum())
        if nv < max(opts.min_valid_points, 6):
            break
        rv = r[valid]
        msd = float(np.mean(rv * rv))
        w, scale = robust_weights(rv, opts.robust, huber_k=opts.huber_k, tukey_c=opts.tukey_c)
        Ov = O[valid]
        Ow = Ov * w[:, None]
        H = Ow.T @ Ov
        b = Ow.T @ rv
        try:
            xi = np.linalg.solve(H, b)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(xi)):
            break
        iterations += 1
        cost = _robust_cost(rv, w, scale, opts)
        accepted = False
        for _halving in range(4):
            T_new = T @ se3_exp(-xi)
            r_new, valid_new, uv_new = residuals(level, image, T_new)
            both = valid & valid_new
            if both.sum() < max(opts.min_valid_points, 6):
                xi = 0.5 * xi
                continue
            new_cost = _robust_cost_at(r_new[valid_new], scale, opts)
            if new_cost <= cost * (1.0 + 1e-9):
                accepted = True
                break
            xi = 0.5 * xi
        if not accepted:
            break
        move = float(np.mean(np.abs(uv_new[both] - uv[both]).sum(axis=1)))
        T, r, valid, uv = T_new, r_new, valid_new, uv_new
        new_msd = float(np.mean(r[valid] ** 2))
        rel = (prev_msd - new_msd) / max(prev_msd, 1e-12) if np.isfinite(prev_msd) else 1.0
        prev_msd = min(prev_msd, msd)
        if move < step_tol or (0.0 <= rel < opts.min_msd_decrease and move < 10 * step_tol):
            break
    if final:
        rv = r[valid]
        w, _ = robust_weights(rv, opts.robust, huber_k=opts.huber_k, tukey_c=opts.tukey_c)
        w_full = np.zeros(len(r))
        w_full[valid] = w
        Ov = level.O[valid]
        H = (Ov * w[:, None]).T @ Ov
    return T, iterations, r, valid, H, w_full


def _rho(a: np.ndarray, opts: EstimatorOptions) -> np.ndarray:
    if opts.robust == "huber":
        k = opts.huber_k
        return np.where(a <= k, 0.5 * a * a, k * a - 0.5 * k * k)
    if opts.robust == "tukey":
        c = opts.tukey_c
        q = np.clip(1.0 - (a / c) ** 2, 0.0, None)
        return (c * c / 6.0) * (1.0 - q ** 3)
    return 0.5 * a * a


def _robust_cost(rv: np.ndarray, w: np.ndarray, scale: float, opts: EstimatorOptions) -> float:
    return _robust_cost_at(rv, scale, opts)


def _robust_cost_at(rv: np.ndarray, scale: float, opts: EstimatorOptions) -> float:
    if len(rv) == 0:
        return np.inf
    return float(np.mean(_rho(np.abs(rv) / scale, opts)))


def inlier_fraction(r: np.ndarray, valid: np.ndarray, noise_sigma: float) -> float:
    """Share of all points that are in view with ``|r| < 3 sqrt(2) sigma`` (both images noisy)."""
    if len(r) == 0:
        return 0.0
    thr = 3.0 * np.sqrt(2.0) * max(noise_sigma, 1.0)
    return float(np.count_nonzero(valid & (np.abs(r) < thr)) / len(r))


def coarse_search(level: KeyLevel, image: np.ndarray, cur_from_key: np.ndarray, *,
                  options: EstimatorOptions, noise_sigma: float,
                  angles_deg: Sequence[float] = (-6.0, -3.0, 0.0, 3.0, 6.0),
                  roll_deg: Sequence[float] = (-5.0, 0.0, 5.0)) -> np.ndarray:
    """A start that survives large motions: try a grid of rotations at the top pyramid level.

    Each hypothesis ``exp(w) cur_from_key`` (rotations about the current camera's x and y by
    ``angles_deg``, about z by ``roll_deg``) is refined with a few Gauss-Newton iterations at
    this level; the one with the most inliers wins. Returns the winning ``cur_from_key``.
    """
    few = EstimatorOptions(**{**options.__dict__, "max_iterations": 8})
    best, best_score = np.array(cur_from_key, dtype=np.float64), -1.0
    for rz in roll_deg:
        for rx in angles_deg:
            for ry in angles_deg:
                w = np.radians([rx, ry, rz])
                T0 = se3_exp(np.r_[0.0, 0.0, 0.0, w]) @ cur_from_key
                T, _, r, valid, _, _ = _solve_level(level, image, T0, few, 1e-2, final=False)
                score = inlier_fraction(r, valid, noise_sigma)
                if score > best_score:
                    best, best_score = T, score
    return best


def estimate_motion(levels: Sequence[KeyLevel], pyramid: Sequence[np.ndarray],
                    cur_from_key: np.ndarray, *, options: EstimatorOptions | None = None,
                    first_level: int | None = None) -> Estimate:
    """Coarse-to-fine maximum-likelihood pose of the current frame relative to the keyframe.

    ``levels[l]`` are the keyframe's points at pyramid level l (finest first) and
    ``pyramid[l]`` the current frame's level-l image (float32). ``cur_from_key`` (4x4) is the
    initial guess. Levels above ``first_level`` are skipped.
    """
    opts = options or EstimatorOptions()
    T = np.array(cur_from_key, dtype=np.float64)
    total = 0
    top = len(levels) - 1 if first_level is None else min(first_level, len(levels) - 1)
    r = valid = w = None
    H = np.eye(6)
    for lv in range(top, -1, -1):
        tol = opts.step_tolerance_px * (1.0 if lv == 0 else 20.0)
        T, it, r, valid, H, w = _solve_level(levels[lv], pyramid[lv], T, opts, tol, final=lv == 0)
        total += it
    nv = int(valid.sum())
    n = len(valid)
    rv = r[valid]
    msd = float(np.mean(rv * rv)) if nv else float("inf")
    wv = w[valid]
    dof = max(float(wv.sum()) - 6.0, 1.0)
    sigma2 = float(np.sum(wv * rv * rv)) / dof
    try:
        cov = sigma2 * np.linalg.inv(H)
        eig = np.linalg.eigvalsh(H)
        cond = float(eig[-1] / max(eig[0], 1e-300))
    except np.linalg.LinAlgError:
        cov = np.full((6, 6), np.inf)
        cond = float("inf")
    converged = bool(nv >= opts.min_valid_points and np.all(np.isfinite(T)))
    return Estimate(T, cov, msd, total, nv, nv / max(n, 1), converged, cond)
