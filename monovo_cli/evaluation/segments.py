"""Errors by travelled distance, the KITTI odometry benchmark's way (Geiger et al. 2012).

For every first pose i (every ``step``-th matched pose; the devkit steps by 10 frames, 1 s
of KITTI's 10 Hz) and every segment length L, the last pose j is the first after i whose
true path length from i exceeds L (the devkit's ``lastFrameFromSegmentLength``: the
distance along the ground truth, summed pose to pose, strictly greater than
``dist[i] + L``); segments running past the end are skipped. The segment's error is the
relative pose error of the two relative motions ``E = inv(inv(P_i) P_j) inv(G_i) G_j``
(P the estimate, G the truth):
translation error ``|t(E)| / L`` (a fraction: x100 for %), rotation error
``angle(R(E)) / L`` (rad/m; x180/pi for deg/m), the angle taken as
``acos(clip((trace(R) - 1) / 2, -1, 1))``. The averages are over every (i, L) pair pooled,
and per length.

Pure: arrays in, numbers out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from monovo_cli.geometry.lie import se3_inv

DEFAULT_SEGMENTS = (1.0, 5.0, 10.0)  # m: a rover's short drives (KITTI's are 100..800 m)
DEFAULT_STEP = 1  # every matched pose starts segments (a rover's frames are few and slow)


@dataclass(frozen=True)
class SegmentErrors:
    """One row per (first pose, length) pair: ``first``, ``last`` (M,) indices into the
    matched poses, ``length`` (M,) L m, ``translation`` (M,) ``|t_err| / L`` (fraction),
    ``rotation`` (M,) ``angle(R_err) / L`` rad/m; ``lengths`` the lengths asked for."""

    first: np.ndarray
    last: np.ndarray
    length: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray
    lengths: tuple[float, ...]
    step: int = DEFAULT_STEP

    def summary(self) -> dict:
        """Plain numbers for JSON and the report: the pooled means (``translation_pct``,
        ``rotation_deg_per_m``, ``segments``) and per length (``by_length``: each length's
        ``length_m``, ``segments``, ``translation_pct``, ``rotation_deg_per_m``; None where no
        segment of that length fits in the drive)."""
        def means(sel: np.ndarray) -> dict:
            n = int(sel.sum())
            return {"segments": n,
                    "translation_pct": float(100.0 * self.translation[sel].mean()) if n else None,
                    "rotation_deg_per_m":
                        float(math.degrees(self.rotation[sel].mean())) if n else None}

        return {"step_poses": self.step, **means(np.ones(len(self.length), bool)),
                "by_length": [{"length_m": float(L), **means(self.length == L)}
                              for L in self.lengths]}


def distances(world_from_cam: np.ndarray) -> np.ndarray:
    """The path length (N,) m from the first pose to each pose of (N, 4, 4), summed pose to
    pose (the devkit's ``trajectoryDistances``)."""
    p = np.asarray(world_from_cam)[:, :3, 3]
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]


def rotation_angle(R: np.ndarray) -> float:
    """The angle (rad) of the rotation (3, 3), ``acos`` of ``(trace - 1) / 2`` clipped."""
    return math.acos(max(-1.0, min(1.0, 0.5 * (float(np.trace(R)) - 1.0))))


def segment_errors(est_world_from_cam: np.ndarray, gt_world_from_cam: np.ndarray,
                   lengths: Sequence[float] = DEFAULT_SEGMENTS, *,
                   step: int = DEFAULT_STEP) -> SegmentErrors:
    """The KITTI-style errors (module docstring) of matched poses ``est``, ``gt`` (N, 4, 4)
    over segments of ``lengths`` m, first poses every ``step``-th."""
    est, gt = np.asarray(est_world_from_cam, float), np.asarray(gt_world_from_cam, float)
    if step < 1:
        raise ValueError(f"step: expected a whole number >= 1, got {step}")
    lengths = tuple(float(L) for L in lengths)
    if not lengths or min(lengths) <= 0:
        raise ValueError(f"lengths: expected positive lengths, got {lengths}")
    dist = distances(gt)
    rows = []
    for i in range(0, len(gt), step):
        for L in lengths:
            j = int(np.searchsorted(dist, dist[i] + L, side="right"))  # first dist > d_i + L
            if j >= len(dist):
                continue
            E = se3_inv(se3_inv(est[i]) @ est[j]) @ (se3_inv(gt[i]) @ gt[j])
            rows.append((i, j, L, np.linalg.norm(E[:3, 3]) / L, rotation_angle(E[:3, :3]) / L))
    a = np.array(rows, dtype=float).reshape(-1, 5)
    return SegmentErrors(a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2], a[:, 3], a[:, 4],
                         lengths, step)
