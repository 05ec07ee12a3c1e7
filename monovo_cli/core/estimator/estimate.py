"""One frame's motion: maximum likelihood on intensity differences (the paper's sections
10.2.3-10.2.4; docs/algorithm.md sections 1-3).

For observation points ``X_i`` (keyframe camera, on the ground plane) with keyframe
intensities ``I_i`` and gradients ``g_i``, the current frame's pose ``cur_from_key = T``
minimises  sum_i rho(I_cur(pi(T X_i)) - I_i)  (eqs. 10.1-10.3, 10.19 with U = sigma^2 I).

The observation rows o_i (the paper's o, eq. 10.12; derived in :mod:`monovo_cli.core.estimator.jacobian`,
which corrects eqs. 10.6 and 10.9) are evaluated once per keyframe at the keyframe's points
(inverse compositional Gauss-Newton: the paper's constant g, with a constant observation
matrix O), and each iteration solves the weighted normal equations (eq. 10.21 with robust
weights W, :mod:`monovo_cli.core.estimator.robust`)

    xi = (O^T W O)^-1 O^T W FD,     FD_i = I_cur(pi(T X_i)) - I_i   (exact warp, eq. 10.7)

and composes on SE(3): T <- T exp(-xi^). Iterations stop when the mean squared
difference (eq. 10.3) falls by less than delta_2 (relative), the update moves the points
by less than ``step_tolerance_px`` (finest level; ``COARSE_STEP_TOLERANCE_PX`` above it), or
it rises (the step is then halved, then refused). At the finest level a step that moves the
points less than REWEIGHT_PX is stretched by ``relaxation``: the constant O is steeper than
the frame as the bicubic kernel samples it, so each step falls short of the fixed point (by
8-27 % depending on the direction) and the steps shrink only five- to tenfold; stretched,
they shrink faster, and the fixed point O^T W FD = 0 is the same (benchmarks.convergence).
This runs coarse to fine over an image pyramid. O^T W O is formed anew only after a step
that moved the points by more than REWEIGHT_PX (the fixed point O^T W FD = 0 does not depend
on it), O^T W FD every iteration.

The warp is exact: the points lie on the keyframe's plane n.X = d, so a keyframe pixel x
moves to K (R + t n^T / d) K^-1 x, the plane's homography, applied to all points in one
OpenCV call (a camera with lens distortion moves and projects the 3-D points instead).
The current frame is then sampled there by OpenCV's remap: bicubically at the finest level
(Keys' kernel: the observation points are where the image changes fastest, where bilinear
interpolation is worst; docs/algorithm.md section 3, "Interpolation"), bilinearly at the
coarser ones.

Beyond the paper: at the finest level the rows o_i take g from the derivative of the
interpolating cubic B-spline at the keyframe pixels (``image.gradients.spline_gradient``, a
better gradient than Sobel's; the frame itself is sampled with OpenCV's bicubic kernel, not
with that spline); an affine brightness model ``I_cur ~ gain I_key + bias`` is estimated
jointly (two more columns ``(I_i, 1)`` in O, section "photometric" of docs/algorithm.md),
the weights W come from a Huber (or Tukey) M-estimator with the scale from the residuals'
median absolute deviation, and the covariance of the estimate is sigma^2 (O^T W O)^-1 with
sigma^2 from the weighted residuals.

Long module: the keyframe level's precomputed rows and warps (:class:`KeyLevel`: the
plane's homography, points with depths of their own, lens distortion) and the solver that
iterates over them share one point layout and are read together.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import cv2
import numpy as np

from monovo_cli.core.estimator.ground import LevelPoints
from monovo_cli.core.estimator.jacobian import distortion_jacobian, observation_matrix, project_in_front
from monovo_cli.core.estimator.robust import inlier_fraction, mad_scale, rho_sum, robust_weights
from monovo_cli.core.options import EstimatorOptions
from monovo_cli.geometry.lie import se3_exp
from monovo_cli.image.pyramid import extend_pyramid
from monovo_cli.image.sampling import INTERPOLATION, pixel_grid, sample_at

PLANAR_TOLERANCE = 1e-7  # |m . X - 1| of points lifted onto one plane (rounding only)
COARSE_STEP_TOLERANCE_PX = 3e-2  # a coarser level's steps, which only steer, stop below this
REWEIGHT_PX = 0.5  # a step that moved the points further than this gets a fresh O^T W O


@dataclass(frozen=True)
class KeyLevel:
    """A keyframe's points at one level with their constant observation matrix.

    ``J`` (N, 8) float32 holds the geometric rows o_i (grey levels per m / per rad) and the
    photometric columns (I_i, 1); ``probes`` (4, 3) are the extreme points, used to measure
    how far an update moves the image. ``grid`` holds the points' keyframe pixels as a remap
    grid (see ``pixel_grid``); ``plane_m`` (3,) is ``n / d`` of the plane they lie on
    (``plane_m . X = 1``; a zero vector when they do not lie on one: points lifted onto a
    terrain grid, :func:`~monovo_cli.core.estimator.terrain_grid.lifted_levels`) and ``box_rays`` (4, 3)
    the rays K^-1 (u, v, 1) of the corners of the points' bounding box in the keyframe image.
    """

    points: LevelPoints
    Jt: np.ndarray
    probes: np.ndarray
    grid: np.ndarray
    plane_m: np.ndarray
    box_rays: np.ndarray

    @classmethod
    def from_points(cls, points: LevelPoints, Jt: np.ndarray | None = None) -> KeyLevel:
        """The level of ``points`` (keyframe camera, one pyramid level) with its rows evaluated
        once (docs/algorithm.md section 3: inverse compositional, a constant O); ``Jt`` (8,
        N) the rows where they are known already (:meth:`subset`)."""
        cam = points.camera
        if Jt is None:
            D = distortion_jacobian(cam, points.X) if cam.has_distortion and len(points) else None
            O = observation_matrix(points.X, points.grad, cam.fx, cam.fy, D)
            Jt = np.empty((8, len(points)), np.float32)
            Jt[:6] = O.T
            Jt[6] = points.intensity
            Jt[7] = 1.0
        uv = points.uv
        if len(points):
            u, v = uv[:, 0], uv[:, 1]
            probes = points.X[[int(np.argmin(u)), int(np.argmax(u)), int(np.argmin(v)),
                               int(np.argmax(v))]]
            u0, u1, v0, v1 = u.min(), u.max(), v.min(), v.max()
            box_rays = cam.rays(np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]]))
            # The plane through the points (they were lifted onto one): X . m = 1.
            step = max(1, len(points) // 2000)
            m = np.linalg.lstsq(points.X[::step], np.ones(len(points.X[::step])), rcond=None)[0]
            if np.max(np.abs(points.X @ m - 1.0)) > PLANAR_TOLERANCE:
                m = np.zeros(3)  # not on one plane: no homography
        else:
            probes = box_rays = np.zeros((0, 3))
            m = np.zeros(3)
        return cls(points, Jt, probes, pixel_grid(uv[:, 0], uv[:, 1]), m, box_rays)

    def subset(self, index: np.ndarray) -> KeyLevel:
        """The level of the points ``index`` (an index array) alone: their rows sliced, not
        evaluated again (each point's row is its own), the rest as :meth:`from_points`."""
        pts = self.points
        sub = replace(pts, uv=pts.uv[index], X=pts.X[index], intensity=pts.intensity[index],
                      grad=pts.grad[index])
        return KeyLevel.from_points(sub, np.ascontiguousarray(self.Jt[:, index]))

    @property
    def J(self) -> np.ndarray:
        """The rows (N, 8) (a view of ``Jt``, stored transposed for the weighted products)."""
        return self.Jt.T

    @cached_property
    def rows(self) -> np.ndarray:
        """The rows (N, 8) as a contiguous copy: BLAS forms ``O^T W O`` from it in about 60 %
        of the time it takes over the strided view ``J`` (once per level)."""
        return np.ascontiguousarray(self.Jt.T)

    @property
    def O(self) -> np.ndarray:
        """The paper's observation matrix (N, 6)."""
        return self.J[:, :6]

    def warp_grid(self, T: np.ndarray) -> np.ndarray:
        """Remap grid of the points' pixels in the current camera, ``T`` = cur_from_key 4x4.

        A pinhole camera with every point in front maps keyframe pixels to current ones by
        the plane's homography K (R + t m^T) K^-1 (applied by OpenCV in one pass); otherwise
        (lens distortion, or points behind the camera) the points are moved and projected.
        A point's current depth has the sign of (R_3 + t_z m) . ray, affine in its keyframe
        pixel, so it is positive at every point when it is at the bounding box's corners.
        """
        cam = self.points.camera
        R, t = T[:3, :3], T[:3, 3]
        if not cam.has_distortion and len(self.box_rays) and self.plane_m.any() and \
                float(np.min(self.box_rays @ (R[2] + t[2] * self.plane_m))) > 1e-9:
            K, K_inv = self._intrinsics
            H = K @ (R + np.outer(t, self.plane_m)) @ K_inv
            return cv2.perspectiveTransform(self.grid, H)
        if not cam.has_distortion and len(self.points) and self._in_front(R[2], t[2]):
            # points with depths of their own (not on one plane), all in front: moved and
            # projected by OpenCV in one pass (a 4x4 map to (u w, v w, w, w)); the (u, v)
            # channels copied out by OpenCV (remap reads a strided map at half the speed, and
            # numpy copies one slowly)
            M = np.zeros((4, 4))
            M[:2] = cam.K[:2] @ T[:3]
            M[2] = M[3] = T[2]
            moved = cv2.perspectiveTransform(self.grid3, M)
            grid = np.empty(moved.shape[:2] + (2,), np.float32)
            cv2.mixChannels([moved], [grid], [0, 0, 1, 1])
            return grid
        Xc = self.points.X @ R.T
        Xc += t
        u, v, _ = project_in_front(cam, Xc)
        return pixel_grid(u, v)

    def _in_front(self, r: np.ndarray, tz: float) -> bool:
        """Every point's current depth ``X . r + tz`` is positive: at once where the points'
        bounding box is in front (the depth's least over the box is a bound of the points'),
        over the points themselves only where it is not."""
        lo, hi = self._box
        if float(np.sum(np.minimum(r * lo, r * hi))) + tz > 1e-9:
            return True
        return float(np.min(self.points.X @ r)) + tz > 1e-9

    @cached_property
    def _box(self) -> tuple[np.ndarray, np.ndarray]:
        """The points' bounding box in the keyframe camera: ``(min, max)`` (3,) each."""
        X = self.points.X  # (column by column: a reduction over axis 0 of (N, 3) is 20x slower)
        return (np.array([X[:, i].min() for i in range(3)]),
                np.array([X[:, i].max() for i in range(3)]))

    @cached_property
    def _intrinsics(self) -> tuple[np.ndarray, np.ndarray]:
        """``(K, K^-1)`` of the level's camera (the homography's, once per level)."""
        K = self.points.camera.K
        return K, np.linalg.inv(K)

    @cached_property
    def intensity_variance(self) -> float:
        """The variance of the points' intensities (grey levels^2): the mean squared difference
        an unrelated image would leave with the brightness fit free (once per level)."""
        return float(np.var(self.points.intensity))

    @cached_property
    def grid3(self) -> np.ndarray:
        """The points ``X`` packed as a (rows, GRID_COLUMNS, 3) float32 array (the layout of
        ``grid``; the padding is zero)."""
        rows, cols = self.grid.shape[:2]
        out = np.zeros((rows * cols, 3), np.float32)
        out[:len(self.points)] = self.points.X
        return out.reshape(rows, cols, 3)


@dataclass(frozen=True)
class Estimate:
    """Result for one frame.

    ``cur_from_key`` 4x4; ``covariance`` (6, 6) of the twist ``xi`` (m, rad) with
    ``key_from_cur_true = exp(xi^) key_from_cur``; ``msd`` the final mean squared intensity
    difference at the finest level's valid points (grey levels^2, after the brightness
    model); ``gain``/``bias`` the brightness model; ``condition`` the condition number of the
    scale-normalised normal matrix. ``weights`` (N,) float32 are the finest level's final
    robust weights (0 at invalid points) and ``normal`` the (P, P) normal matrix ``J^T W J``
    behind ``covariance`` (P = 8 with the brightness model, else 6), for propagating other
    errors through the estimate (:mod:`monovo_cli.core.plane.motion_covariance`); ``scale`` (grey
    levels) the robust scale (MAD) of the final differences those weights were made with
    (None where there were too few points).
    """

    cur_from_key: np.ndarray
    covariance: np.ndarray
    msd: float
    iterations: int
    points: int
    valid_fraction: float
    converged: bool
    condition: float
    gain: float = 1.0
    bias: float = 0.0
    residuals: np.ndarray | None = None
    valid: np.ndarray | None = None
    finest_iterations: int = 0
    weights: np.ndarray | None = None
    normal: np.ndarray | None = None
    scale: float | None = None


def residuals(level: KeyLevel, image: np.ndarray, T: np.ndarray, gain: float = 1.0,
              bias: float = 0.0, flag: int = cv2.INTER_LINEAR) -> tuple[np.ndarray, np.ndarray]:
    """FD (eq. 10.2) at one level: ``I_cur(pi(T X_i)) - (gain I_i + bias)`` (N,) float32, validity (N,).

    ``image`` (H, W) float32 is the current frame at the level, sampled with OpenCV
    interpolation ``flag``; invalid points (out of view or behind the camera) get 0.
    """
    pts = level.points
    vals, valid = sample_at(image, level.warp_grid(T), len(pts), flag)
    if gain != 1.0 or bias != 0.0:
        vals -= np.float32(gain) * pts.intensity + np.float32(bias)
    else:
        vals -= pts.intensity
    vals *= valid
    return vals, valid


def _probe_move(level: KeyLevel, T0: np.ndarray, T1: np.ndarray) -> float:
    """Largest image displacement (px) of the level's probe points between poses T0 and T1."""
    P = level.probes
    if not len(P):
        return 0.0
    A = P @ T0[:3, :3].T + T0[:3, 3]
    B = P @ T1[:3, :3].T + T1[:3, 3]
    if A[:, 2].min() <= 1e-9 or B[:, 2].min() <= 1e-9:
        return float("inf")
    cam = level.points.camera
    d = B[:, :2] / B[:, 2:] - A[:, :2] / A[:, 2:]
    return float(max(cam.fx * np.abs(d[:, 0]).max(), cam.fy * np.abs(d[:, 1]).max()))


@dataclass
class _LevelResult:
    T: np.ndarray
    gain: float
    bias: float
    iterations: int
    r: np.ndarray
    valid: np.ndarray
    H: np.ndarray | None = None  # the weighted normal matrix the level's steps used


def _solve_level(level: KeyLevel, image: np.ndarray, T: np.ndarray, gain: float, bias: float,
                 opts: EstimatorOptions, step_tol: float, max_iterations: int,
                 flag: int = cv2.INTER_LINEAR, relax: float = 1.0) -> _LevelResult:
    """Gauss-Newton / IRLS iterations at one pyramid level (``flag``: OpenCV interpolation).

    Residuals are 0 at invalid points and weights are masked there, so every sum runs over
    all points (no compressing copies); rho(0) = 0, so the mean cost needs no mask.
    """
    npar = 8 if opts.photometric else 6
    Jt = level.Jt[:npar]
    r, valid = residuals(level, image, T, gain, bias, flag)
    nv = np.count_nonzero(valid)
    iterations = 0
    min_valid = max(opts.min_valid_points, npar)
    scale = None  # the robust scale, from this level's first residuals (MAD)

    def rho(res: np.ndarray) -> float:  # total robust cost at the level's scale
        return rho_sum(res, scale, opts.robust, huber_k=opts.huber_k, tukey_c=opts.tukey_c)

    H, move, cost = None, 0.0, None
    for _ in range(max_iterations):
        if nv < min_valid:
            break
        if scale is None:
            scale = mad_scale(r, valid)
        w = robust_weights(r, opts.robust, huber_k=opts.huber_k, tukey_c=opts.tukey_c,
                           scale=scale)[0]
        w *= valid
        if H is None or move > REWEIGHT_PX:
            # O^T W O with these weights; kept while the steps are small (the weights then
            # barely change, and the fixed point O^T W FD = 0 does not depend on it)
            Jw = Jt * w
            H = (Jw @ level.rows[:, :npar]).astype(np.float64)
            b = (Jw @ r).astype(np.float64)
        else:
            b = (Jt @ (w * r)).astype(np.float64)
        try:
            p = np.linalg.solve(H, b)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(p)):
            break
        iterations += 1
        T_new = T @ se3_exp(-p[:6])
        move = _probe_move(level, T, T_new)
        if relax != 1.0 and move < REWEIGHT_PX:
            p *= relax
            T_new = T @ se3_exp(-p[:6])
            move = _probe_move(level, T, T_new)
        if move < step_tol:
            # Converged: a step this small cannot raise the cost, so it is taken without
            # sampling again (r and valid stay those of the previous pose, for statistics).
            T = T_new
            if npar == 8:
                gain, bias = gain + p[6], bias + p[7]
            break
        if cost is None:  # (an accepted step's cost is the next iteration's)
            cost = rho(r) / nv
        for _halving in range(4):
            if _halving:
                T_new = T @ se3_exp(-p[:6])
            g_new = gain + (p[6] if npar == 8 else 0.0)
            b_new = bias + (p[7] if npar == 8 else 0.0)
            r_new, valid_new = residuals(level, image, T_new, g_new, b_new, flag)
            nv_new = np.count_nonzero(valid_new)
            if nv_new >= min_valid:
                cost_new = rho(r_new) / nv_new
                if cost_new <= cost * (1.0 + 1e-7):
                    break
            p = 0.5 * p
        else:
            break
        cost = cost_new
        if _halving:
            move = _probe_move(level, T, T_new)
        msd_old = _msd(r, nv)
        T, gain, bias, r, valid, nv = T_new, g_new, b_new, r_new, valid_new, nv_new
        rel = (msd_old - _msd(r, nv)) / max(msd_old, 1e-12)
        if move < step_tol or (0.0 <= rel < opts.min_msd_decrease and move < 10 * step_tol):
            break
    return _LevelResult(T, gain, bias, iterations, r, valid, H)


