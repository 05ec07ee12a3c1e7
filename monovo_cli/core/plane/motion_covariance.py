"""The reported covariance of a frame's motion T_{k-1}_k: the estimates' noise and the
keyframe plane's error.

Each frame is estimated against its keyframe, whose points ``X_i = d ray_i / (n . ray_i)``
lie on the keyframe's plane ``(n, d)``. That plane is known only to within
``PlaneTracker.covariance`` P (3, 3) of its chart coordinates ``x = (d, theta_1, theta_2)``
(:mod:`monovo_cli.core.plane.belief`), and an error ``dx`` in it moves every point along its
ray, ``X_i -> (1 + s_i) X_i`` with

    s_i = dd / d - X_i . E dtheta / d       (E: the chart's tangent basis at n).

The estimate answers to first order with the twist ``p = S dx`` (``key_from_cur_est =
exp(p^) key_from_cur``, the convention of ``Estimate.covariance``): a point moved along its
keyframe ray moves in the current image by its parallax, ``-J_pi t s_i`` (t the current
frame's translation), i.e. its intensity difference by ``c_i s_i`` with ``c_i = a_i .
t_kc`` (``a_i`` the first three entries of its observation row o_i, ``t_kc`` key_from_cur's
translation; the inverse compositional approximation of the current gradient by the
keyframe's), and the estimator's normal equations (weights W, normal matrix N over the motion
and the brightness model) turn that into

    S = [N^-1 J^T W diag(c) [1/d, -X E / d]]_motion          (6, 3).

Its distance column is exactly ``(t_kc / d, 0)``: the images fix t / d, so a distance error
scales every translation against the keyframe by ``1 + dd / d`` (:func:`plane_sensitivity`
uses the exact column; the linear one approximates it).

For T_{k-1}_k, whose left twist is ``Ad(prev_from_key) (xi_k - xi_{k-1})``, the two frames'
estimation noises are independent but their plane errors are one and the same (one keyframe
plane): the plane adds ``A (S_k - S_{k-1}) P (S_k - S_{k-1})^T A^T`` with ``A =
Ad(prev_from_key)``. Its distance part is ``var(dd / d) t t^T`` on the translation (t that of
T_{k-1}_k): a fixed share of the step, however many frames the keyframe lives. Most of the
tilt part cancels in the same way, and what is left grows with the step too.

P itself is the keyframe plane's belief, whose widths are chosen for the MAP's weights (the
process noise, the mounting prior's default width), not measured. :class:`PlaneConsistency`
calibrates it for reporting from how the keyframe planes actually agree at each re-anchor:

- distance: the carried distance against the mounting prior's, ``nu_d = d_carried - d_prior``
  with predicted variance ``P_c + (process noise)^2 + sigma_prior^2``; the median of their
  ratios (normalised by 0.455, the median of chi-square with 1 dof) scales P's distance
  variance (covariance matching: where the carried plane and the prior agree better than
  their widths say, so does the MAP of the two);
- tilt: the carried tilt against the new keyframe's, ``nu_t``; what it holds beyond the two
  beliefs' own covariances (their noise) is the plane model's error (ground that is not a
  plane, the normal measured on the previous keyframe's patch). Its element-wise median
  (robust to the first keyframes' settling, normalised by 0.455) is added to P's tilt
  block after a factor ``1 / (2 (1 - rho))``: consecutive keyframe planes share most of that
  error, and ``nu_t`` only sees what changes between them. TILT_PERSISTENCE is rho, 2/3
  (a factor 1.5). The lag-1 correlation of the keyframe planes' tilt errors against the true
  ground is 0.8-0.9 on the rolling terrain drive (a factor 2.5-5), but the frames are tracked
  against the relief carried from keyframe to keyframe, which takes up much of that error:
  with 0.9 the reported std was twice the errors' spread after the first re-anchor on the
  rolling and sloped drives (std of error / std 0.35-0.5 on ty, tz and rx); with 2/3 (and
  the tilt noise below) 0.54-1.14 on every axis of the four terrain drives, 0.56-1.91 on
  another seed's rolling and sloped ones (benchmarks.terrain, docs/benchmarks.md).

Before the first re-anchor the tilt's model error is not measured yet: a plane the images did
not confirm as exact (:func:`~monovo_cli.core.plane.belief.exact_covariance`) gets the
filter's own tilt process noise per keyframe, TILT_CHANGE_DEG on each angle. Without it the
first frames of the rolling drive, on frame 0's plane corrected to the swell under it to
within 0.02 deg, had pitch errors twelve times their reported std.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, KeyLevel
from monovo_cli.core.plane.belief import (
    EXACT_STD,
    TILT_CHANGE_DEG,
    PlaneBelief,
    to_chart,
)
from monovo_cli.geometry.lie import adjoint, output_covariance
from monovo_cli.geometry.plane import Plane, tangent_basis

TILT_PERSISTENCE = 2.0 / 3.0  # rho: correlation of consecutive keyframe planes' tilt errors
CONSISTENCY_WINDOW = 100  # re-anchors remembered by PlaneConsistency
CHI2_1_MEDIAN = 0.455  # median of a chi-square variable with 1 degree of freedom
SENSITIVITY_POINTS = 32768  # the plane sensitivity's tilt columns sum over at most these


def point_sample(level: KeyLevel, max_points: int = SENSITIVITY_POINTS
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """Every ``stride``-th point of ``level`` (stride = ceil(N / max_points)), contiguous for
    :func:`plane_sensitivity`: ``(Jt (8, M) float32, X^T (3, M) float32, stride)``."""
    stride = max(1, -(-len(level.points) // max_points))
    return (np.ascontiguousarray(level.Jt[:, ::stride]),
            np.ascontiguousarray(level.points.X[::stride].T, dtype=np.float32), stride)


def plane_sensitivity(level: KeyLevel, plane: Plane, cur_from_key: np.ndarray,
                      weights: np.ndarray, normal: np.ndarray,
                      sample: tuple[np.ndarray, np.ndarray, int] | None = None) -> np.ndarray:
    """S (6, 3): the estimate's twist error (m, rad; ``key_from_cur_est = exp(p^)
    key_from_cur``) per unit error of the keyframe plane's chart coordinates (m, rad, rad).

    ``level`` the keyframe's finest level (points on ``plane``, keyframe camera),
    ``cur_from_key`` (4x4) the estimate, ``weights`` (N,) and ``normal`` (P, P) its final
    robust weights and normal matrix (``Estimate.weights``/``.normal``). The distance column
    is exact; the tilt columns' sum over the points runs over ``sample``
    (:func:`point_sample` of ``level``, made here if None; a caller with many frames per
    keyframe keeps it), times its stride: at 512² every 4th point, which moves them by ~3 %
    (5 % at most on the rolling terrain drive) and costs a quarter of the memory traffic.
    Module docstring.
    """
    R, t = cur_from_key[:3, :3], cur_from_key[:3, 3]
    t_kc = -R.T @ t
    d = plane.distance
    npar = normal.shape[0]
    Jt, points_t, stride = point_sample(level) if sample is None else sample
    wc = weights[::stride] * (t_kc.astype(np.float32) @ Jt[:3])   # w_i c_i (M,)
    # J^T W diag(c) X E, the (3, P) (X^T W diag(c)) J first: one matrix product over the
    # points with contiguous rows (an (N, 3) @ (3, 2) product is slow in numpy)
    XJ = stride * np.dot(points_t * wc, Jt[:npar].T)  # (3, P)
    rhs = tangent_basis(plane.normal).T @ XJ.astype(np.float64)  # (2, P)
    try:
        S_tilt = -np.linalg.solve(normal, rhs.T)[:6] / d
    except np.linalg.LinAlgError:
        S_tilt = np.zeros((6, 2))
    S = np.zeros((6, 3))
    S[:3, 0] = t_kc / d
    S[:, 1:] = S_tilt
    return S


class MotionCovariance:
    """The covariance of each accepted frame's T_{k-1}_k (module docstring): keeps the
    previous frame's keyframe-relative covariance and plane sensitivity."""

    def __init__(self) -> None:
        self.anchored()

    def anchored(self) -> None:
        """A new keyframe on the previous frame: its pose relative to itself is exact."""
        self._cov_prev = np.zeros((6, 6))
        self._sens_prev = np.zeros((6, 3))
        self._sample: tuple[KeyLevel, tuple] | None = None  # (level, its point_sample)

    def relative(self, est: Estimate, level: KeyLevel, plane: Plane,
                 plane_covariance: np.ndarray | None, cur_from_key_prev: np.ndarray,
                 prev_from_cur: np.ndarray) -> np.ndarray:
        """(6, 6) covariance of (t, rotvec) of ``prev_from_cur`` (m, rad), the frame estimated
        as ``est`` against the keyframe of finest level ``level`` and ``plane`` (covariance
        ``plane_covariance`` (3, 3) in its chart; None: exact); the previous frame was at
        ``cur_from_key_prev`` (4x4). Becomes the previous frame for the next call."""
        sens = np.zeros((6, 3))
        if plane_covariance is not None and est.normal is not None and est.weights is not None:
            if self._sample is None or self._sample[0] is not level:
                self._sample = level, point_sample(level)
            sens = plane_sensitivity(level, plane, est.cur_from_key, est.weights, est.normal,
                                     self._sample[1])
        A = adjoint(cur_from_key_prev)  # Ad(prev_from_key)
        D = sens - self._sens_prev
        inner = est.covariance + self._cov_prev
        if plane_covariance is not None:
            inner = inner + D @ plane_covariance @ D.T
        cov = output_covariance(A @ inner @ A.T, prev_from_cur)
        self._cov_prev, self._sens_prev = est.covariance, sens
        return 0.5 * (cov + cov.T)


