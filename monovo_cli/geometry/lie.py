"""SO(3) and SE(3): exp/log maps, inverses, poses from vectors, quaternions (TUM order).

Poses are plain 4x4 arrays named by the frames they join (``b_from_a``); rotation vectors are
axis * angle in radians.
"""

from __future__ import annotations

import math

import numpy as np


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
    half = math.sin(0.5 * theta) / (0.5 * theta)
    b = 0.5 * half * half  # (1 - cos t) / t^2 without the cancellation of 1 - cos t
    if theta2 < 1e-2:  # t - sin t cancels: its series, truncation below 3e-17 relative
        c = 1.0 / 6.0 - theta2 * (1.0 / 120.0 - theta2 * (1.0 / 5040.0 - theta2 / 362880.0))
    else:
        c = (theta - sin_t) / (theta2 * theta)
    return sin_t / theta, b, c


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (3,), radians (Rodrigues)."""
    w = np.asarray(w, dtype=float)
    a, b, _ = _exp_coefficients(float(w @ w))
    W = skew(w)
    return np.eye(3) + a * W + b * W @ W


def so3_exp_rows(w: np.ndarray) -> np.ndarray:
    """(n, 3, 3): :func:`so3_exp` of every rotation vector of ``w`` (n, 3) at once (Rodrigues;
    below 1e-4 rad the coefficients' series)."""
    t2 = np.einsum("ni,ni->n", w, w)
    small = t2 < 1e-8
    t = np.sqrt(np.where(small, 1.0, t2))
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(t) / t)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(t)) / np.where(small, 1.0, t2))
    W = np.zeros((len(w), 3, 3))
    W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    W[:, 1, 0], W[:, 2, 0], W[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return np.eye(3) + a[:, None, None] * W + b[:, None, None] * (W @ W)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (3,), radians, of the rotation matrix ``R``; angle in [0, pi]."""
    R = np.asarray(R, dtype=float)
    cos_t = np.clip((np.trace(R) - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(cos_t)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-6:
        return 0.5 * v * (1.0 + theta * theta / 6.0)
    if np.pi - theta > 1e-2:
        return v * (theta / (2.0 * np.sin(theta)))
    # Near pi v ~ 2 sin(theta) loses its digits: the axis from the symmetric part,
    # (R + R^T) / 2 - cos(theta) I = (1 - cos(theta)) a a^T, its sign from v, and the
    # angle from both sin and cos.
    B = 0.5 * (R + R.T) - cos_t * np.eye(3)
    i = int(np.argmax(np.diag(B)))
    axis = B[i] / np.linalg.norm(B[i])
    if axis @ v < 0:
        axis = -axis
    return axis * np.arctan2(0.5 * abs(axis @ v), cos_t)


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


def motion_change(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(6,) (m, rad): motion ``a`` (4x4) less motion ``b`` in (tx, ty, tz, rx, ry, rz), the
    rotation as the rotation vector of ``a_R b_R^T``."""
    return np.concatenate([a[:3, 3] - b[:3, 3], so3_log(a[:3, :3] @ b[:3, :3].T)])


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


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint of a 4x4 pose for twists ordered (v, w)."""
    R, t = T[:3, :3], T[:3, 3]
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[:3, 3:] = skew(t) @ R
    A[3:, 3:] = R
    return A


def output_covariance(cov_xi: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Covariance of (t, rotvec) of ``pose`` from that of its left-perturbation twist (6, 6)."""
    A = np.eye(6)
    A[:3, 3:] = -skew(pose[:3, 3])
    return A @ cov_xi @ A.T


def motion_covariance_of_key_twist(cov_xi: np.ndarray, prev_from_key: np.ndarray,
                      prev_from_cur: np.ndarray) -> np.ndarray:
    """Covariance (6, 6) of (t, rotvec) of the motion ``prev_from_cur = prev_from_key @
    key_from_cur`` (4x4 each) from that of the twist ``xi`` of ``key_from_cur`` (``cov_xi``,
    ``key_from_cur_true = exp(xi^) key_from_cur``): the motion's left twist is
    ``Ad(prev_from_key) xi``."""
    A = adjoint(prev_from_key)
    return output_covariance(A @ cov_xi @ A.T, prev_from_cur)
