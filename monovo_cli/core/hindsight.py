"""Hindsight for what a run writes at its end: the keyframe planes smoothed over the whole
drive, and the poses re-scaled with them.

Every keyframe's plane is the MAP of what was known when it was anchored
(:mod:`monovo_cli.core.plane_belief`): the plane carried from the previous keyframe, the
images' normal and the mounting prior. The planes of the first keyframes are the least
certain, and frame 0's is init.yaml's: when the camera was at a crest of its suspension,
the first keyframes' scale is off by the crest's height over the distance. The backward pass
of the Rauch-Tung-Striebel smoother (:func:`~monovo_cli.core.plane_belief.smoothed_corrections`,
with the gains and innovations each re-anchor left in its
:class:`~monovo_cli.core.plane_belief.PlaneLink`) gives each keyframe's plane with the
knowledge of the keyframes after it.

The images fix a motion against a plane only as ``t / d`` (the plane-induced homography
``R + t n^T / d``): the motions of a keyframe's segment, measured against its plane at
distance ``d``, are re-read against its smoothed plane at ``d'`` by scaling their
translations by ``d' / d``, rotations unchanged. That is exact for a plane without relief
and a change of distance; the smoothed tilt's effect on the motions (first order in the
tilt correction times the translation) is left out. Each keyframe's pose is its
predecessor's re-scaled pose composed with the re-scaled motion between the two, and every
frame's pose its keyframe's composed with its own re-scaled motion from it, so the
trajectory stays one rigid chain.

``motion.csv`` is written as frames are done and stays causal; trajectory.csv, .tum and the
terrain products (:mod:`monovo_cli.core.terrain_map`) are written with these poses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from monovo_cli.core.plane_belief import PlaneLink, from_chart, smoothed_corrections
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.geometry.plane import Plane


class Anchored(Protocol):
    """What hindsight needs of a keyframe (a :class:`~monovo_cli.core.keyframe.Keyframe`
    or a record of one): its pose, its plane (its camera) and its plane's link."""

    world_from_key: np.ndarray
    plane: Plane
    link: PlaneLink | None


@dataclass(frozen=True)
class KeyRecord:
    """The :class:`Anchored` part of a keyframe, without its images and points."""

    world_from_key: np.ndarray
    plane: Plane
    link: PlaneLink | None


def smoothed_planes(keys: Sequence[Anchored]) -> list[Plane]:
    """Each keyframe's plane (its camera) smoothed over the chain, ``keys`` oldest first."""
    delta = smoothed_corrections([k.link for k in keys])
    return [k.plane if not np.any(x) else from_chart(k.plane, x) for k, x in zip(keys, delta)]


def smoothed_key_poses(keys: Sequence[Anchored], planes: Sequence[Plane]) -> np.ndarray:
    """(K, 4, 4) the keyframes' poses re-scaled with their smoothed ``planes``: the first
    keeps its pose, each next one is its predecessor's composed with the motion between the
    two, its translation scaled by the predecessor's ``d' / d``."""
    out = np.empty((len(keys), 4, 4))
    for a, key in enumerate(keys):
        if a == 0:
            out[a] = key.world_from_key
            continue
        prev = keys[a - 1]
        step = se3_inv(prev.world_from_key) @ key.world_from_key
        step[:3, 3] *= planes[a - 1].distance / prev.plane.distance
        out[a] = out[a - 1] @ step
    return out


def smoothed_poses(index: Sequence[int], world_from_cam: np.ndarray,
                   keys: Sequence[tuple[int, Anchored]]) -> np.ndarray:
    """(N, 4, 4) the poses ``world_from_cam`` (N, 4, 4) of frames ``index`` (N,), in order,
    re-scaled with the smoothed planes of ``keys`` (``(frame index, keyframe)``, oldest
    first): each frame's motion from the latest keyframe at or before it scaled by that
    keyframe's ``d' / d``. Frames before the first keyframe keep their poses."""
    W = np.asarray(world_from_cam, dtype=float)
    if not keys:
        return W.copy()
    at = np.array([i for i, _ in keys])
    anchored = [k for _, k in keys]
    planes = smoothed_planes(anchored)
    key_poses = smoothed_key_poses(anchored, planes)
    seg = np.searchsorted(at, np.asarray(index), side="right") - 1
    out = W.copy()
    for a, key in enumerate(anchored):
        rows = np.flatnonzero(seg == a)
        if not len(rows):
            continue
        rel = np.einsum("ij,njk->nik", se3_inv(key.world_from_key), W[rows])
        rel[:, :3, 3] *= planes[a].distance / key.plane.distance
        out[rows] = np.einsum("ij,njk->nik", key_poses[a], rel)
    return out


class Hindsight:
    """The keyframes of a run as they come (:meth:`add`, a rebuilt keyframe replacing the
    one of its index), for :meth:`poses` at the end (module docstring)."""

    def __init__(self) -> None:
        self._keys: dict[int, KeyRecord] = {}

    def add(self, index: int, key: Anchored) -> None:
        self._keys[int(index)] = KeyRecord(np.array(key.world_from_key), key.plane, key.link)

    def poses(self, index: Sequence[int], world_from_cam: np.ndarray) -> np.ndarray:
        """:func:`smoothed_poses` of the frames ``index`` over the keyframes added so far."""
        return smoothed_poses(index, world_from_cam, sorted(self._keys.items()))
