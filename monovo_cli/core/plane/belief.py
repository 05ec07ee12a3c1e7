"""The keyframe plane as a Gaussian belief: carried through the motions, fused at re-anchors
(docs/algorithm.md section 4, "The new keyframe's plane").

A plane ``{X : n . X = d}`` near a reference plane ``(n_r, d_r)`` has the chart coordinates
``x = (d - d_r, theta_1, theta_2)`` (m, rad) with ``theta = E_r^T n / (n_r . n)``, where the
columns of ``E_r`` (3, 2) span the plane orthogonal to ``n_r`` (:func:`tangent_basis`): the
distance and two tilt angles (the gnomonic chart of the unit sphere, so the inverse is
``n = normalize(n_r + E_r theta)``). A :class:`PlaneBelief` is a Gaussian in these
coordinates in information form (``information`` Lambda, ``vector`` eta = Lambda x_mean), so
that a measurement that says nothing about the distance (the images, see below) has a
zero row and column instead of an infinite variance.

At a new keyframe the plane is the maximum a posteriori combination (:func:`fuse`, the sum
of the informations, iterated on the sphere) of

(a) the previous keyframe's plane carried through the estimated motion, its covariance
    propagated with the motion's (:func:`propagate`): a distance error scales the
    translation with it (the images fix t / d), so it is carried as ``d_cur / d_key`` times
    itself; the motion's error adds ``-n . v`` to the distance and ``n x w`` to the normal.
    Then a process noise of DISTANCE_CHANGE times the distance and TILT_CHANGE_DEG on each
    tilt: on ground that is not a plane the carried plane errs by more than the motion's
    covariance knows, and the new keyframe's patch of ground is not the old one. Where the
    images of frame 0 confirmed init.yaml's tilt, the ground seen is the plane under the
    wheels, and the distance's is DISTANCE_CHANGE_PLANAR times the distance: the chain then
    keeps frame 0's exact distance, where the larger one hands every keyframe's distance to
    the mounting prior, and with it frame 0's own bob (:class:`PlaneTracker`). The tilt's
    is none by default: the carried normal's information then only grows from keyframe to
    keyframe, and the images' normal of each new patch, biased on curved ground, can walk it
    away from the mounting prior (why none was chosen: the docs section above);
(b) the plane measured from the images at that keyframe: the normal from the joint
    refinement of motion and normal (:mod:`monovo_cli.core.plane.fit`), with the information
    of its normal equations; no information on the distance (with d and the translation
    scaled together the images do not change);
(c) the mounting prior (:func:`mounting_prior`): the rover stands on the ground, so in every
    camera frame the ground is the plane of init.yaml within ``ground.sigma_distance`` (m)
    and ``ground.sigma_deg`` (suspension, terrain). Each keyframe's prior counts as an
    independent measurement of that keyframe's ground, so the scale converges to the mean
    of the departures rather than to frame 0's: frame 0 is one sample, not the truth.

How the process noises were chosen, and what they cost and buy: the docs section above.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from monovo_cli.geometry.lie import skew
from monovo_cli.geometry.plane import Plane, tangent_basis

SIGMA_DISTANCE_FRACTION = 1.0 / 30.0  # default ground.sigma_distance: this x the distance
SIGMA_DEG = 3.0  # default ground.sigma_deg
DISTANCE_CHANGE = 0.02  # process noise of the carried distance per keyframe: this x the distance
DISTANCE_CHANGE_PLANAR = 0.002  # ... where frame 0's images confirmed init.yaml's tilt
TILT_CHANGE_DEG = 0.0  # process noise of each carried tilt angle per keyframe (deg)


def to_chart(ref: Plane, plane: Plane) -> np.ndarray:
    """Coordinates (3,) of ``plane`` in the chart at ``ref``: (d - d_r, theta_1, theta_2)."""
    n = plane.normal
    return np.r_[plane.distance - ref.distance, tangent_basis(ref.normal).T @ n / (ref.normal @ n)]


def from_chart(ref: Plane, x: np.ndarray) -> Plane:
    """The plane at chart coordinates ``x`` (3,) of ``ref`` (inverse of :func:`to_chart`)."""
    n = ref.normal + tangent_basis(ref.normal) @ x[1:]
    return Plane(n / np.linalg.norm(n), ref.distance + float(x[0]))


def chart_jacobian(ref: Plane, at: Plane) -> np.ndarray:
    """(3, 3): d to_chart(ref, .) / d x at the origin of the chart of ``at``."""
    nr, n = ref.normal, at.normal
    Er, Ea = tangent_basis(nr), tangent_basis(n)
    c = float(nr @ n)
    J = np.zeros((3, 3))
    J[0, 0] = 1.0
    J[1:, 1:] = (Er.T / c - np.outer(Er.T @ n, nr) / c ** 2) @ Ea
    return J


@dataclass(frozen=True)
class PlaneBelief:
    """A Gaussian belief about a plane in the chart at ``plane`` (module docstring).

    ``information`` (3, 3) of (d, theta_1, theta_2) (1/m^2, 1/rad^2, ...), symmetric positive
    semi-definite; ``vector`` (3,) the information vector eta: the mean is at chart
    coordinates ``x`` with ``information @ x = vector`` (zeros: the mean is ``plane``).
    """

    plane: Plane
    information: np.ndarray
    vector: np.ndarray | None = None

    @property
    def eta(self) -> np.ndarray:
        """(3,) the information vector (zeros when ``vector`` is None)."""
        return np.zeros(3) if self.vector is None else np.asarray(self.vector, dtype=float)

    @property
    def covariance(self) -> np.ndarray:
        """(3, 3) inverse of the information (raises LinAlgError if it is singular)."""
        return np.linalg.inv(self.information)

    @classmethod
    def from_covariance(cls, plane: Plane, covariance: np.ndarray) -> PlaneBelief:
        """The belief with mean ``plane`` and ``covariance`` (3, 3) in its chart (invertible)."""
        return cls(plane, np.linalg.inv(covariance))

    def in_chart(self, ref: Plane) -> tuple[np.ndarray, np.ndarray]:
        """``(information, vector)`` of this belief in the chart at ``ref`` (linearised)."""
        K = np.linalg.inv(chart_jacobian(ref, self.plane))
        L = K.T @ self.information @ K
        return 0.5 * (L + L.T), L @ to_chart(ref, self.plane) + K.T @ self.eta


def mounting_prior(plane: Plane, sigma_distance: float, sigma_deg: float) -> PlaneBelief:
    """The mounting prior: ``plane`` (init.yaml's, valid in every camera frame) with std
    ``sigma_distance`` (m) on the distance and ``sigma_deg`` on each tilt angle; an infinite
    sigma gives no information on its part."""
    s_t = math.radians(sigma_deg)
    info = np.diag([1.0 / sigma_distance ** 2, 1.0 / s_t ** 2, 1.0 / s_t ** 2])
    return PlaneBelief(plane, info)


def default_sigmas(plane: Plane, sigma_distance: float | None,
                   sigma_deg: float | None) -> tuple[float, float]:
    """``(sigma_distance, sigma_deg)`` with the documented defaults for those not given:
    ``SIGMA_DISTANCE_FRACTION`` of the plane's distance (5 cm at 1.5 m) and ``SIGMA_DEG``."""
    return (plane.distance * SIGMA_DISTANCE_FRACTION if sigma_distance is None else sigma_distance,
            SIGMA_DEG if sigma_deg is None else sigma_deg)


def fuse(beliefs: Sequence[PlaneBelief], iterations: int = 3) -> PlaneBelief:
    """The maximum a posteriori plane of independent ``beliefs`` (at least one with full
    information in sum), with its information in its own chart.

    Linearised in the chart at the current estimate (first: the first belief's plane), the
    sum of the informations and information vectors gives the next estimate; a few
    iterations settle the sphere's curvature. Raises ValueError if the sum is singular.
    """
    ref = beliefs[0].plane
    for _ in range(iterations):
        L = np.zeros((3, 3))
        eta = np.zeros(3)
        for b in beliefs:
            Lb, eb = b.in_chart(ref)
            L += Lb
            eta += eb
        try:
            x = np.linalg.solve(L, eta)
        except np.linalg.LinAlgError:
            raise ValueError("the plane beliefs do not determine the plane") from None
        ref = from_chart(ref, x)
        if np.max(np.abs(x)) < 1e-12:
            break
    L = sum(b.in_chart(ref)[0] for b in beliefs)
    return PlaneBelief(ref, L)


def propagate(plane: Plane, covariance: np.ndarray, cur_from_key: np.ndarray,
              motion_covariance: np.ndarray, sensitivity: np.ndarray | None = None
              ) -> PlaneBelief:
    """Belief (a): ``plane`` (in the keyframe camera, ``covariance`` (3, 3) in its chart)
    in the current camera, given ``cur_from_key`` (4x4) whose twist xi (v, w) has
    ``motion_covariance`` (6, 6) with ``key_from_cur_true = exp(xi^) key_from_cur``.

    First order: ``n_c = R n``, ``d_c = d + n_c . t``; a distance error scales t with it (the
    images fix t / d), a tilt moves with R, and the motion's error moves the plane by
    ``exp(-xi)`` in the keyframe (``d -= n . v``, ``n += n x w``). ``sensitivity`` (6, 3):
    the motion was estimated against ``plane``, so a plane error ``dx`` moved the estimate
    too, by ``S dx`` (:func:`~monovo_cli.core.plane.motion_covariance.plane_sensitivity`);
    the carried plane's error is then ``(J_plane + J_motion S) dx`` plus the motion's own
    noise (:func:`carrying_jacobian`). None: plane and motion errors taken as independent.
    """
    cur, J = propagation_jacobian(plane, cur_from_key)
    A = carrying_jacobian(J, sensitivity)
    Jm = J[:, 3:]
    P = A @ covariance @ A.T + Jm @ motion_covariance @ Jm.T
    return PlaneBelief(cur, np.linalg.inv(0.5 * (P + P.T)))


def carrying_jacobian(J: np.ndarray, sensitivity: np.ndarray | None) -> np.ndarray:
    """(3, 3) how an error of the keyframe's plane (its chart) reaches the carried plane:
    ``J`` (3, 9) :func:`propagation_jacobian`'s; with ``sensitivity`` S (6, 3), through the
    motion estimated against it too, ``J_plane + J_motion S`` on the tilt columns (the
    distance column of S, the translation's scale, is J's ``d_c / d`` already). At MER
    spacing (0.6 m steps, 45 deg down) that factor is about 1.24 on each tilt: a tilt error
    grows by a quarter per keyframe unless the images' normal corrects it
    (docs/algorithm.md section 4)."""
    A = np.array(J[:, :3])
    if sensitivity is not None:
        A[:, 1:] += J[:, 3:] @ sensitivity[:, 1:]
    return A


def propagation_jacobian(plane: Plane, cur_from_key: np.ndarray) -> tuple[Plane, np.ndarray]:
    """``plane`` (keyframe camera) in the current camera and the Jacobian (3, 9) of its chart
    coordinates there with respect to the keyframe chart's (3) and the twist xi (6) of
    :func:`propagate`."""
    R, t = cur_from_key[:3, :3], cur_from_key[:3, 3]
    cur = plane.in_frame(cur_from_key)
    n = plane.normal
    Ek, Ec = tangent_basis(n), tangent_basis(cur.normal)
    REk = R @ Ek
    RN = R @ skew(n)
    J = np.zeros((3, 9))
    J[0, 0] = cur.distance / plane.distance
    J[0, 1:3] = t @ REk
    J[0, 3:6] = -n
    J[0, 6:9] = t @ RN
    J[1:, 1:3] = Ec.T @ REk
    J[1:, 6:9] = Ec.T @ RN
    return cur, J


@dataclass(frozen=True)
class PlaneLink:
    """How a keyframe's plane (the MAP at its re-anchor) corrected the plane carried to it
    from the previous keyframe, for smoothing the previous one's in hindsight
    (Rauch-Tung-Striebel): ``innovation`` (3,) the MAP's chart coordinates at the carried
    plane, ``gain`` (3, 3) the previous keyframe's smoother gain ``P_k J^T P_pred^-1`` (P_k its
    plane's covariance, J :func:`carrying_jacobian`, P_pred the carried
    plane's covariance with the process noise).

    For re-solving the distances in hindsight (:func:`monovo_cli.mapping.smoothing.smoothed_distances`):
    ``propagated_distance`` (m) the carried plane's distance, ``propagated_variance`` (m^2) the
    variance that carrying added to it (the motion's error, the tilt's, the process noise:
    the carried plane's distance variance less the previous keyframe's own, scaled),
    ``previous_variance`` (m^2) the previous keyframe's distance variance when it was left,
    ``mounting`` the mounting prior's ``(distance, std)`` (m): its reference distance (frame
    0's, or the declared mount's) and the bobbing's std; ``latent_mount`` whether the mean
    mount is unknown (estimated from the drive) rather than the reference. NaN: not recorded."""

    gain: np.ndarray
    innovation: np.ndarray
    propagated_distance: float = math.nan
    propagated_variance: float = math.nan
    previous_variance: float = math.nan
    mounting: tuple[float, float] = (math.nan, math.nan)
    latent_mount: bool = False


def smoothed_corrections(links: Sequence[PlaneLink | None]) -> list[np.ndarray]:
    """The backward pass of the smoother over a chain of keyframes, oldest first: ``links[k]``
    links keyframe k to its predecessor (None: a chain begins there, e.g. frame 0 or a
    re-initialisation). Returns each keyframe's correction (3,) in its plane's chart: the
    last's is zero (it has no successor), then ``delta_k = gain_{k+1} (innovation_{k+1} +
    delta_{k+1})`` (the successor's correction taken as one at its carried plane: first order)."""
    out = [np.zeros(3) for _ in links]
    for k in range(len(links) - 2, -1, -1):
        link = links[k + 1]
        if link is not None:
            out[k] = link.gain @ (link.innovation + out[k + 1])
    return out


def propagated_plane(key_plane: Plane, key_covariance: np.ndarray, cur_from_key: np.ndarray,
                  motion_covariance: np.ndarray, sensitivity: np.ndarray | None = None
                  ) -> PlaneBelief:
    """Belief (a) before its process noise: :func:`propagate`, a motion covariance that is not
    finite (no estimate of it) taken as zero, and with it the sensitivity."""
    if not np.all(np.isfinite(motion_covariance)):
        motion_covariance, sensitivity = np.zeros((6, 6)), None
    return propagate(key_plane, key_covariance, cur_from_key, motion_covariance, sensitivity)


def keyframe_plane(carried: PlaneBelief, *, measured: PlaneBelief | None = None,
                   prior: PlaneBelief | None = None, distance_change: float = 0.0,
                   tilt_change: float = 0.0) -> PlaneBelief:
    """The plane of a new keyframe (in its camera): the MAP of (a) ``carried``
    (:func:`propagated_plane`) with process noise of std ``distance_change`` (m) added to its
    distance and ``tilt_change`` (rad) to each tilt, (b) ``measured`` and (c) ``prior``
    (module docstring)."""
    if distance_change > 0 or tilt_change > 0:
        P = carried.covariance + process_noise(distance_change, tilt_change)
        carried = PlaneBelief(carried.plane, np.linalg.inv(P))
    return fuse([carried] + [b for b in (measured, prior) if b is not None])


def carried_map(plane: Plane, covariance: np.ndarray, cur_from_key: np.ndarray, twist: np.ndarray,
                sensitivity: np.ndarray | None, measured: PlaneBelief | None, prior: PlaneBelief,
                distance_change: float, tilt_change: float) -> tuple[PlaneBelief, PlaneBelief]:
    """``(carried, MAP)``: the keyframe ``plane`` (chart ``covariance``) carried by
    ``cur_from_key`` (twist covariance ``twist``, :func:`propagated_plane`) and the new
    keyframe's plane from it, ``measured`` and ``prior`` (:func:`keyframe_plane`)."""
    carried = propagated_plane(plane, covariance, cur_from_key, twist, sensitivity)
    return carried, keyframe_plane(carried, measured=measured, prior=prior,
                                   distance_change=distance_change, tilt_change=tilt_change)


def process_noise(distance_change: float, tilt_change: float) -> np.ndarray:
    """(3, 3) chart covariance of the carried plane's process noise: std ``distance_change``
    (m) on the distance and ``tilt_change`` (rad) on each tilt."""
    return np.diag([distance_change ** 2, tilt_change ** 2, tilt_change ** 2])


def widened(belief: PlaneBelief, factor: float) -> PlaneBelief:
    """``belief`` with its std multiplied by ``factor`` (its information divided by the
    square), its mean kept: a measurement whose information counted noise as texture."""
    if factor == 1.0:
        return belief
    scale = 1.0 / factor ** 2
    return PlaneBelief(belief.plane, belief.information * scale,
                       None if belief.vector is None else belief.eta * scale)


def transported(belief: PlaneBelief, b_from_a: np.ndarray) -> PlaneBelief:
    """A belief about a plane in frame a, as one about the same plane in frame b (exact pose
    ``b_from_a``, 4x4): the tilt coordinates turn with the rotation; a distance with no
    information stays without."""
    moved = belief.plane.in_frame(b_from_a)
    M = np.eye(3)
    M[1:, 1:] = tangent_basis(moved.normal).T @ b_from_a[:3, :3] @ tangent_basis(belief.plane.normal)
    M[0, 1:] = b_from_a[:3, 3] @ b_from_a[:3, :3] @ tangent_basis(belief.plane.normal)
    K = np.linalg.inv(M)
    L = K.T @ belief.information @ K
    return PlaneBelief(moved, 0.5 * (L + L.T), K.T @ belief.eta)


PLANE_SETTLED_DEG = 1.0  # a keyframe plane whose tilt std exceeds this is measured on every frame


def tilt_std_deg(covariance: np.ndarray) -> float:
    """The largest std (deg) of the tilt angles in a plane covariance (3, 3)."""
    return float(np.degrees(np.sqrt(max(np.linalg.eigvalsh(covariance[1:, 1:])[-1], 0.0))))
CONSISTENT_CHI2 = 13.8  # chi-square of 2 tilts at 99.9 %: below it the images confirm a plane
UNCONFIRMED_CHI2 = 4.61  # chi-square of 2 tilts at 90 %: from it the images do not confirm a tilt


def measured_tilt(measured: PlaneBelief, plane: Plane) -> tuple[np.ndarray, np.ndarray] | None:
    """The tilt angles (2,) rad the normal ``measured`` gives in the chart of ``plane``, and
    their covariance (2, 2); None where the measurement holds no tilt information."""
    L, eta = measured.in_chart(plane)
    try:
        C = np.linalg.inv(L[1:, 1:])
    except np.linalg.LinAlgError:
        return None
    return C @ eta[1:], C


def with_mount_departure(covariance: np.ndarray,
                         mount: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """A keyframe plane's reported ``covariance`` (3, 3), and, where its tilt and the mounting
    prior's cannot both hold, their difference too: ``mount`` the prior's tilt angles (2,) in
    the plane's chart and their covariance (:func:`measured_tilt`; None: nothing added). If
    the difference's chi-square against both covariances is beyond CONSISTENT_CHI2, ``delta
    delta^T`` joins the tilt block: the rover stands on its ground, so a keyframe plane that
    far from the mount is the estimate's error or a ground seen that is not the one under the
    wheels, and the tool cannot tell which (soak scenario 307, a low-texture rock field: a
    keyframe's normal 29 deg from the truth in fifteen frames, its tilt reported to within
    2.5 deg)."""
    if mount is None:
        return covariance
    delta, C = mount
    try:
        chi2 = float(delta @ np.linalg.solve(C + covariance[1:, 1:], delta))
    except np.linalg.LinAlgError:
        return covariance
    if chi2 <= CONSISTENT_CHI2:
        return covariance
    P = np.array(covariance, dtype=float)
    P[1:, 1:] += np.outer(delta, delta)
    return P


def tilt_chi2(measured: PlaneBelief, plane: Plane) -> float:
    """Chi-square (2 dof) of the tilt that ``measured`` gives against ``plane``'s: how far the
    measurement's mean lies from ``plane`` in units of its own information."""
    L, eta = measured.in_chart(plane)
    x = np.linalg.pinv(L[1:, 1:]) @ eta[1:]
    return float(x @ L[1:, 1:] @ x)
CONFIRMED_DEG = 0.5  # a consistent measurement this precise confirms a plane as exact
EXACT_STD = 1e-6  # relative std of the distance and std (rad) of the tilts of a confirmed plane


def measured_tilt_std_deg(measured: PlaneBelief) -> float:
    """The largest std (deg) of the tilts a measurement gives (inf where it says nothing)."""
    lam = np.linalg.eigvalsh(measured.information[1:, 1:])[0]
    return float(np.degrees(1.0 / np.sqrt(lam))) if lam > 0 else float("inf")


def exact_covariance(plane: Plane) -> np.ndarray:
    """(3, 3) covariance of a plane taken as exact (tiny, so that beliefs stay invertible)."""
    return np.diag([(EXACT_STD * plane.distance) ** 2, EXACT_STD ** 2, EXACT_STD ** 2])