def _msd(r: np.ndarray, n_valid: int) -> float:
    """Mean squared difference over the valid points of ``r`` (0 at the invalid ones)."""
    return float(np.dot(r, r)) / n_valid if n_valid else float("inf")


def coarse_search(level: KeyLevel, image: np.ndarray, cur_from_key: np.ndarray, *,
                  options: EstimatorOptions, noise_sigma: float, gain: float = 1.0,
                  bias: float = 0.0,
                  angles_deg: Sequence[float] = (-6.0, -3.0, 0.0, 3.0, 6.0),
                  roll_deg: Sequence[float] = (-5.0, 0.0, 5.0)) -> np.ndarray:
    """A start that survives large motions: try a grid of rotations at the top pyramid level.

    Each hypothesis ``exp(w) cur_from_key`` (rotations about the current camera's x and y by
    ``angles_deg``, about z by ``roll_deg``) is refined with up to eight Gauss-Newton
    iterations at this level; the one with the most inliers wins. Returns the winning
    ``cur_from_key``.

    ``noise_sigma`` is the full-resolution noise; each pyramid level's 5-tap binomial
    smoothing divides white noise by ~3.7 (0.273 per level), so the inlier threshold is scaled
    to the level, but kept above 5 % of the level's contrast (interpolation and texture
    mismatch). A full-resolution threshold would call every hypothesis good at high noise.
    """
    best, best_score = np.array(cur_from_key, dtype=np.float64), -1.0
    image = np.ascontiguousarray(image, dtype=np.float32)
    contrast = float(np.std(level.points.intensity)) if len(level.points) else 1.0
    noise_sigma = max(noise_sigma * 0.273 ** level.points.level, 0.05 * contrast)
    for rz in roll_deg:
        for rx in angles_deg:
            for ry in angles_deg:
                w = np.radians([rx, ry, rz])
                T0 = se3_exp(np.r_[0.0, 0.0, 0.0, w]) @ cur_from_key
                res = _solve_level(level, image, T0, gain, bias, options, 1e-2, 8)
                score = inlier_fraction(res.r, res.valid, noise_sigma)
                if score > best_score:
                    best, best_score = res.T, score
    return best


