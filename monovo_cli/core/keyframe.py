"""A keyframe: the paper's ground model (section 10.2.5) anchored on one frame.

:func:`build_keyframe` picks the observation points of every pyramid level of a frame inside
the ground rectangle, log_ratios them onto the plane and precomputes their observation rows
(:class:`~monovo_cli.core.estimator.estimate.KeyLevel`); :func:`point_budget` says how many points the
finest level gets, :func:`footprint` how much of an image the model still covers.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import cv2
import numpy as np

from monovo_cli.core.aliases import ground_periods
from monovo_cli.core.estimator.estimate import KeyLevel
from monovo_cli.core.estimator.ground import (
    default_threshold,
    in_front,
    rectangle_corners,
    require_points,
    select_points,
)
from monovo_cli.core.estimator.terrain_grid import TerrainGrid
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import estimate_noise_sigma
from monovo_cli.image.pyramid import build_pyramid, num_levels


@dataclass(frozen=True)
class Keyframe:
    """A ground model anchored on one frame: plane and points in that frame's camera.

    ``index`` the frame's index; ``world_from_key`` (4x4) its pose (world: camera 0's);
    ``plane`` the ground in its camera; ``corners`` (4, 3) the model rectangle there (m);
    ``levels`` the observation points per pyramid level, finest first; ``noise_sigma`` the
    frame's noise and ``threshold`` the gradient threshold its points passed (grey levels).
    """

    index: int
    world_from_key: np.ndarray
    plane: Plane
    corners: np.ndarray
    levels: tuple[KeyLevel, ...]
    noise_sigma: float
    threshold: float
    terrain_grid: TerrainGrid | None = None  # the points' heights off the plane (None: on it)
    link: PlaneLink | None = None  # how its plane corrected the one carried from the last keyframe
    periods: np.ndarray | None = None  # (K, 3) its texture's periods along the plane (aliases)

    @property
    def periodic(self) -> bool:
        """Its texture repeats: it has :attr:`periods`."""
        return self.periods is not None and len(self.periods) > 0


def build_keyframe(index: int, image: np.ndarray, camera: PinholeCamera, plane: Plane,
                   region: tuple[int, int, int, int], world_from_key: np.ndarray,
                   options: TrackOptions, *, mask: np.ndarray | None = None,
                   pyramid: list[np.ndarray] | None = None,
                   surface: Callable[[np.ndarray], TerrainGrid] | None = None) -> Keyframe:
    """The ground model of section 10.2.5 on ``image`` (H, W) float32, plane in its camera.

    ``surface``, given the finest level's points (N, 3) on the plane, returns the keyframe's
    terrain grid (:mod:`monovo_cli.core.estimator.terrain_grid`): every level's points are then
    lifted onto it.

    Raises TrackingError when the frame has too few observation points.
    """
    n_levels = options.levels or num_levels(camera.width, camera.height)
    pyr = pyramid if pyramid is not None and len(pyramid) >= n_levels \
        else build_pyramid(image, n_levels)
    sigma = estimate_noise_sigma(image)
    threshold = options.threshold if options.threshold is not None else default_threshold(sigma)
    corners = rectangle_corners(camera, plane, region)
    budget = point_budget(options, camera)
    coarse = min(budget, _one_point_per(options.coarse_pixels_per_point, camera))
    spline = options.estimator.interpolation != "linear"
    if not in_front(corners):
        raise TrackingError("the ground plane is not in front of the camera over the region")
    levels = []
    m = mask
    terrain_grid = None
    for lv in range(n_levels):
        cam = camera.scaled(lv)
        if lv > 0 and m is not None:
            m = cv2.resize(m.astype(np.uint8), (cam.width, cam.height),
                           interpolation=cv2.INTER_NEAREST).astype(bool)
        pts = select_points(pyr[lv], cam, plane, corners, level=lv, threshold=threshold,
                            max_points=max((budget if lv == 0 else coarse) // (4 ** lv), 200),
                            mask=m, spline=lv == 0 and spline)
        if lv == 0:
            textured = None
            if len(pts) < options.min_points:  # would any threshold give enough?
                textured = len(select_points(pyr[lv], cam, plane, corners, level=lv,
                                             threshold=0.0, max_points=options.min_points,
                                             mask=m))
            require_points(pts, minimum=options.min_points, threshold=threshold,
                           textured=textured)
            if surface is not None:
                terrain_grid = surface(pts.X)
        if terrain_grid is not None:
            pts = replace(pts, X=terrain_grid.lift(pts.X))
        levels.append(KeyLevel.from_points(pts))
    # Coarse levels with too few points cannot constrain 6 DoF: drop them.
    while len(levels) > 1 and len(levels[-1].points) < 30:
        levels.pop()
    return Keyframe(index, np.array(world_from_key), plane, corners, tuple(levels), sigma,
                    threshold, terrain_grid, periods=ground_periods(pyr, camera, plane, corners))


def _one_point_per(pixels: int, camera: PinholeCamera) -> int:
    """One point per ``pixels`` pixels of the image, at least 2000."""
    return int(max(2000, camera.width * camera.height // pixels))


def point_budget(options: TrackOptions, camera: PinholeCamera) -> int:
    """Observation points at full resolution: ``max_points`` or one per ``pixels_per_point`` px."""
    if options.max_points is not None:
        return int(options.max_points)
    return _one_point_per(options.pixels_per_point, camera)


def footprint(camera: PinholeCamera, corners_cur: np.ndarray) -> float:
    """Share of the image covered by the model rectangle (4, 3) given in the current camera."""
    if np.any(corners_cur[:, 2] <= 1e-6):
        return 0.0
    poly = camera.project(corners_cur).astype(np.float32)
    img = np.array([[0, 0], [camera.width, 0], [camera.width, camera.height], [0, camera.height]],
                   np.float32)
    area, _ = cv2.intersectConvexConvex(poly, img)
    return float(area) / (camera.width * camera.height)


def mask_keyframe(key: Keyframe, camera: PinholeCamera, usable: np.ndarray, *,
                  min_points: int) -> Keyframe:
    """``key`` without the observation points on unusable pixels: ``usable`` (H, W) bool at
    full resolution, resized to each level as :func:`build_keyframe` does (a model built
    before the mask was known, e.g. ``monovo init`` without ``--mask``).

    Raises TrackingError when fewer than ``min_points`` full-resolution points are left.
    """
    levels = []
    m = np.asarray(usable, bool)
    for lv, kl in enumerate(key.levels):
        cam = camera.scaled(lv)
        if lv > 0:
            m = cv2.resize(m.astype(np.uint8), (cam.width, cam.height),
                           interpolation=cv2.INTER_NEAREST).astype(bool)
        p = kl.points
        x = np.clip(np.rint(p.uv[:, 0]).astype(int), 0, cam.width - 1)
        y = np.clip(np.rint(p.uv[:, 1]).astype(int), 0, cam.height - 1)
        keep = m[y, x]
        pts = replace(p, uv=p.uv[keep], X=p.X[keep], intensity=p.intensity[keep],
                      grad=p.grad[keep])
        if lv == 0:
            require_points(pts, minimum=min_points, threshold=key.threshold)
        levels.append(KeyLevel.from_points(pts))
    while len(levels) > 1 and len(levels[-1].points) < 30:
        levels.pop()
    return replace(key, levels=tuple(levels))
