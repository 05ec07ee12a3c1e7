"""Re-estimating the ground plane at a keyframe from the images, with the mounting prior.

Carrying the plane from keyframe to keyframe with the accumulated estimate alone lets an
error in the normal bias the next motions, which tilt the normal further. At each re-anchor
we therefore refine, jointly, the motion ``cur_from_key`` and the keyframe plane's normal n
from the two images (the keyframe's observation points sampled in the current frame, a
forward Gauss-Newton whose point positions X_i(n) = d r_i / (n . r_i) move with the plane),
regularised by the camera's mounting pose from init.yaml: the rover stands on the ground,
so in every camera frame the plane is close to the initial one (n0, d0).

The distance d is not refined here: with d and the translation scaled together the images
do not change (the monocular scale gauge). Instead the next keyframe's distance is pulled
gently back toward the mounting height (``distance_pull``), which bounds scale drift.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monovo_cli.core.estimate import EstimatorOptions
from monovo_cli.core.ground import LevelPoints
from monovo_cli.core.jacobian import distortion_jacobian, observation_rows, project_in_front
from monovo_cli.core.robust import robust_weights
from monovo_cli.geometry.lie import se3_exp
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import sobel_gradient
from monovo_cli.image.sampling import sample_bilinear


@dataclass(frozen=True)
class PlanePrior:
    """The mounting plane (n0, d0) in the camera frame and the prior's std of the normal (rad)."""

    plane: Plane
    normal_sigma: float = np.radians(2.0)
    distance_pull: float = 0.1


def _tangent_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def refine_plane_and_motion(points: LevelPoints, image: np.ndarray, cur_from_key: np.ndarray,
                            plane: Plane, prior: PlanePrior, *, gain: float = 1.0,
                            bias: float = 0.0, options: EstimatorOptions | None = None,
                            iterations: int = 8,
                            max_points: int = 8192) -> tuple[np.ndarray, Plane, float, float]:
    """Jointly refine ``cur_from_key`` (4x4) and the keyframe ``plane``'s normal.

    ``points`` are the keyframe's observation points at the level of ``image`` (the current
    frame, float32). Returns the refined ``(cur_from_key, plane, gain, bias)``; if the data
    do not support a refinement (too few points in view, a singular system) the inputs come
    back unchanged. At most ``max_points`` of the points are used (every k-th: they are
    sorted by row, so the subset keeps their spread); two normal parameters need far fewer
    than the motion estimate, and this keeps a re-anchor cheap.
    """
    opts = options or EstimatorOptions()
    cam = points.camera
    gx_img, gy_img = sobel_gradient(image)
    step_k = max(1, -(-len(points) // max_points))
    rays = points.X[::step_k] / points.X[::step_k, 2:3]
    I_key = points.intensity[::step_k].astype(np.float64)
    T = np.array(cur_from_key, dtype=np.float64)
    n = np.array(plane.normal, dtype=np.float64)
    d = float(plane.distance)
    n0 = prior.plane.normal
    inv_s2 = 1.0 / prior.normal_sigma ** 2
    for _ in range(iterations):
        denom = rays @ n
        if np.any(denom <= 1e-9):
            break
        X = rays * (d / denom)[:, None]
        R, t = T[:3, :3], T[:3, 3]
        Xc = X @ R.T + t
        u, v, front = project_in_front(cam, Xc)
        z = Xc[:, 2]
        iz = np.where(front, 1.0 / np.where(front, z, 1.0), 0.0)
        vals, valid = sample_bilinear(image, u, v)
        gx, _ = sample_bilinear(gx_img, u, v)
        gy, _ = sample_bilinear(gy_img, u, v)
        valid &= front
        if np.count_nonzero(valid) < max(opts.min_valid_points, 50):
            break
        r = vals.astype(np.float64) - (gain * I_key + bias)
        D = None
        if cam.has_distortion:
            D = distortion_jacobian(cam, np.where(front[:, None], Xc, np.array([0.0, 0.0, 1.0])))
        e1, e2 = _tangent_basis(n)
        # Columns: d r / d(left twist of T) = the observation rows (a, Xc x a) at the current
        # points; d r / d(normal along e1, e2) = (a^T R X) * (-(X . e) / d); then the
        # brightness model (-I_key, -1).
        J = np.empty((len(r), 10))
        J[:, :6] = observation_rows(Xc, gx, gy, cam.fx, cam.fy, D, inverse_depth=iz).T
        a1, a2, a3 = J[:, 0], J[:, 1], J[:, 2]
        aRX = a1 * (Xc[:, 0] - t[0]) + a2 * (Xc[:, 1] - t[1]) + a3 * (Xc[:, 2] - t[2])
        aRX /= -d
        J[:, 6] = aRX * (X @ e1)
        J[:, 7] = aRX * (X @ e2)
        J[:, 8] = -I_key
        J[:, 9] = -1.0
        rv = r[valid]
        wv, scale = robust_weights(rv.astype(np.float32), opts.robust, huber_k=opts.huber_k,
                                   tukey_c=opts.tukey_c)
        Jv = J[valid]
        Jw = Jv * (wv[:, None] / scale ** 2)
        H = Jw.T @ Jv
        g = Jw.T @ rv
        # prior on the normal, in the tangent coordinates of the current n
        dn = n - n0
        H[6, 6] += inv_s2
        H[7, 7] += inv_s2
        g[6] += inv_s2 * (dn @ e1)
        g[7] += inv_s2 * (dn @ e2)
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        T = se3_exp(step[:6]) @ T
        n = n + step[6] * e1 + step[7] * e2
        n /= np.linalg.norm(n)
        gain += step[8]
        bias += step[9]
        if np.max(np.abs(step[:8])) < 1e-9:
            break
    return T, Plane(n, d), gain, bias
