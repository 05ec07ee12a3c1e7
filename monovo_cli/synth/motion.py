"""Camera motions of the synthetic sequences: a rover drive and the paper's pairs.
"""

from __future__ import annotations

import math

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, pose_from_vectors, so3_exp
from monovo_cli.synth.render import REGION_MIN_DEPRESSION_DEG, _corner_depressions

DRIVE_MAST_HEIGHT = 1.5  # m
DRIVE_PITCH_DEG = 45.0  # optical axis below the horizontal
DRIVE_STEP = 0.05  # m/frame, nominal forward speed (varies +-30 %)
DRIVE_SPEED_VARIATION = 0.3
DRIVE_MAX_YAW_RATE_DEG = 1.0  # per frame
DRIVE_WOBBLE_DEG = 1.0  # roll and pitch of the rover body
DRIVE_HEIGHT_WOBBLE = 0.02  # m

PAIR_DISTANCE = 100.0  # m, camera 0 to the plane
PAIR_TILT_DEG = 25.0  # optical axis off the plane normal
PAIR_EXTRA_TILT_DEG = 5.0  # random extra tilt per axis (about camera x and y)
PAIR_MAX_TRANSLATION = 10.0  # m per axis
PAIR_MAX_DRAWS = 1000


# --------------------------------------------------------------------------- motion


def _smooth(rng: np.random.Generator, n: int, periods: tuple[float, float], *, count: int = 3,
            zero_start: bool = False) -> np.ndarray:
    """A smooth random signal in [-1, 1] over frames 0..n-1 (sum of sinusoids)."""
    k = np.arange(n, dtype=float)
    omega = 2.0 * np.pi / rng.uniform(periods[0], periods[1], count)
    amp = rng.uniform(0.5, 1.0, count)
    amp /= amp.sum()
    if zero_start:  # exactly 0 at frame 0, random sign per component
        amp *= rng.choice([-1.0, 1.0], count)
        phase = np.zeros(count)
    else:
        phase = rng.uniform(0.0, 2.0 * np.pi, count)
    return (amp[None, :] * np.sin(omega[None, :] * k[:, None] + phase[None, :])).sum(axis=1)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def body_from_camera(pitch_rad: float) -> np.ndarray:
    """Rotation of a camera pitched down by ``pitch_rad`` in a body frame (x forward, y left,
    z up). Columns are the camera axes: x right, y down, z along the optical axis."""
    c, s = math.cos(pitch_rad), math.sin(pitch_rad)
    x_cam = np.array([0.0, -1.0, 0.0])
    z_cam = np.array([c, 0.0, -s])
    y_cam = np.cross(z_cam, x_cam)
    return np.column_stack([x_cam, y_cam, z_cam])


def drive_poses(n_frames: int, rng: np.random.Generator, *, peak_step: float,
                origin: tuple[float, float] = (0.0, 0.0)) -> list[np.ndarray]:
    """``g_from_cam_k`` of a rover drive: mast camera (1.5 m, pitched 45 deg down) moving
    forward ``peak_step / 1.3 * (1 +- 0.3)`` m per frame with a smooth yaw rate of up to
    1 deg/frame about the ground normal, +-1 deg roll/pitch and +-2 cm height wobble.
    Frame 0 is exactly on the nominal mast pose."""
    speed = (peak_step / (1.0 + DRIVE_SPEED_VARIATION)) * (
        1.0 + DRIVE_SPEED_VARIATION * _smooth(rng, n_frames, (40.0, 250.0)))
    bias = rng.uniform(-1.0, 1.0)
    yaw_rate = math.radians(DRIVE_MAX_YAW_RATE_DEG) * (
        0.4 * bias + 0.6 * _smooth(rng, n_frames, (60.0, 400.0)))
    roll = math.radians(DRIVE_WOBBLE_DEG) * _smooth(rng, n_frames, (15.0, 60.0), zero_start=True)
    pitch = math.radians(DRIVE_WOBBLE_DEG) * _smooth(rng, n_frames, (15.0, 60.0),
                                                     zero_start=True)
    height = DRIVE_MAST_HEIGHT + DRIVE_HEIGHT_WOBBLE * _smooth(rng, n_frames, (20.0, 80.0),
                                                               zero_start=True)
    heading = rng.uniform(0.0, 2.0 * np.pi)
    R_body_cam = body_from_camera(math.radians(DRIVE_PITCH_DEG))
    pos = np.array(origin, dtype=float)
    poses = []
    for k in range(n_frames):
        if k > 0:
            mid = heading + 0.5 * yaw_rate[k]
            pos = pos + speed[k] * np.array([math.cos(mid), math.sin(mid)])
            heading += yaw_rate[k]
        R = _rot_z(heading) @ _rot_y(pitch[k]) @ _rot_x(roll[k]) @ R_body_cam
        poses.append(make_pose(R, np.array([pos[0], pos[1], height[k]])))
    return poses


def pair_poses(cam: PinholeCamera, rng: np.random.Generator, *, max_translation: float,
               max_rotation_deg: float, origin: tuple[float, float] = (0.0, 0.0),
               min_depression_deg: float = REGION_MIN_DEPRESSION_DEG,
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(g_from_cam_0, g_from_cam_1)`` of one pair: camera 0 100 m from the plane with its
    optical axis 25 deg (+- 5 deg about camera x and y) off the normal, random azimuth;
    ``T_0_1`` with rotation vector and translation uniform per axis in
    ``+-max_rotation_deg`` / ``+-max_translation``, redrawn until frame 1 sees only ground."""
    extra = np.radians(rng.uniform(-PAIR_EXTRA_TILT_DEG, PAIR_EXTRA_TILT_DEG, 2))
    R_extra = so3_exp(np.array([extra[0], extra[1], 0.0]))
    azimuth = rng.uniform(0.0, 2.0 * np.pi)
    R0 = _rot_z(azimuth) @ body_from_camera(math.radians(90.0 - PAIR_TILT_DEG)) @ R_extra.T
    g0 = make_pose(R0, np.array([origin[0], origin[1], PAIR_DISTANCE]))
    margin = math.radians(min_depression_deg)
    for _ in range(PAIR_MAX_DRAWS):
        t = rng.uniform(-max_translation, max_translation, 3)
        r = np.radians(rng.uniform(-max_rotation_deg, max_rotation_deg, 3))
        g1 = g0 @ pose_from_vectors(t, r)
        if g1[2, 3] > 0.05 * PAIR_DISTANCE and np.all(_corner_depressions(cam, g1) >= margin):
            return g0, g1
    raise InputError(f"max_rotation_deg {max_rotation_deg:g}, max_translation {max_translation:g}: "
                     "motions this large keep showing the horizon in frame 1")