def estimate_motion(levels: Sequence[KeyLevel], pyramid: Sequence[np.ndarray],
                    cur_from_key: np.ndarray, *, options: EstimatorOptions | None = None,
                    gain: float = 1.0, bias: float = 0.0,
                    first_level: int | None = None) -> Estimate:
    """Coarse-to-fine maximum-likelihood pose of the current frame relative to the keyframe.

    ``levels[l]`` are the keyframe's points at pyramid level l (finest first) and
    ``pyramid[l]`` the current frame's level-l image (float32; levels it lacks are made from
    its coarsest, :func:`~monovo_cli.image.pyramid.extend_pyramid`). ``cur_from_key`` (4x4) is the
    initial guess, ``gain``/``bias`` that of the brightness model. Levels above
    ``first_level`` are skipped. Returns the :class:`Estimate` at the finest level, its
    covariance ``sigma^2 (O^T W O)^-1`` (docs/algorithm.md section 3); ValueError for an
    unknown ``options.interpolation``.
    """
    opts = options or EstimatorOptions()
    pyramid = extend_pyramid(pyramid, len(levels))
    T = np.array(cur_from_key, dtype=np.float64)
    total = 0
    top = len(levels) - 1 if first_level is None else min(first_level, len(levels) - 1)
    if opts.interpolation not in INTERPOLATION:
        raise ValueError(f"unknown interpolation {opts.interpolation!r}")
    fine_flag = INTERPOLATION[opts.interpolation]
    res = None
    for lv in range(top, -1, -1):
        tol = opts.step_tolerance_px if lv == 0 else COARSE_STEP_TOLERANCE_PX
        res = _solve_level(levels[lv], np.ascontiguousarray(pyramid[lv], dtype=np.float32), T,
                           gain, bias, opts, tol, opts.max_iterations,
                           fine_flag if lv == 0 else cv2.INTER_LINEAR,
                           opts.relaxation if lv == 0 else 1.0)
        T, gain, bias = res.T, res.gain, res.bias
        total += res.iterations
    # Final statistics at the finest level: the normal matrix its steps used (weights of its
    # first residuals) and the noise from the final residuals and their weights.
    npar = 8 if opts.photometric else 6
    Jt = levels[0].Jt[:npar]
    valid, r = res.valid, res.r
    nv = int(np.count_nonzero(valid))
    msd = _msd(r, nv)
    cov = np.full((6, 6), np.inf)
    cond = float("inf")
    w = H = scale = None
    if nv >= max(opts.min_valid_points, npar):
        scale = mad_scale(r, valid)
        w = robust_weights(r, opts.robust, huber_k=opts.huber_k, tukey_c=opts.tukey_c,
                           scale=scale)[0]
        w *= valid
        H = res.H
        if H is None:
            Jw = Jt * w
            H = (Jw @ levels[0].rows[:, :npar]).astype(np.float64)
        dof = max(float(w.sum(dtype=np.float64)) - npar, 1.0)
        sigma2 = float(np.dot(w, r * r)) / dof
        d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
        Hn = H / np.outer(d, d)
        try:
            eig = np.linalg.eigvalsh(Hn)
            cond = float(eig[-1] / eig[0]) if eig[0] > 0 else float("inf")
            H = 0.5 * (H + H.T)
            cov = sigma2 * np.linalg.inv(H)[:6, :6]
            cov = 0.5 * (cov + cov.T)
        except np.linalg.LinAlgError:
            pass
    converged = bool(nv >= opts.min_valid_points and np.all(np.isfinite(T)))
    return Estimate(T, cov, msd, total, nv, nv / max(len(valid), 1), converged, cond,
                    float(gain), float(bias), res.r, valid, res.iterations, w, H, scale)
