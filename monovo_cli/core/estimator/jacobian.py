"""Derivatives of the projection: the observation rows of the estimator and the plane fit.

Linearisation (our derivation, docs/algorithm.md section 2; it replaces eqs. 10.5-10.12,
which carry a lost sign in the projection derivative, eq. 10.6, and a C_X where C_Y belongs,
eq. 10.9). For the
projection u = fx X/Z + cx, v = fy Y/Z + cy:

    d(u, v)/dX = [[fx/Z, 0, -fx X/Z^2],
                  [0, fy/Z, -fy Y/Z^2]]                      (eq. 10.6, corrected sign)

and for a small rigid motion exp(xi^) with xi = (v, w):  d(exp(xi^) X)/d xi = [I | -[X]x].
The observation row (the paper's o, eq. 10.12) is o = g^T d(u,v)/dX [I | -[X]x], i.e. with
a = (gx fx/Z, gy fy/Z, -(gx fx X + gy fy Y)/Z^2):

    o = (a1, a2, a3,  a3 Y - a2 Z,  a1 Z - a3 X,  a2 X - a1 Y).

:func:`observation_rows` gives them for any points and image gradients (the estimator's
constant O at the keyframe's points, the plane fit's rows at the current points);
:func:`distortion_jacobian` replaces diag(fx, fy) for a camera with lens distortion;
:func:`project_in_front` gives the pixels of camera-frame points (NaN behind the camera).
"""

from __future__ import annotations

import numpy as np


def observation_rows(X: np.ndarray, gx: np.ndarray, gy: np.ndarray, fx: float, fy: float,
                     distortion_jacobian: np.ndarray | None = None,
                     inverse_depth: np.ndarray | None = None) -> np.ndarray:
    """The observation rows o_i as columns (6, N): d(intensity)/d(twist) at points ``X`` (N, 3).

    The derivative of the intensity at the projection of ``exp(xi^) X`` with respect to the
    twist ``xi = (v, w)`` at 0 (grey levels per metre / per radian), for image gradients
    ``gx``, ``gy`` (N,) in grey levels per pixel at the projections. ``distortion_jacobian``
    (N, 2, 2) is d(pixel)/d(normalised coordinates) of a distorted camera; without it the
    camera is a pinhole, d(pixel)/d(normalised) = diag(fx, fy). ``inverse_depth`` (N,) is
    1 / Z (default), or 0 where a caller masks points behind the camera. Rows 0..2 are the
    vector ``a`` of the module docstring.
    """
    x, y, z = np.ascontiguousarray(X.T)
    given = [a for a in (distortion_jacobian, inverse_depth) if a is not None]
    out = np.empty((6, len(X)), np.result_type(X, gx, gy, *given))  # (np.stack's type)
    a1, a2, a3, r4, r5, r6 = out
    iz = 1.0 / z if inverse_depth is None else inverse_depth
    # In place, the same operations as a = (gx fx iz, gy fy iz, -(a1 x + a2 y) iz) and the
    # rotation rows a x X: a keyframe's finest level is 10^5 points, and a fresh temporary
    # of that size a step cost more than the step.
    D = distortion_jacobian
    g_type = np.result_type(gx, gy, *(() if D is None else (D,)))  # that of (gx, gy) fx or D
    if D is None:
        np.multiply(gx, fx, out=a1)  # (computed in gx's type, as gx * fx is)
        np.multiply(gy, fy, out=a2)
    else:
        a1[:], a2[:] = gx * D[:, 0, 0] + gy * D[:, 1, 0], gx * D[:, 0, 1] + gy * D[:, 1, 1]
    if np.result_type(g_type, iz) == out.dtype:
        a1 *= iz
        a2 *= iz
    else:  # inverse depths narrower than the points: the products in their own type
        a1[:], a2[:] = a1.astype(g_type) * iz, a2.astype(g_type) * iz
    tmp = a2 * y
    np.multiply(a1, x, out=a3)
    a3 += tmp
    a3 *= iz
    np.negative(a3, out=a3)
    np.multiply(a3, y, out=r4)
    r4 -= np.multiply(a2, z, out=tmp)
    np.multiply(a1, z, out=r5)
    r5 -= np.multiply(a3, x, out=tmp)
    np.multiply(a2, x, out=r6)
    r6 -= np.multiply(a1, y, out=tmp)
    return out


def observation_matrix(X: np.ndarray, grad: np.ndarray, fx: float, fy: float,
                       distortion_jacobian: np.ndarray | None = None) -> np.ndarray:
    """The rows o_i (N, 6) of the observation matrix O at points ``X`` (N, 3) with gradients
    ``grad`` (N, 2) (grey levels per px), a view of :func:`observation_rows`' (6, N)."""
    g = grad.astype(np.float64)
    return observation_rows(np.asarray(X, dtype=np.float64), g[:, 0], g[:, 1], fx, fy,
                            distortion_jacobian).T


def distortion_jacobian(camera, X: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """d(pixel)/d(normalised coordinates) (N, 2, 2) of ``camera`` at points ``X`` (N, 3)."""
    xn, yn = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    J = np.empty((len(X), 2, 2))
    for j, (dx, dy) in enumerate(((eps, 0.0), (0.0, eps))):
        up = camera.distort_normalized(xn + dx, yn + dy)
        dn = camera.distort_normalized(xn - dx, yn - dy)
        J[:, 0, j] = camera.fx * (up[0] - dn[0]) / (2 * eps)
        J[:, 1, j] = camera.fy * (up[1] - dn[1]) / (2 * eps)
    return J


def project_in_front(cam, Xc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels (u, v) (N,) float64 of camera-frame points ``Xc`` (N, 3), NaN for points not in
    front of the camera, and that in-front mask (N,) bool."""
    z = Xc[:, 2]
    in_front = z > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        if cam.has_distortion:
            uv = cam.project(np.where(in_front[:, None], Xc, np.nan))
            return uv[:, 0], uv[:, 1], in_front
        iz = np.where(in_front, 1.0 / z, np.nan)
    u = Xc[:, 0] * iz
    u *= cam.fx
    u += cam.cx
    v = Xc[:, 1] * iz
    v *= cam.fy
    v += cam.cy
    return u, v, in_front
