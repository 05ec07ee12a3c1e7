"""Hindsight for lost frames: the correction a closing frame measured, shared out among the
predicted motions before it (docs/algorithm.md section 8, "Re-solving the gap").

A run of lost frames carries the prediction from the last good frame ``g``: motions
``m_1 .. m_n`` to the lost frames and ``m_{n+1}`` to the closing frame ``r``, each with the
covariance ``C_k`` its row states (:class:`~monovo_cli.core.recovery.gap.GapClosure`). ``r``
was measured directly, at ``B`` from ``g``. The corrected motions ``m_k exp(delta_k)`` are the
smallest, in the metric of the ``C_k``, that compose to ``B``: with ``S_k = m_{k+1} .. m_{n+1}``
a perturbation of ``m_k`` reaches ``r`` as ``Ad(S_k^-1) delta_k`` (to first order), so for the
closing error ``e = log((m_1 .. m_{n+1})^-1 B)``

    delta_k = C_k J_k^T (sum_j J_j C_j J_j^T)^-1 e,     J_k = Ad(S_k^-1),

a Kalman smoother's correction of a random walk, iterated a few times for corrections
beyond first order. The motions the prediction was least sure of take the most: a heading
the prediction missed turns the gap into an arc, and the frames right after ``g``, whose
prediction had barely begun to drift, move little. motion.csv stays causal; only the
trajectory written at the end (trajectory.csv, .tum) takes these poses.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.geometry.lie import adjoint, orthonormalize, se3_exp, se3_inv, se3_log

ITERATIONS = 5  # Gauss-Newton steps of the constrained least squares (first order: one)
MIN_VARIANCE = 1e-12  # floor of a predicted motion's variances (m^2, rad^2)


def close_gaps(index: Sequence[int], world_from_cam: np.ndarray,
               closures: Sequence[tuple[int, GapClosure]]) -> np.ndarray:
    """(N, 4, 4): ``world_from_cam`` (N, 4, 4, T_0_k of frames ``index``, in order) with the
    lost frames before each closing frame moved as the module docstring says.

    ``closures``: ``(closing frame index, its GapClosure)``. A closure whose last good frame
    is not among ``index``, or whose variances do not count one motion per frame from it to
    the closing frame, is left alone.
    """
    W = np.array(world_from_cam, dtype=float)
    row = {int(k): i for i, k in enumerate(index)}
    for frame, c in closures:
        r, g = row.get(int(frame)), row.get(int(c.last_good))
        if r is None or g is None or r - g < 2 or np.shape(c.variances) != (r - g, 6):
            continue
        g_from_world = se3_inv(W[g])
        path = [g_from_world @ W[j] for j in range(g + 1, r)] + [g_from_world @ c.predicted]
        motions = [path[0]] + [se3_inv(a) @ b for a, b in zip(path[:-1], path[1:])]
        motions = shared_out(motions, g_from_world @ W[r], np.asarray(c.variances, float))
        T = W[g]
        for j, m in zip(range(g + 1, r), motions):
            T = T @ m
            W[j] = orthonormalize(T)
    return W


def shared_out(motions: Sequence[np.ndarray], end: np.ndarray, variances: np.ndarray
               ) -> list[np.ndarray]:
    """The motions (4, 4 each) corrected so that they compose to ``end`` (4, 4), each by the
    least its covariance ``diag(variances[k])`` (variances (K, 6)) allows (module
    docstring)."""
    m = [np.array(x, dtype=float) for x in motions]
    C = [np.diag(np.maximum(v, MIN_VARIANCE)) for v in variances]
    for _ in range(ITERATIONS):
        total = np.eye(4)
        for x in m:
            total = total @ x
        e = se3_log(se3_inv(total) @ end)
        if np.max(np.abs(e)) < 1e-12:
            break
        J, suffix = [None] * len(m), np.eye(4)
        for k in range(len(m) - 1, -1, -1):
            J[k] = adjoint(se3_inv(suffix))
            suffix = m[k] @ suffix
        M = sum(Jk @ Ck @ Jk.T for Jk, Ck in zip(J, C))
        y = np.linalg.solve(M, e)
        m = [x @ se3_exp(Ck @ Jk.T @ y) for x, Jk, Ck in zip(m, J, C)]
    return m
