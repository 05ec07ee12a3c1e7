"""The reported covariance of a frame's motion T_{k-1}_k: the estimates' noise and the
keyframe plane's error (docs/algorithm.md section 3, "Covariance").

Each frame is estimated against its keyframe, whose points ``X_i = d ray_i / (n . ray_i)``
lie on the keyframe's plane, known only to within its covariance P (3, 3) in the chart
``x = (d, theta_1, theta_2)`` (m, rad, rad; :mod:`monovo_cli.core.plane.belief`). An error
``dx`` moves every point along its ray by the share ``s_i = dd / d - X_i . E dtheta / d``
(E the chart's tangent basis), its intensity difference by ``c_i s_i`` with ``c_i = a_i .
t_kc`` (``a_i`` the translation part of its observation row, ``t_kc`` key_from_cur's
translation), and the estimator's normal equations (weights W, normal matrix N with the
brightness model) turn that into the twist error

    S = [N^-1 J^T W diag(c) [1/d, -X E / d]]_motion          (6, 3),

whose distance column is exactly ``(t_kc / d, 0)`` (the images fix t / d). Both frames of
T_{k-1}_k share the keyframe plane, so with ``A = Ad(prev_from_key)`` the plane adds
``A (S_k - S_{k-1}) P (S_k - S_{k-1})^T A^T`` to their independent estimation noises.

P is the filter's belief, whose widths are set for the MAP's weights rather than measured;
:class:`PlaneCovarianceCalibration` calibrates it for reporting from how the keyframe planes agree at
the re-anchors (covariance matching on the distance; the tilt's model error, scaled by
``1 / (2 (1 - TILT_PERSISTENCE))`` because consecutive keyframe planes share most of it).
At every re-anchor the images' own normal (the joint refinement's) is held against the
carried plane: what their difference holds beyond both covariances is how far the ground the
camera sees departs from the plane carried, which no agreement between keyframe planes shows
(a plane carried from init.yaml's exact one keeps init.yaml's tilt, while on a slope with a
swell the ground seen sits 0.5-0.7 deg off the wheels' plane). Its size, the same on both
tilts, is added to every keyframe plane's tilt, one taken as exact included. Before the first
re-anchor a plane the images did not confirm as exact gets the filter's tilt process noise
(:class:`~monovo_cli.core.plane.tracker.PlaneTracker` adds it to frame 0's exact one where the
images stop confirming it). Why these choices, and how honest the result is on the terrain
drives: the docs section above.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, KeyLevel
from monovo_cli.core.estimator.gradient_noise import noise_factor
from monovo_cli.core.plane.belief import (
    EXACT_STD,
    PlaneBelief,
    measured_tilt,
    to_chart,
)
from monovo_cli.geometry.lie import motion_covariance_of_key_twist
from monovo_cli.geometry.plane import Plane, tangent_basis

TILT_MODEL_ERROR_DEG = 0.5  # each tilt's model error before a re-anchor has measured it (deg)
TILT_PERSISTENCE = 2.0 / 3.0  # rho: correlation of consecutive keyframe planes' tilt errors
CONSISTENCY_WINDOW = 100  # re-anchors remembered by PlaneCovarianceCalibration
PLANAR_SEEN_DEG = 0.1  # the ground seen departs from the carried planes by less: a plane
#                         (measured: flat drives 0.00-0.004 deg, terrain 0.54-0.70)
CHI2_1_MEDIAN = 0.455  # median of a chi-square variable with 1 degree of freedom
OFFSET_SAMPLES = 4  # re-anchors before their innovations size the prior's offset
SEEN_DIRECTION_SAMPLES = 3  # re-anchors before the ground seen's departure keeps its direction
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
    key_from_cur``) per unit error of the keyframe plane's chart coordinates (m, rad, rad),
    the module docstring's S.

    ``level`` the keyframe's finest level (points on ``plane``, keyframe camera),
    ``cur_from_key`` (4x4) the estimate, ``weights`` (N,) and ``normal`` (P, P) its final
    robust weights and normal matrix (``Estimate.weights``/``.normal``). The distance column
    is exact; the tilt columns' sum over the points runs over ``sample`` (:func:`point_sample`
    of ``level``, made here if None; a caller with many frames per keyframe keeps it), times
    its stride: an estimate of the full sum at a fraction of the memory traffic.
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
        self._sens_of: tuple[Estimate, np.ndarray] | None = None  # (estimate, its sensitivity)
        self._noise_of: tuple[KeyLevel, float] | None = None  # (level, its noise_factor)

    def measure_noise(self, level: KeyLevel, plane: Plane, image: np.ndarray, est: Estimate,
                      keep: bool = True) -> float:
        """The keyframe gradients' noise factor of ``level`` (on ``plane``,
        :func:`~monovo_cli.core.estimator.gradient_noise.noise_factor`): the one kept for it,
        or measured on ``image`` (at its resolution, ``est`` its fit) and, with ``keep``, kept
        for the keyframe (the rows' std: measured on its first frame)."""
        if self._noise_of is not None and self._noise_of[0] is level:
            return self._noise_of[1]
        f = noise_factor(level, plane, image, est.cur_from_key, est.weights)
        if keep:
            self._noise_of = level, f
        return f

    def noise_factor_of(self, level: KeyLevel) -> float:
        """The keyframe gradients' noise factor measured on the first frame against ``level``
        (:func:`~monovo_cli.core.estimator.gradient_noise.noise_factor`); 1 where none was."""
        return 1.0 if self._noise_of is None or self._noise_of[0] is not level else self._noise_of[1]

    def sensitivity(self, est: Estimate, level: KeyLevel, plane: Plane) -> np.ndarray | None:
        """:func:`plane_sensitivity` of ``est`` (against the keyframe of finest level ``level``
        and ``plane``), worked out once per estimate; None without weights or normal matrix."""
        if est.normal is None or est.weights is None:
            return None
        if self._sens_of is not None and self._sens_of[0] is est:
            return self._sens_of[1]
        if self._sample is None or self._sample[0] is not level:
            self._sample = level, point_sample(level)
        S = plane_sensitivity(level, plane, est.cur_from_key, est.weights, est.normal,
                              self._sample[1])
        self._sens_of = est, S
        return S

    def relative(self, est: Estimate, level: KeyLevel, plane: Plane,
                 plane_covariance: np.ndarray | None, cur_from_key_prev: np.ndarray,
                 prev_from_cur: np.ndarray, image: np.ndarray | None = None) -> np.ndarray:
        """(6, 6) covariance of (t, rotvec) of ``prev_from_cur`` (m, rad), the frame estimated
        as ``est`` against the keyframe of finest level ``level`` and ``plane`` (covariance
        ``plane_covariance`` (3, 3) in its chart; None: exact); the previous frame was at
        ``cur_from_key_prev`` (4x4). Becomes the previous frame for the next call. Given the
        frame's ``image`` (``level``'s resolution), the estimate's noise is widened by the
        keyframe gradients' own (:func:`~monovo_cli.core.estimator.gradient_noise.noise_factor`,
        measured on the keyframe's first frame given one)."""
        S = None if plane_covariance is None else self.sensitivity(est, level, plane)
        sens = np.zeros((6, 3)) if S is None else S
        D = sens - self._sens_prev
        if image is not None:
            self.measure_noise(level, plane, image, est)
        noise = est.covariance * self.noise_factor_of(level) ** 2
        inner = noise + self._cov_prev
        if plane_covariance is not None:
            inner = inner + D @ plane_covariance @ D.T
        # (cur_from_key_prev is prev_from_key)
        cov = motion_covariance_of_key_twist(inner, cur_from_key_prev, prev_from_cur)
        self._cov_prev, self._sens_prev = noise, sens
        return 0.5 * (cov + cov.T)


class PlaneCovarianceCalibration:
    """Calibrates the keyframe plane's covariance for reporting from the re-anchors seen so far
    (the last CONSISTENCY_WINDOW; docs/algorithm.md section 3, "Covariance").

    Distance: at each re-anchor the carried distance and the mounting prior's differ by
    ``nu_d``, of predicted variance ``P_carried + (process noise)^2 + sigma_prior^2``; the
    median of ``nu_d^2 / predicted`` over CHI2_1_MEDIAN scales the distance variance where it
    is above 1 (where it is below, both may stand on frame 0's plane while the ground seen
    sits elsewhere: on a sloped drive they agreed to 0.5 % while the distance was 2.5 % off).
    Tilt: what the outer product of the carried and new planes' tilt difference holds beyond
    their two covariances is the plane model's error; its element-wise median over
    CHI2_1_MEDIAN, times ``1 / (2 (1 - TILT_PERSISTENCE))``, is added to the tilt block. The
    same of the images' measured normal against the carried plane is the ground seen's
    departure from the plane. Until SEEN_DIRECTION_SAMPLES re-anchors have measured it, its
    trace, shared by the two tilts, is added to the model error (one sample is a rank-one
    outer product: it sizes the departure, not its direction). From then on the departure
    keeps its direction, and the larger (by trace) of it and the model error is added, not
    both: the new keyframe plane is fused from the images' normal, so the keyframe planes'
    jumps already hold the ground seen's departure, and the sum counted it twice. On rolling
    ground (``benchmarks.honesty``) the sum with a shared trace made the tilt across the
    track 2.8x its error and the rows' tx and rz std 2-3x theirs; the departure along the
    track is 2-3x the one across it.

    The same innovations size how far the ground's distance sits from the prior's
    (:meth:`prior_offset`), the error the prior's pull gives the keyframes' distances.
    """

    def __init__(self) -> None:
        self._distance_nis: deque[float] = deque(maxlen=CONSISTENCY_WINDOW)
        #: (nu_d (m), the share of the prior's offset the carried distance holds, less 1)
        self._distance_offsets: deque[tuple[float, float]] = deque(maxlen=CONSISTENCY_WINDOW)
        self._tilt_excess: deque[np.ndarray] = deque(maxlen=CONSISTENCY_WINDOW)
        self._seen_excess: deque[np.ndarray] = deque(maxlen=CONSISTENCY_WINDOW)
        #: (g, Q, the departure's share of the tilts, it directed against Q; None: not yet)
        self._calibration: tuple[float, np.ndarray, np.ndarray | None, np.ndarray | None] | None = None

    def reanchored(self, carried: PlaneBelief, new: PlaneBelief, prior: PlaneBelief,
                   distance_change: float, measured: PlaneBelief | None = None,
                   carried_pull: float = 0.0) -> None:
        """One re-anchor: the old keyframe's plane ``carried`` to the new keyframe
        (:func:`~monovo_cli.core.plane.belief.propagated_plane`, before process noise), whose
        plane is ``new`` (the MAP); ``prior`` the mounting prior, ``distance_change`` (m) the
        distance's process noise; ``measured`` the images' normal there (None: not measured);
        ``carried_pull`` the share of the prior's offset from the ground the carried distance's
        error holds (the pull of the re-anchors before, :meth:`PlaneTracker.successor`)."""
        try:
            Pc, Pn, Pp = carried.covariance, new.covariance, prior.covariance
        except np.linalg.LinAlgError:
            return
        predicted = Pc[0, 0] + distance_change ** 2 + Pp[0, 0]
        self._calibration = None
        if np.isfinite(predicted) and predicted > 0:
            nu_d = carried.plane.distance - prior.plane.distance
            self._distance_nis.append(nu_d ** 2 / predicted)
            self._distance_offsets.append((nu_d, carried_pull - 1.0))
        nu_t = to_chart(new.plane, carried.plane)[1:]
        excess = np.outer(nu_t, nu_t) - Pc[1:, 1:] - Pn[1:, 1:]
        if np.all(np.isfinite(excess)):
            self._tilt_excess.append(excess)
        got = None if measured is None else measured_tilt(measured, carried.plane)
        if got is not None:
            seen = np.outer(got[0], got[0]) - got[1] - Pc[1:, 1:]
            if np.all(np.isfinite(seen)):
                self._seen_excess.append(seen)

    @property
    def ground_planar(self) -> bool:
        """The images' normals at the re-anchors so far agree with the planes carried to them
        (what they hold beyond both covariances, per angle, within PLANAR_SEEN_DEG): the
        ground seen is the plane model's, and the keyframes' tilts measure one plane (True
        before any re-anchor)."""
        seen = self._seen_variance()
        return seen is None or seen <= math.radians(PLANAR_SEEN_DEG) ** 2

    def prior_offset(self) -> tuple[float, float] | None:
        """``(common, spread)`` (m^2): how far the ground's distance sits from the mounting
        prior's, from the re-anchors' innovations; None before OFFSET_SAMPLES of them.

        The prior's centre differs from the ground's distance by an offset ``b`` common to
        every keyframe (frame 0 off the mean mount, a mount declared a little off) and a
        bobbing ``u`` of its own at each. An innovation ``nu = carried - prior`` is then
        ``a b - u`` and the carried distance's own error, ``a`` the share of ``b`` the carried
        error holds less 1 (a drive whose prior has pulled its distance all the way tells
        nothing of ``b`` any more). ``b`` is fitted by least squares; ``spread`` is the
        residuals' variance at its upper one-sigma bound for as many (n - 1 degrees of
        freedom, Wilson-Hilferty: 3.6x at 4 re-anchors, 1.9x at 10, 1.3x at 40), ``common``
        the fitted ``b`` squared (whose expectation holds the fit's variance). The prior's
        width is a weight chosen for the MAP, the bobbing a drive may have; these are the
        drive's own (512² flat drives: a width of 71 mm with a latent mount, a departure of
        6.8 mm RMS; a MER drive: frame 0 35 mm below the mean mount)."""
        n = len(self._distance_offsets)
        if n < OFFSET_SAMPLES:
            return None
        nu, a = np.array(self._distance_offsets).T
        aa = float(a @ a)
        if aa <= 0.0:
            return None
        b = float(nu @ a) / aa
        dof = n - 1
        lower = dof * (1.0 - 2.0 / (9.0 * dof) - math.sqrt(2.0 / (9.0 * dof))) ** 3
        spread = float(np.sum((nu - a * b) ** 2)) / lower
        return b ** 2, spread

    @property
    def departure_measured(self) -> bool:
        """A re-anchor has measured how far the ground seen departs from the carried plane."""
        return bool(self._seen_excess)

    def _seen_variance(self) -> float | None:
        """(rad^2) how far, per tilt angle, the ground seen departs from the carried planes
        (the median excess's trace shared by the two); None before any re-anchor measured it."""
        if not self._seen_excess:
            return None
        return 0.5 * float(np.trace(_median_excess(self._seen_excess)))

    def reported(self, covariance: np.ndarray) -> np.ndarray:
        """``covariance`` (3, 3), the keyframe plane's in its chart (m, rad), calibrated: the
        distance's row and column scaled; added to the tilts, the plane model's error and the
        ground seen's departure from the carried plane, or the larger of the two once the
        departure's direction is known (class docstring), or before any re-anchor
        TILT_MODEL_ERROR_DEG on each. A plane taken as exact (tilt std within 10 EXACT_STD)
        gets only the departure, its trace shared by the tilts."""
        if self._calibration is None or len(self._calibration) != 4:  # (once per re-anchor;
            #                                              a checkpoint's of 3: worked out anew)
            g, Q = 1.0, np.eye(2) * math.radians(TILT_MODEL_ERROR_DEG) ** 2
            directed = None
            if self._distance_nis:
                # widened where the innovations say so, never narrowed: the carried distance
                # and the prior agreeing better than their widths does not make either right
                # when both stand on frame 0's plane and the ground seen is elsewhere
                g = max(1.0, math.sqrt(float(np.median(self._distance_nis)) / CHI2_1_MEDIAN))
            if self._tilt_excess:
                Q = _median_excess(self._tilt_excess) / (2.0 * (1.0 - TILT_PERSISTENCE))
            v = self._seen_variance()  # its size (a plane taken as exact: always)
            seen = None if v is None else np.eye(2) * v
            if len(self._seen_excess) >= SEEN_DIRECTION_SAMPLES:  # ... and its direction
                S = _median_excess(self._seen_excess)
                directed = Q if np.trace(Q) >= np.trace(S) else S
            self._calibration = g, Q, seen, directed
        g, Q, seen, directed = self._calibration
        P = np.array(covariance, dtype=float)
        if np.max(np.diag(P)[1:]) <= (10 * EXACT_STD) ** 2:  # a plane taken as exact
            if seen is not None:
                P[1:, 1:] += seen
            return P
        P[0, :] *= g
        P[:, 0] *= g
        if directed is not None:
            P[1:, 1:] += directed
        else:
            P[1:, 1:] += Q if seen is None else Q + seen
        return P


def _median_excess(excess) -> np.ndarray:
    """(2, 2) the element-wise median of tilt excesses (outer products of a difference less
    its predicted covariance) over CHI2_1_MEDIAN, its negative part dropped."""
    Q = np.median(np.array(excess), axis=0) / CHI2_1_MEDIAN
    lam, V = np.linalg.eigh(0.5 * (Q + Q.T))
    return (V * np.clip(lam, 0.0, None)) @ V.T
