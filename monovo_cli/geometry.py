"""Rigid-body geometry: SO(3)/SE(3) exponential and logarithm, quaternions, pinhole camera.

Conventions (SPEC): camera axes x right, y down, z forward; a pose ``b_from_a`` is a
4x4 matrix ``[R | t]`` mapping a point expressed in frame a to frame b,
``X_b = R X_a + t``. A twist ``xi = (v, w)`` (translation part first, as the paper's
``B = (dTx, dTy, dTz, dwx, dwy, dwz)``) is exponentiated to ``T = exp(xi^)``.
Angles are radians here; degrees exist only at the interfaces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

_EPS = 1e-12


def skew(w: np.ndarray) -> np.ndarray:
    """The 3x3 cross-product matrix ``[w]x`` with ``[w]x @ a == cross(w, a)``."""
    wx, wy, wz = w
    return np.array([[0.0, -wz, wy], [wz, 0.0, -wx], [-wy, wx, 0.0]])


def _exp_coefficients(theta2: float) -> tuple[float, float, float]:
    """A = sin(t)/t, B = (1 - cos(t))/t^2, C = (t - sin(t))/t^3 at t^2 = ``theta2``: exp of a
    rotation vector w is I + A W + B W^2 and its left Jacobian I + B W + C W^2 (W = [w]x)."""
    if theta2 < 1e-16:
        return 1.0, 0.5, 1.0 / 6.0
    theta = math.sqrt(theta2)
    sin_t = math.sin(theta)
    return sin_t / theta, (1.0 - math.cos(theta)) / theta2, (theta - sin_t) / (theta2 * theta)


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (3,), radians (Rodrigues)."""
    w = np.asarray(w, dtype=float)
    a, b, _ = _exp_coefficients(float(w @ w))
    W = skew(w)
    return np.eye(3) + a * W + b * W @ W


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), radians, of the rotation matrix ``R``; angle in [0, pi]."""
    R = np.asarray(R, dtype=float)
    cos_t = np.clip((np.trace(R) - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(cos_t)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-6:
        return 0.5 * v * (1.0 + theta * theta / 6.0)
    if np.pi - theta > 1e-4:
        return v * (theta / (2.0 * np.sin(theta)))
    # Near pi: take the axis from the symmetric part, sign from v.
    B = 0.5 * (R + np.eye(3))
    axis = np.sqrt(np.clip(np.diag(B), 0.0, None))
    i = int(np.argmax(axis))
    axis = B[i] / axis[i]
    axis /= np.linalg.norm(axis)
    if axis @ v < 0:
        axis = -axis
    return axis * theta


def _so3_left_jacobian(w: np.ndarray) -> np.ndarray:
    _, b, c = _exp_coefficients(float(w @ w))
    W = skew(w)
    return np.eye(3) + b * W + c * W @ W


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """4x4 rigid transform ``exp(xi^)`` of the twist ``xi = (v, w)`` (6,), metres and radians:
    ``so3_exp(w)`` and ``_so3_left_jacobian(w) @ v``, sharing W and W^2."""
    xi = np.asarray(xi, dtype=float)
    v, w = xi[:3], xi[3:]
    a, b, c = _exp_coefficients(float(w @ w))
    W = skew(w)
    W2 = W @ W
    T = np.eye(4)
    T[:3, :3] += a * W + b * W2
    T[:3, 3] = v + b * (W @ v) + c * (W2 @ v)
    return T


def se3_log(T: np.ndarray) -> np.ndarray:
    """Twist ``xi = (v, w)`` (6,) with ``se3_exp(xi) == T``."""
    w = so3_log(T[:3, :3])
    v = np.linalg.solve(_so3_left_jacobian(w), T[:3, 3])
    return np.concatenate([v, w])


def se3_inv(T: np.ndarray) -> np.ndarray:
    """Inverse of a 4x4 rigid transform: ``a_from_b`` from ``b_from_a``."""
    Ti = np.eye(4)
    R = T[:3, :3]
    Ti[:3, :3] = R.T
    Ti[:3, 3] = -R.T @ T[:3, 3]
    return Ti


def orthonormalize(T: np.ndarray) -> np.ndarray:
    """The rigid transform nearest to ``T`` (4x4): its rotation block projected onto SO(3) by SVD.

    Chained products of poses lose orthonormality to rounding; left alone, the error compounds
    through the constant-velocity prediction.
    """
    U, _, Vt = np.linalg.svd(T[:3, :3])
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] = -U[:, -1]
        R = U @ Vt
    out = np.eye(4)
    out[:3, :3] = R
    out[:3, 3] = T[:3, 3]
    return out


def make_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 transform from a 3x3 rotation and a translation (3,)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def pose_from_vectors(t: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    """4x4 transform ``[so3_exp(rotvec) | t]`` (translation m, rotation vector rad)."""
    return make_pose(so3_exp(rotvec), np.asarray(t, dtype=float))


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(qx, qy, qz, qw)`` with ``qw >= 0`` of a rotation matrix."""
    R = np.asarray(R, dtype=float)
    tr = np.trace(R)
    if tr > 0:
        s = np.sqrt(tr + 1.0) * 2.0
        q = np.array([(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s,
                      (R[1, 0] - R[0, 1]) / s, 0.25 * s])
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2.0
        q = np.array([0.25 * s, (R[0, 1] + R[1, 0]) / s,
                      (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s])
    elif R[1, 1] > R[2, 2]:
        s = np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2.0
        q = np.array([(R[0, 1] + R[1, 0]) / s, 0.25 * s,
                      (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s])
    else:
        s = np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2.0
        q = np.array([(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s,
                      0.25 * s, (R[1, 0] - R[0, 1]) / s])
    q /= np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    return q


def matrix_from_quat(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion ``(qx, qy, qz, qw)`` (normalised here)."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole camera with optional OpenCV distortion ``(k1, k2, p1, p2[, k3])``.

    Pixel centres are integers, the top-left pixel's centre is (0, 0).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = field(default=(0.0, 0.0, 0.0, 0.0, 0.0))

    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def has_distortion(self) -> bool:
        return any(abs(c) > 0.0 for c in self.distortion)

    def scaled(self, level: int) -> PinholeCamera:
        """The camera of pyramid level ``level`` (each level halves the image, cv2.pyrDown).

        cv2.pyrDown smooths, then keeps the even rows and columns: pixel j of level l sits
        at pixel ``j * 2**l`` of level 0, so ``x_l = x_0 / 2**l`` (no half-pixel shift).
        """
        w, h = self.width, self.height
        for _ in range(level):
            w, h = (w + 1) // 2, (h + 1) // 2
        s = 0.5 ** level
        return replace(self, width=w, height=h, fx=self.fx * s, fy=self.fy * s,
                       cx=self.cx * s, cy=self.cy * s)

    def project(self, X: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of camera-frame points ``X`` (N, 3), metres; z must be > 0."""
        X = np.asarray(X)
        z = X[:, 2]
        xn, yn = X[:, 0] / z, X[:, 1] / z
        if self.has_distortion:
            xn, yn = self.distort_normalized(xn, yn)
        return np.stack([self.fx * xn + self.cx, self.fy * yn + self.cy], axis=1)

    def distort_normalized(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply the OpenCV radial-tangential model to normalised coordinates."""
        k1, k2, p1, p2, *rest = (tuple(self.distortion) + (0.0,) * 5)[:5]
        k3 = rest[0]
        r2 = xn * xn + yn * yn
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
        return xd, yd

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """Viewing rays (N, 3) with z = 1 through pixels ``uv`` (N, 2), distortion removed."""
        uv = np.asarray(uv, dtype=float)
        if self.has_distortion:
            import cv2

            dist = np.asarray(self.distortion, dtype=float)
            pts = cv2.undistortPoints(
                uv.reshape(-1, 1, 2), self.K, dist,
                criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12),
            ).reshape(-1, 2)
            return np.concatenate([pts, np.ones((len(pts), 1))], axis=1)
        out = np.empty((len(uv), 3))
        out[:, 0] = (uv[:, 0] - self.cx) / self.fx
        out[:, 1] = (uv[:, 1] - self.cy) / self.fy
        out[:, 2] = 1.0
        return out
