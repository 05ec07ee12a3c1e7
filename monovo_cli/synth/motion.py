"""Camera motions of the synthetic sequences: a rover drive, the paper's pairs, rover drives
over terrain (smooth or MER-like stop-and-go paths, wheels on the ground, suspension bobbing).
"""

from __future__ import annotations

import math

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, pose_from_vectors, so3_exp
from monovo_cli.synth.render import REGION_MIN_DEPRESSION_DEG, corner_depressions

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


def smooth(rng: np.random.Generator, n: int, periods: tuple[float, float], *, count: int = 3,
           zero_start: bool = False) -> np.ndarray:
    """(n,) a smooth random signal in [-1, 1] over frames 0..n-1: ``count`` sinusoids with
    periods (frames) drawn from ``periods`` and weights summing to 1, exactly 0 at frame 0
    with ``zero_start``. Deterministic in ``rng``."""
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
        1.0 + DRIVE_SPEED_VARIATION * smooth(rng, n_frames, (40.0, 250.0)))
    bias = rng.uniform(-1.0, 1.0)
    yaw_rate = math.radians(DRIVE_MAX_YAW_RATE_DEG) * (
        0.4 * bias + 0.6 * smooth(rng, n_frames, (60.0, 400.0)))
    roll = math.radians(DRIVE_WOBBLE_DEG) * smooth(rng, n_frames, (15.0, 60.0), zero_start=True)
    pitch = math.radians(DRIVE_WOBBLE_DEG) * smooth(rng, n_frames, (15.0, 60.0),
                                                    zero_start=True)
    height = DRIVE_MAST_HEIGHT + DRIVE_HEIGHT_WOBBLE * smooth(rng, n_frames, (20.0, 80.0),
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
        if g1[2, 3] > 0.05 * PAIR_DISTANCE and np.all(corner_depressions(cam, g1) >= margin):
            return g0, g1
    raise InputError(f"max_rotation_deg {max_rotation_deg:g}, max_translation {max_translation:g}: "
                     "motions this large keep showing the horizon in frame 1")


# --------------------------------------------------------------------------- rover drives over terrain

TERRAIN_PITCH_DEG = 40.0  # camera pitch of the terrain drives (benchmarks/terrain.py)
ROVER_WHEELBASE = 1.4  # m, front to rear wheel contacts (a MER-sized rover)
ROVER_TRACK = 1.2  # m, left to right wheel contacts
ROVER_MAST_FORWARD = 0.4  # m, the mast ahead of the rover's centre (the turning centre)
BOB_HEIGHT = 0.02  # m, suspension bobbing of the body
BOB_TILT_DEG = 2.0  # pitch and roll bobbing of the body

# MER visual odometry: a frame every ~75 cm of driving or ~18 deg of turn (Maimone et al., 2007)
MER_STEP = (0.6, 0.75)  # m of driving between frames
MER_TURN_DEG = (12.0, 18.0)  # turn in place between frames
MER_ARC_DEG = 3.0  # heading change per driving step, at most (the runs are arcs)
MER_RUN = (3, 8)  # driving steps between turns
MER_TURNS = (1, 3)  # turn frames in a row
MER_PITCH_DEG = 45.0
MER_FOV_DEG = 45.0  # horizontal field of view of the Navcam


def drive_path(n_frames: int, rng: np.random.Generator, *, peak_step: float,
               origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """``(n, 3)`` rover centre ``x, y`` (m, in G) and heading (rad from G's x axis) of a
    smooth drive: the speed and turns of :func:`drive_poses`, without the body's wobble."""
    speed = (peak_step / (1.0 + DRIVE_SPEED_VARIATION)) * (
        1.0 + DRIVE_SPEED_VARIATION * smooth(rng, n_frames, (40.0, 250.0)))
    bias = rng.uniform(-1.0, 1.0)
    yaw_rate = math.radians(DRIVE_MAX_YAW_RATE_DEG) * (
        0.4 * bias + 0.6 * smooth(rng, n_frames, (60.0, 400.0)))
    heading = rng.uniform(0.0, 2.0 * np.pi)
    pos = np.array(origin, dtype=float)
    path = np.zeros((n_frames, 3))
    for k in range(n_frames):
        if k > 0:
            mid = heading + 0.5 * yaw_rate[k]
            pos = pos + speed[k] * np.array([math.cos(mid), math.sin(mid)])
            heading += yaw_rate[k]
        path[k] = pos[0], pos[1], heading
    return path


def mer_path(n_frames: int, rng: np.random.Generator,
             origin: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A MER-like stop-and-go drive: runs of ``MER_RUN`` steps of ``MER_STEP`` m (arcs
    turning up to ``MER_ARC_DEG`` per step) and turns in place of ``MER_TURN_DEG`` per frame.

    Returns ``(n, 3)`` rover centre ``x, y`` (m) and heading (rad), and ``(n,)`` bool:
    frame k was reached by turning in place (else by driving; frame 0: False)."""
    heading = rng.uniform(0.0, 2.0 * np.pi)
    pos = np.array(origin, dtype=float)
    path, turning = [(pos[0], pos[1], heading)], [False]
    while len(path) < n_frames:
        arc = math.radians(rng.uniform(-MER_ARC_DEG, MER_ARC_DEG))
        for _ in range(int(rng.integers(MER_RUN[0], MER_RUN[1] + 1))):
            mid = heading + 0.5 * arc
            pos = pos + rng.uniform(*MER_STEP) * np.array([math.cos(mid), math.sin(mid)])
            heading += arc
            path.append((pos[0], pos[1], heading))
            turning.append(False)
        sign = rng.choice([-1.0, 1.0])
        for _ in range(int(rng.integers(MER_TURNS[0], MER_TURNS[1] + 1))):
            heading += sign * math.radians(rng.uniform(*MER_TURN_DEG))
            path.append((pos[0], pos[1], heading))
            turning.append(True)
    return np.array(path[:n_frames]), np.array(turning[:n_frames])


def _phased(rng: np.random.Generator, n: int, periods: tuple[float, float], phase: float,
            count: int = 3) -> np.ndarray:
    """A smooth random signal in [-1, 1] over frames 0..n-1 worth ``cos(phase)`` at frame 0
    (every component shifted by ``phase``, rad)."""
    k = np.arange(n, dtype=float)
    omega = 2.0 * np.pi / rng.uniform(periods[0], periods[1], count)
    amp = rng.uniform(0.5, 1.0, count)
    amp /= amp.sum()
    return (amp[None, :] * np.cos(omega[None, :] * k[:, None] - phase)).sum(axis=1)


def _crest(rng: np.random.Generator, n: int, periods: tuple[float, float], count: int = 3
           ) -> np.ndarray:
    """A smooth random signal in [-1, 1] over frames 0..n-1 at a crest (+1 or -1) at frame 0."""
    signal = _phased(rng, n, periods, 0.0, count)
    return rng.choice([-1.0, 1.0]) * signal


def bobbing(n_frames: int, rng: np.random.Generator, periods: tuple[float, float],
            crest: float | None = None) -> np.ndarray:
    """``(n, 3)`` suspension bobbing of the body per frame: height (m, +-BOB_HEIGHT), pitch
    and roll (rad, +-BOB_TILT_DEG); periods in frames. Frame 0 is at a crest of all three,
    as far from the mean as the bobbing goes; with ``crest`` (m, within +-BOB_HEIGHT), frame
    0's height is ``crest`` and its pitch and roll are at their means (0), the signs of their
    slopes drawn."""
    tilt = math.radians(BOB_TILT_DEG)
    if crest is None:
        return np.column_stack([BOB_HEIGHT * _crest(rng, n_frames, periods),
                                tilt * _crest(rng, n_frames, periods),
                                tilt * _crest(rng, n_frames, periods)])
    rising = rng.choice([-1.0, 1.0], 3)
    height = math.acos(float(np.clip(crest / BOB_HEIGHT, -1.0, 1.0)))
    return np.column_stack([BOB_HEIGHT * _phased(rng, n_frames, periods, rising[0] * height),
                            tilt * _phased(rng, n_frames, periods, rising[1] * 0.5 * np.pi),
                            tilt * _phased(rng, n_frames, periods, rising[2] * 0.5 * np.pi)])


def camera_mount(pitch_deg: float, mast_height: float = DRIVE_MAST_HEIGHT,
                 forward: float = ROVER_MAST_FORWARD) -> np.ndarray:
    """``body_from_cam`` (4x4): the camera ``forward`` m ahead of the rover's centre,
    ``mast_height`` m above its ground plane, pitched ``pitch_deg`` down."""
    return make_pose(body_from_camera(math.radians(pitch_deg)),
                     np.array([forward, 0.0, mast_height]))


def body_on_ground(path: np.ndarray, height_at) -> list[np.ndarray]:
    """``g_from_body`` (4x4) per frame: the plane fitted (least squares) to the ground under
    the four wheel contacts (wheelbase ROVER_WHEELBASE, track ROVER_TRACK) of the rover at
    ``path`` (n, 3); body x = the heading in that plane, z = its normal (up), origin on the
    plane under the rover's centre. ``height_at(x, y)`` (arrays, m) gives the ground."""
    s = 0.5 * ROVER_WHEELBASE * np.array([1.0, 1.0, -1.0, -1.0])
    q = 0.5 * ROVER_TRACK * np.array([1.0, -1.0, 1.0, -1.0])
    fit = np.linalg.pinv(np.column_stack([np.ones(4), s, q]))  # z = c0 + c1 s + c2 q
    poses = []
    for x, y, h in path:
        f = np.array([math.cos(h), math.sin(h)])
        left = np.array([-f[1], f[0]])
        wheels = np.array([x, y])[None, :] + s[:, None] * f[None, :] + q[:, None] * left[None, :]
        c0, c1, c2 = fit @ height_at(wheels[:, 0], wheels[:, 1])
        grad = c1 * f + c2 * left
        z = np.array([-grad[0], -grad[1], 1.0]) / math.hypot(grad[0], grad[1], 1.0)
        fwd = np.array([f[0], f[1], 0.0])
        xb = fwd - (fwd @ z) * z
        xb /= np.linalg.norm(xb)
        poses.append(make_pose(np.column_stack([xb, np.cross(z, xb), z]), np.array([x, y, c0])))
    return poses


def rover_poses(path: np.ndarray, height_at, bob: np.ndarray, mount: np.ndarray
                ) -> list[np.ndarray]:
    """``g_from_cam_k``: the body on the ground under the wheels (:func:`body_on_ground`),
    bobbing by ``bob`` (n, 3) (height along the body's z, pitch about its y, roll about its
    x, about its origin), the camera at ``mount`` (``body_from_cam``) on it."""
    return [g_from_body @ bobbed_mount(b, mount)
            for g_from_body, b in zip(body_on_ground(path, height_at), bob)]


def bobbed_mount(bob: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """(4, 4) the camera's pose in the frame of the ground under the wheels: the body bobbing
    by ``bob`` (3,) (height, pitch, roll; :func:`rover_poses`), the camera at ``mount``."""
    return make_pose(_rot_y(bob[1]) @ _rot_x(bob[2]), np.array([0.0, 0.0, bob[0]])) @ mount
