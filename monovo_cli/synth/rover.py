"""The scene of a rover drive over terrain (``monovo synth --terrain``, ``--preset mer``).

A rover (wheelbase ``ROVER_WHEELBASE``, track ``ROVER_TRACK``) follows a planar path; its
body lies on the plane fitted to the ground under its four wheels (the base ground: the
rover straddles rocks rather than climbing them) and bobs on its suspension; the camera sits
on a mast at a fixed mounting on the body. The rover knows only that mounting: the nominal
ground plane of ``init.yaml`` is the body's plane (wheel contacts) seen from the mounting,
not the true local ground under the camera at frame 0, which differs by the bobbing (at a
crest at frame 0) and by the terrain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.synth.motion import (
    MER_FOV_DEG,
    MER_PITCH_DEG,
    TERRAIN_PITCH_DEG,
    bobbing,
    camera_mount,
    drive_path,
    mer_path,
    rover_poses,
)
from monovo_cli.synth.terrain import Terrain, make_terrain

MER_SIZE = (1024, 1024)
MER_FRAMES = 100
ROCK_MARGIN = 25.0  # m: rocks lie within this distance of the path's bounding box
HEIGHTS_MARGIN = 10.0  # m: terrain.npz's height grid around the path's bounding box
DRIVE_BOB_PERIODS = (15.0, 60.0)  # frames (5 cm apart)
MER_BOB_PERIODS = (2.0, 6.0)  # frames (~70 cm apart)


def fov_camera(width: int, height: int, fov_deg: float) -> PinholeCamera:
    """A camera with ``fov_deg`` horizontal field of view, square pixels, centred."""
    f = 0.5 * width / math.tan(math.radians(0.5 * fov_deg))
    return PinholeCamera(width=int(width), height=int(height), fx=f, fy=f,
                         cx=(width - 1) / 2.0, cy=(height - 1) / 2.0)


def mer_camera(width: int, height: int) -> PinholeCamera:
    """The MER Navcam's geometry at ``width x height``: 45 deg horizontal field of view."""
    return fov_camera(width, height, MER_FOV_DEG)


@dataclass(frozen=True)
class RoverScene:
    """One drive: ``poses`` ``g_from_cam_k``; ``path`` (n, 3) rover centre x, y (m) and
    heading (rad); ``turning`` (n,) bool, frame reached by a turn in place (MER) or None;
    ``bob`` (n, 3) height (m), pitch, roll (rad); ``mount`` ``body_from_cam``; the terrain,
    the box ``(x0, y0, x1, y1)`` (m) of its height grid, the sun's azimuth (rad)."""

    poses: list[np.ndarray]
    path: np.ndarray
    turning: np.ndarray | None
    bob: np.ndarray
    mount: np.ndarray
    terrain: Terrain
    heights_bounds: tuple[float, float, float, float]
    sun_azimuth: float


def _box(path: np.ndarray, margin: float) -> tuple[float, float, float, float]:
    return (float(path[:, 0].min() - margin), float(path[:, 1].min() - margin),
            float(path[:, 0].max() + margin), float(path[:, 1].max() + margin))


def rover_scene(preset: str, terrain: str, frames: int, *, motion_rng: np.random.Generator,
                terrain_rng: np.random.Generator, bob_rng: np.random.Generator,
                peak_step: float, origin: tuple[float, float],
                crest: float | None = None) -> RoverScene:
    """The drive of ``preset`` (``drive``: ~5 cm steps, smooth turns, camera pitched
    TERRAIN_PITCH_DEG; ``mer``: MER stop-and-go steps, MER_PITCH_DEG) over ``terrain`` (one
    of TERRAINS), starting at ``origin`` (m), frame 0's bob as :func:`bobbing` has it for
    ``crest``; deterministic in the generators."""
    if preset == "mer":
        path, turning = mer_path(frames, motion_rng, origin)
        periods = MER_BOB_PERIODS
    else:
        path = drive_path(frames, motion_rng, peak_step=peak_step, origin=origin)
        turning, periods = None, DRIVE_BOB_PERIODS
    ground = make_terrain(terrain, terrain_rng, _box(path, ROCK_MARGIN))
    sun_azimuth = float(terrain_rng.uniform(0.0, 2.0 * math.pi))
    bob = bobbing(frames, bob_rng, periods, crest)
    mount = rover_mount(preset)
    poses = rover_poses(path, ground.base_height, bob, mount)
    return RoverScene(poses, path, turning, bob, mount, ground, _box(path, HEIGHTS_MARGIN),
                      sun_azimuth)


def rover_mount(preset: str) -> np.ndarray:
    """``body_from_cam`` of ``preset``'s rover (``mer`` or ``drive``): the camera on the mast."""
    return camera_mount(MER_PITCH_DEG if preset == "mer" else TERRAIN_PITCH_DEG)
