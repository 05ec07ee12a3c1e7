"""Measuring the ground plane at a keyframe from the images (belief (b) of docs/algorithm.md
section 4).

Carrying the plane from keyframe to keyframe with the accumulated estimate alone lets an
error in the normal bias the next motions, which tilt the normal further. At each re-anchor
we therefore refine, jointly, the motion ``cur_from_key`` and the keyframe plane's normal n
from the two images (the keyframe's observation points sampled in the current frame, a
forward Gauss-Newton whose point positions X_i(n) = d r_i / (n . r_i) move with the plane).
The result is a measurement of the normal with the information of its normal equations
(:class:`PlaneFit`), which :mod:`monovo_cli.core.plane.belief` combines with the plane
carried through the motions and the mounting prior.

The distance d is not refined here: with d and the translation scaled together the images
do not change (the monocular scale gauge); the measurement carries no information on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from monovo_cli.core.estimator.ground import LevelPoints
from monovo_cli.core.estimator.jacobian import distortion_jacobian, observation_rows, project_in_front
from monovo_cli.core.estimator.robust import robust_weights
from monovo_cli.core.options import EstimatorOptions
from monovo_cli.core.plane.belief import PlaneBelief
from monovo_cli.geometry.lie import se3_exp
from monovo_cli.geometry.plane import Plane, tangent_basis
from monovo_cli.image.gradients import with_sobel_gradient
from monovo_cli.image.sampling import sample_bilinear

REGULARISER_DEG = 5.0  # std of the numerical prior that keeps the steps finite (removed after)


@dataclass(frozen=True)
class PlaneFit:
    """The joint refinement's result: ``cur_from_key`` (4x4), the keyframe ``plane`` with the
    refined normal, the brightness model, and ``measured``: what the images say about the
    plane (in the keyframe camera, chart at ``plane``; no information on the distance), or
    None when they could not be evaluated."""

    cur_from_key: np.ndarray
    plane: Plane
    gain: float
    bias: float
    measured: PlaneBelief | None


def _system(rays: np.ndarray, I_key: np.ndarray, cam, stack: np.ndarray, T: np.ndarray,
            n: np.ndarray, d: float, gain: float, bias: float, opts: EstimatorOptions):
    """Residuals and rows at ``(T, n, gain, bias)``: ``(J (M, 10), r (M,), w (M,), scale)`` over
    the valid points, or None when too few are valid. Columns: the left twist of T, the
    normal along ``tangent_basis(n)``, gain, bias. ``stack`` (H, W, 3) float32: the current
    frame and its Sobel gradients."""
    denom = rays @ n
    if np.any(denom <= 1e-9):
        return None
    X = rays * (d / denom)[:, None]
    R, t = T[:3, :3], T[:3, 3]
    Xc = X @ R.T + t
    u, v, front = project_in_front(cam, Xc)
    z = Xc[:, 2]
    iz = np.where(front, 1.0 / np.where(front, z, 1.0), 0.0)
    samples, valid = sample_bilinear(stack, u, v)
    vals, gx, gy = samples.T
    valid &= front
    if np.count_nonzero(valid) < max(opts.min_valid_points, 50):
        return None
    r = vals.astype(np.float64) - (gain * I_key + bias)
    D = None
    if cam.has_distortion:
        D = distortion_jacobian(cam, np.where(front[:, None], Xc, np.array([0.0, 0.0, 1.0])))
    E = tangent_basis(n)
    # Columns: d r / d(left twist of T) = the observation rows (a, Xc x a) at the current
    # points; d r / d(normal along e1, e2) = (a^T R X) * (-(X . e) / d); then the
    # brightness model (-I_key, -1).
    J = np.empty((len(r), 10))
    J[:, :6] = observation_rows(Xc, gx, gy, cam.fx, cam.fy, D, inverse_depth=iz).T
    a1, a2, a3 = J[:, 0], J[:, 1], J[:, 2]
    aRX = a1 * (Xc[:, 0] - t[0]) + a2 * (Xc[:, 1] - t[1]) + a3 * (Xc[:, 2] - t[2])
    aRX /= -d
    J[:, 6] = aRX * (X @ E[:, 0])
    J[:, 7] = aRX * (X @ E[:, 1])
    J[:, 8] = -I_key
    J[:, 9] = -1.0
    rv = r[valid]
    wv, scale = robust_weights(rv.astype(np.float32), opts.robust, huber_k=opts.huber_k,
                               tukey_c=opts.tukey_c)
    return J[valid], rv, wv.astype(np.float64), scale


def _measurement(plane: Plane, J: np.ndarray, r: np.ndarray, w: np.ndarray) -> PlaneBelief | None:
    """What the images alone say about the normal at ``plane``: the normal equations'
    information on it with the motion and brightness eliminated (Schur complement), and the
    information vector of the images-only Gauss-Newton step from there."""
    Jw = J * w[:, None]
    dof = max(float(w.sum()) - J.shape[1], 1.0)
    sigma2 = max(float(np.dot(w, r * r)) / dof, 1e-12)
    H = (Jw.T @ J) / sigma2
    g = (Jw.T @ r) / sigma2
    o = [0, 1, 2, 3, 4, 5, 8, 9]
    try:
        K = np.linalg.solve(H[np.ix_(o, o)], np.column_stack([H[o][:, 6:8], g[o]]))
    except np.linalg.LinAlgError:
        return None
    L = H[6:8, 6:8] - H[6:8, o] @ K[:, :2]
    eta = -(g[6:8] - H[6:8, o] @ K[:, 2])
    L = 0.5 * (L + L.T)
    lam, V = np.linalg.eigh(L)
    lam = np.clip(lam, 0.0, None)
    if not np.all(np.isfinite(lam)):
        return None
    info = np.zeros((3, 3))
    info[1:, 1:] = (V * lam) @ V.T
    return PlaneBelief(plane, info, np.r_[0.0, eta])


def refine_plane_and_motion(points: LevelPoints, image: np.ndarray, cur_from_key: np.ndarray,
                            plane: Plane, *, gain: float = 1.0, bias: float = 0.0,
                            options: EstimatorOptions | None = None, iterations: int = 8,
                            max_points: int = 8192) -> PlaneFit:
    """Jointly refine ``cur_from_key`` (4x4) and the keyframe ``plane``'s normal.

    ``points`` are the keyframe's observation points at the level of ``image`` (the current
    frame, float32). The steps are kept finite by a weak prior on the normal (std
    REGULARISER_DEG, centred on the starting normal) which the returned measurement does
    not contain: its information and information vector are those of the images alone at
    the refined plane. If the data do not support a refinement (too few points in view, a
    singular system) the inputs come back unchanged, with no measurement. At most
    ``max_points`` of the points are used (every k-th: they are sorted by row, so the subset
    keeps their spread); two normal parameters need far fewer than the motion estimate, and
    this keeps a re-anchor cheap.
    """
    opts = options or EstimatorOptions()
    cam = points.camera
    stack = with_sobel_gradient(image)  # sampled together: one remap
    step_k = max(1, -(-len(points) // max_points))
    rays = points.X[::step_k] / points.X[::step_k, 2:3]
    I_key = points.intensity[::step_k].astype(np.float64)
    T = np.array(cur_from_key, dtype=np.float64)
    n = np.array(plane.normal, dtype=np.float64)
    d = float(plane.distance)
    n_start = n.copy()
    inv_s2 = 1.0 / math.radians(REGULARISER_DEG) ** 2
    system = None
    for _ in range(iterations):
        system = _system(rays, I_key, cam, stack, T, n, d, gain, bias, opts)
        if system is None:
            break
        Jv, rv, wv, scale = system
        Jw = Jv * (wv[:, None] / scale ** 2)
        H = Jw.T @ Jv
        g = Jw.T @ rv
        E = tangent_basis(n)
        dn = n - n_start
        H[6, 6] += inv_s2
        H[7, 7] += inv_s2
        g[6] += inv_s2 * (dn @ E[:, 0])
        g[7] += inv_s2 * (dn @ E[:, 1])
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            system = None
            break
        if not np.all(np.isfinite(step)):
            system = None
            break
        T = se3_exp(step[:6]) @ T
        n = n + step[6] * E[:, 0] + step[7] * E[:, 1]
        n /= np.linalg.norm(n)
        gain += step[8]
        bias += step[9]
        if np.max(np.abs(step[:8])) < 1e-9:
            break
    refined = Plane(n, d)
    measured = None
    if system is not None:
        final = _system(rays, I_key, cam, stack, T, n, d, gain, bias, opts)
        if final is not None:
            measured = _measurement(refined, final[0], final[1], final[2])
    return PlaneFit(T, refined, float(gain), float(bias), measured)
