"""What a re-anchoring frame measures for the keyframe it anchors: its pose refined with the
old keyframe's terrain grid (the old keyframe's finest points lifted to the heights found),
and the new keyframe's plane (:meth:`PlaneTracker.successor`). docs/algorithm.md section 4
gives the re-anchoring rules.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate
from monovo_cli.core.estimator.terrain_grid import TerrainGrid, refine_pose_and_terrain_grid
from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.core.plane.motion_covariance import MotionCovariance
from monovo_cli.core.plane.tracker import PlaneTracker
from monovo_cli.geometry.lie import orthonormalize
from monovo_cli.geometry.plane import Plane


@dataclass(frozen=True)
class Successor:
    """The keyframe a frame anchors, as measured on it: ``est`` the frame's estimate (its pose
    refined with the terrain grid where there is one), ``plane`` the new keyframe's plane in
    the frame's camera, ``covariance`` its chart covariance (3, 3; None: the prior's),
    ``gain``/``bias`` the brightness, ``link`` the plane's link to the old keyframe's,
    ``terrain_grid`` the old keyframe's grid solved with the pose (None: none), ``rebuilt``
    the old keyframe with its finest points at the heights found (None: not rebuilt)."""

    est: Estimate
    plane: Plane
    covariance: np.ndarray | None
    gain: float
    bias: float
    link: PlaneLink | None
    terrain_grid: TerrainGrid | None = None
    rebuilt: Keyframe | None = None


def successor(key: Keyframe, pyr: list[np.ndarray], est: Estimate, tracker: PlaneTracker,
              motion_cov: MotionCovariance, options: TrackOptions, recovering: bool, *,
              anchoring: bool = True) -> Successor:
    """The keyframe the frame (``pyr``, ``est`` against ``key``) anchors: its terrain grid
    solved with the pose (``TrackOptions.terrain_grid``), then its plane; the pose keeps the
    fixed-plane estimate, whose error is smaller (the free normal adds variance to the joint
    solution's motion). ``recovering``: the frame follows lost frames, its plane's tilt is
    loosened (:meth:`PlaneTracker.loosened`). Not ``anchoring`` (a frame that anchors
    nothing, or a recovering tracker's frame on its own keyframe): ``est`` as it is and
    ``key``'s plane carried to it, its brightness the fit's."""
    if not anchoring:
        plane = key.plane.in_frame(orthonormalize(est.cur_from_key))
        return Successor(est, plane, None, est.gain, est.bias, None)
    terrain_grid, rebuilt = None, None
    if options.terrain_grid:
        est, terrain_grid, lifted = refine_pose_and_terrain_grid(
            key.levels[0], key.plane, pyr[0], est, options.estimator, start=key.terrain_grid)
        if lifted is None:
            terrain_grid = None
        else:  # the keyframe's finest points at the heights found
            rebuilt = replace(key, levels=(lifted,) + key.levels[1:], terrain_grid=terrain_grid)
    plane, cov, gain, bias, link = tracker.successor(
        key, pyr[0], est, orthonormalize(est.cur_from_key), est.gain, est.bias, options.estimator,
        motion_cov.sensitivity(est, key.levels[0], key.plane), motion_cov.noise_factor_of(key.levels[0]))
    if recovering and cov is not None:
        cov = tracker.loosened(cov)
    return Successor(est, plane, cov, gain, bias, link, terrain_grid, rebuilt)