class PlaneConsistency:
    """Calibrates the keyframe plane's covariance for reporting from the re-anchors seen so far
    (the last CONSISTENCY_WINDOW; module docstring)."""

    def __init__(self) -> None:
        self._distance_nis: deque[float] = deque(maxlen=CONSISTENCY_WINDOW)
        self._tilt_excess: deque[np.ndarray] = deque(maxlen=CONSISTENCY_WINDOW)
        self._calibration: tuple[float, np.ndarray] | None = None  # (distance factor, Q)

    def reanchored(self, carried: PlaneBelief, new: PlaneBelief, prior: PlaneBelief,
                   distance_change: float) -> None:
        """One re-anchor: the old keyframe's plane ``carried`` to the new keyframe
        (:func:`~monovo_cli.core.plane.belief.carried_plane`, before process noise), whose
        plane is ``new`` (the MAP); ``prior`` the mounting prior, ``distance_change`` (m) the
        distance's process noise."""
        try:
            Pc, Pn, Pp = carried.covariance, new.covariance, prior.covariance
        except np.linalg.LinAlgError:
            return
        predicted = Pc[0, 0] + distance_change ** 2 + Pp[0, 0]
        self._calibration = None
        if np.isfinite(predicted) and predicted > 0:
            nu_d = carried.plane.distance - prior.plane.distance
            self._distance_nis.append(nu_d ** 2 / predicted)
        nu_t = to_chart(new.plane, carried.plane)[1:]
        excess = np.outer(nu_t, nu_t) - Pc[1:, 1:] - Pn[1:, 1:]
        if np.all(np.isfinite(excess)):
            self._tilt_excess.append(excess)

    def reported(self, covariance: np.ndarray) -> np.ndarray:
        """The plane covariance (3, 3) of the keyframe plane's chart, calibrated."""
        if self._calibration is None:  # (worked out once per re-anchor)
            g, Q = 1.0, np.eye(2) * math.radians(TILT_CHANGE_DEG) ** 2
            if self._distance_nis:
                g = math.sqrt(float(np.median(self._distance_nis)) / CHI2_1_MEDIAN)
            if self._tilt_excess:
                Q = np.median(np.array(self._tilt_excess), axis=0) / CHI2_1_MEDIAN
                Q = Q / (2.0 * (1.0 - TILT_PERSISTENCE))
                lam, V = np.linalg.eigh(0.5 * (Q + Q.T))
                Q = (V * np.clip(lam, 0.0, None)) @ V.T
            self._calibration = g, Q
        g, Q = self._calibration
        P = np.array(covariance, dtype=float)
        if np.max(np.diag(P)[1:]) <= (10 * EXACT_STD) ** 2:  # a plane taken as exact stays so
            return P
        P[0, :] *= g
        P[:, 0] *= g
        P[1:, 1:] += Q
        return P
