"""The scenario soak (issue 40): hundreds of drives drawn at random from a wide box, each
tracked by ``monovo track`` as a user would run it, each held to the same invariants.

    python -m benchmarks.soak --scenarios 500 --seed 40 [--workers N]
    python -m benchmarks.soak --seed 40 --only 137 --keep /tmp/x     # replay one scenario
    python -m benchmarks.soak --scenarios 500 --write-docs           # + the table in docs/benchmarks.md

Every scenario is fully determined by ``(--seed, index)`` (``--tiny``: the test slice's small
ones, tests/benchmarks/test_soak.py), rendered with monovo_cli.synth's pieces into a sequence
folder of the SPEC layout (frames/, init.yaml, groundtruth_motion.csv, groundtruth.tum) and
tracked by ``python -m monovo_cli track SEQ -o OUT --threads 1 --skip-bad-frames -q`` in a
subprocess (frames are PNGs; corrupt frames are part of the box, hence
``--skip-bad-frames``, which records them as lost).

The box (each parameter drawn per scenario):

* size 128x128 .. 1024x1024 (mostly 128-384; 512 at 8 %, 768 and 1024 at 7 % together),
  square or 4:3; 12-30 frames (12-24 at 512, 12-16 above: 500 scenarios in about an hour on
  one core of a two-core machine that others load to 6);
* a camera of 60 deg (synth's default) or 45 deg (the Navcam's) field of view, 0.5-3 m above
  the ground (0.8-2.5 m over terrain), pitched 35-90 deg down (35-70 over terrain), up to
  0.3 heights ahead of the rover's turning centre;
* motion: ``smooth`` (speed and yaw rate varying slowly), ``mer`` (stop-and-go runs and
  turns in place of 5-25 deg), ``zigzag`` (a yaw rate of 0.5-8 deg/frame changing sign every
  frame), ``spin`` (turns in place of 2-25 deg/frame, sometimes reversing), ``standing``;
  steps, in camera heights per frame: 0.005-0.05 (35 %), 0.05-0.2 (25 %), 0.2-0.5 (25 %;
  MER's 0.75 m at 1.5 m is 0.5), 0.5-1.0 (15 %, past the capture range; a car's 1.5 m at
  1.65 m is 0.9);
* the body bobbing on its suspension (height up to 1.5 % of the camera height, pitch and roll
  up to 2 deg, one to three periods of 2-60 frames, random phase: frame 0 is off the mean
  mount), and in 12 % of the scenarios a jerking camera (independent pitch and roll of
  1-4 deg std per frame, half of that in yaw);
* ground: flat (40 %), rolling, slope or a rock field (monovo_cli.synth.terrain, rendered by
  ray casting; synth's ray caster marches rays that graze the ground for kilometres, so over
  terrain the pitch is raised in 5 deg steps until the horizon of the mean ground stays
  HORIZON_DEG above every frame, recorded in synth.yaml as ``pitch_deg_rendered``); the
  rover straddles the rocks (its body on the plane under its wheels over the base ground)
  or, in 30 % of the rock fields, climbs them (the wheels on the rocks: the camera jerks
  when a wheel meets one);
* texture: synth's procedural one, gravel, a low texture (the procedural one blurred by 3-8
  texels, 10-30 % of its contrast), a checkerboard (4-32 texel squares, a repetitive
  texture), or a photo-like natural texture synthesised here (a dead-leaves image of discs
  with power-law radii over 1/f noise, the statistics of natural images: no photograph is
  used);
* photometry: noise variance 1-40 (log-uniform); a lighting ramp (gain 1 +- 0.1..0.4 and bias
  +-25 grey levels over the drive, 20 %); a shadow that moves (a soft-edged half plane
  darkening by 25-60 %, its edge sweeping across the image, 15 %); 1-2 blank frames (10 %);
  1-2 corrupt frames (truncated PNG, garbage bytes or an empty file, 10 %); 1-3 dropped frames
  (the file is missing: the ground truth is the motion between the files present, 15 %);
  init.yaml as frame 0's true ground (the plane under the wheels seen from camera 0, 70 %)
  or the nominal mount declared as such (``ground.nominal``, 30 %).

Classes, the first that applies (the drift bound in brackets):

* ``beyond`` [10 %]: steps past the capture range (> 0.5 heights), a jerking camera, or a
  rover climbing rocks;
* ``large-motion`` [10 %]: steps of 0.2-0.5 heights, turns in place or zigzags of 5 deg per
  frame or more, or dropped frames;
* ``photometric`` [10 %]: a lighting ramp, a moving shadow, blank or corrupt frames, low
  texture or the checkerboard;
* ``terrain`` [5 %]: rolling, slope or rocks;
* ``flat`` [2 %]: the rest.

The invariants, per scenario:

* ``exit``: monovo exits 0 or 3 (more than half of the frames lost), never 1 or 2, and
  prints no traceback;
* ``untrusted``: no row more than 5 cm or 1 deg off the true motion (norm of the
  translation / rotation-vector error) whose reported std does not cover its error within 4x
  on every axis, counted as ../shared/tools/integrity.py counts them (every status; a blank
  std covers nothing); the failure line says how many of them were written ``ok`` or
  ``reanchored``;
* ``msd``: no ``ok`` or ``reanchored`` row with an msd above 10 x max(the median msd of the
  run's ``ok``/``reanchored`` rows, 2 x noise variance + 1): the difference of two noisy images
  has a variance of twice the noise's, the +1 covers rounding and interpolation, and a row
  ten times beyond both the noise and its own drive's level has converged to something the
  model does not explain;
* ``drift``: for a run that exits 0, the end-point error of trajectory.tum against
  groundtruth.tum is within the class's bound x the true path length + 1 % of the camera
  height (the floor keeps a standing camera's millimetres from counting as a percentage of
  nothing);
* ``threads``: on every tenth scenario (index divisible by 10), ``--threads 2`` writes the
  same bytes of motion.csv and trajectory.csv as ``--threads 1``.

Honesty: z = error / reported std per axis over the ``ok`` and ``reanchored`` rows that
have a std (../shared/tools/honesty.py's z), pooled per class and over all scenarios;
std(z) is printed per axis (1 = honest, target 0.5-2).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from benchmarks.common import final_drift, machine, one_core
from monovo_cli.geometry.lie import make_pose, se3_inv, so3_exp
from monovo_cli.io.formats import read_tum
from monovo_cli.synth.gravel import gravel_texture
from monovo_cli.synth.motion import bobbed_mount, body_on_ground, camera_mount, smooth
from monovo_cli.synth.raycast import TerrainRenderer
from monovo_cli.synth.render import (
    GroundRenderer,
    default_camera,
    finish_frame,
    grid,
    ground_region,
    pixel_size_on_plane,
    plane_homography,
)
from monovo_cli.synth.rover import ROCK_MARGIN, fov_camera
from monovo_cli.synth.sequence_files import write_png, write_sequence
from monovo_cli.synth.terrain import make_terrain
from monovo_cli.synth.texture import TEXTURE_MEAN, TEXTURE_STD, GroundTexture, procedural_texture

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "benchmarks.md"
BEGIN, END = "<!-- soak:begin -->", "<!-- soak:end -->"

AXES = ("tx", "ty", "tz", "rx", "ry", "rz")
OFF_M, OFF_DEG, COVER = 0.05, 1.0, 4.0  # ../shared/tools/integrity.py's defaults
MSD_FACTOR = 10.0
DRIFT_FLOOR = 0.01  # camera heights
THREAD_EVERY = 10
CAPTURE = 0.5  # camera heights per frame: MER's 0.75 m at 1.5 m
HORIZON_DEG = 3.0  # over terrain, every frame's border dips at least this below the mean ground
CLASSES = ("flat", "terrain", "photometric", "large-motion", "beyond")
DRIFT_PCT = {"flat": 2.0, "terrain": 5.0, "photometric": 10.0, "large-motion": 10.0, "beyond": 10.0}
SIZES = (128, 160, 192, 224, 256, 320, 384, 512, 768, 1024)
SIZE_WEIGHTS = (0.14, 0.12, 0.14, 0.12, 0.14, 0.10, 0.09, 0.08, 0.05, 0.02)
TEXTURES = ("procedural", "gravel", "photo", "low", "checker")
MODES = ("smooth", "mer", "zigzag", "spin", "standing")


# --------------------------------------------------------------------------- the box


@dataclass(frozen=True)
class Scenario:
    """One drive of the box, fully determined by ``(seed, index, tiny)``."""

    seed: int
    index: int
    tiny: bool
    width: int
    height: int
    frames: int
    fov: str  # "wide" (synth's default camera) or "navcam" (45 deg)
    cam_height: float  # m above the ground plane under the wheels
    pitch_deg: float
    forward: float  # m, camera ahead of the turning centre
    mode: str
    step: float  # camera heights per frame (driving frames)
    yaw_deg: float  # deg per frame: the mode's yaw rate or turn
    bob_height: float  # m
    bob_tilt_deg: float
    bob_periods: tuple[float, ...]
    jerk_deg: float  # std of the per-frame pitch and roll jerk (0: none)
    ground: str  # flat, rolling, slope, rocks
    climb: bool  # the wheels climb the rocks instead of straddling them
    texture: str
    noise_var: float
    ramp: tuple[float, float] | None  # (gain change, bias change) over the drive
    shadow: tuple[float, float, float, float] | None  # (darkening, angle, sweep, edge px)
    blank: tuple[int, ...]
    corrupt: tuple[tuple[int, str], ...]
    dropped: tuple[int, ...]
    nominal: bool  # init.yaml holds the nominal mount (declared), not frame 0's ground

    @property
    def klass(self) -> str:
        """The scenario's class (module docstring)."""
        if self.step > CAPTURE and self.mode in ("smooth", "mer", "zigzag") or self.jerk_deg > 0 \
                or self.climb:
            return "beyond"
        moving = self.mode in ("smooth", "mer", "zigzag")
        if (moving and self.step >= 0.2) or self.dropped or (
                self.mode in ("mer", "zigzag", "spin") and self.yaw_deg >= 5.0):
            return "large-motion"
        if (self.ramp or self.shadow or self.blank or self.corrupt
                or self.texture in ("low", "checker")):
            return "photometric"
        if self.ground != "flat":
            return "terrain"
        return "flat"

    def describe(self) -> str:
        """One line: what was drawn."""
        parts = [f"{self.width}x{self.height}", f"{self.frames} fr", self.fov,
                 f"h {self.cam_height:.2f} m", f"pitch {self.pitch_deg:.0f}", self.mode]
        if self.mode in ("smooth", "mer", "zigzag"):
            parts.append(f"step {self.step:.2f} h ({self.step * self.cam_height:.2f} m)")
        if self.mode != "standing":
            parts.append(f"yaw {self.yaw_deg:.1f} deg")
        parts.append(f"bob {self.bob_tilt_deg:.1f} deg/{self.bob_height * 100:.1f} cm "
                     f"periods {','.join(f'{p:.0f}' for p in self.bob_periods)}")
        if self.jerk_deg:
            parts.append(f"jerk {self.jerk_deg:.1f} deg")
        parts.append(self.ground + (" climbing" if self.climb else ""))
        parts.append(self.texture)
        parts.append(f"noise {self.noise_var:.1f}")
        if self.ramp:
            parts.append("ramp")
        if self.shadow:
            parts.append("moving shadow")
        if self.blank:
            parts.append(f"blank {list(self.blank)}")
        if self.corrupt:
            parts.append(f"corrupt {[k for k, _ in self.corrupt]}")
        if self.dropped:
            parts.append(f"dropped {list(self.dropped)}")
        parts.append("init nominal" if self.nominal else "init frame 0")
        return ", ".join(parts)

    def replay(self) -> str:
        """The command that replays this scenario alone and keeps its files."""
        tiny = " --tiny" if self.tiny else ""
        return (f"python -m benchmarks.soak --seed {self.seed} --only {self.index}{tiny} "
                f"--keep /tmp/soak_{self.seed}_{self.index}")


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw(seed: int, index: int, *, tiny: bool = False) -> Scenario:
    """Scenario ``index`` of the soak seeded ``seed`` (``tiny``: 96-160 px, 8-15 frames)."""
    rng = np.random.default_rng([int(seed), int(index), int(tiny)])
    if tiny:
        width = int(rng.integers(12, 21)) * 8
        frames = int(rng.integers(8, 16))
    else:
        width = int(rng.choice(SIZES, p=SIZE_WEIGHTS))
        frames = int(rng.integers(12, 31 if width <= 384 else 25 if width <= 512 else 17))
    height = width if tiny or rng.random() < 0.7 else int(round(0.75 * width / 8)) * 8
    ground = str(rng.choice(["flat", "rolling", "slope", "rocks"], p=[0.4, 0.2, 0.15, 0.25]))
    fov = "wide" if rng.random() < 0.7 else "navcam"
    flat = ground == "flat"
    cam_height = float(rng.uniform(0.5, 3.0) if flat else rng.uniform(0.8, 2.5))
    pitch = float(rng.uniform(35.0, 90.0) if flat else rng.uniform(35.0, 70.0))
    forward = float(rng.uniform(0.0, 0.3) * cam_height)
    mode = str(rng.choice(MODES, p=[0.4, 0.2, 0.2, 0.1, 0.1]))
    band = int(rng.choice(4, p=[0.35, 0.25, 0.25, 0.15]))
    step = float(rng.uniform(*((0.005, 0.05), (0.05, 0.2), (0.2, 0.5), (0.5, 1.0))[band]))
    if mode in ("spin", "standing"):
        step = 0.0
    yaw = {"smooth": (0.0, 3.0), "mer": (5.0, 25.0), "zigzag": (0.5, 8.0), "spin": (2.0, 25.0),
           "standing": (0.0, 0.0)}[mode]
    yaw_deg = float(rng.uniform(*yaw))
    bob_height = float(rng.uniform(0.0, 0.015) * cam_height)
    bob_tilt = float(rng.uniform(0.0, 2.0))
    bob_periods = tuple(float(_log_uniform(rng, 2.0, 60.0)) for _ in range(int(rng.integers(1, 4))))
    jerk = float(rng.uniform(1.0, 4.0)) if rng.random() < 0.12 else 0.0
    climb = bool(ground == "rocks" and rng.random() < 0.3)
    texture = str(rng.choice(TEXTURES, p=[0.3, 0.2, 0.2, 0.15, 0.15]))
    noise_var = _log_uniform(rng, 1.0, 40.0)
    ramp = None
    if rng.random() < 0.2:
        ramp = (float(rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.4)), float(rng.uniform(-25, 25)))
    shadow = None
    if rng.random() < 0.15:
        shadow = (float(rng.uniform(0.25, 0.6)), float(rng.uniform(0.0, 2 * math.pi)),
                  float(rng.uniform(0.3, 1.2)), float(rng.uniform(0.5, 5.0)))
    inner = np.arange(1, frames)

    def some(p: float, most: int) -> tuple[int, ...]:
        if rng.random() >= p:
            return ()
        k = int(rng.integers(1, most + 1))
        return tuple(sorted(int(v) for v in rng.choice(inner, size=min(k, len(inner)), replace=False)))

    blank = some(0.1, 2)
    corrupt_frames = some(0.1, 2)
    corrupt = tuple((k, str(rng.choice(["truncated", "garbage", "empty"]))) for k in corrupt_frames
                    if k not in blank)
    dropped = tuple(k for k in some(0.15, 3) if k not in blank and k not in corrupt_frames)
    if len(dropped) >= frames - 2:
        dropped = dropped[:1]
    nominal = bool(rng.random() < 0.3)
    return Scenario(seed=int(seed), index=int(index), tiny=bool(tiny), width=width, height=height,
                    frames=frames, fov=fov, cam_height=cam_height, pitch_deg=pitch, forward=forward,
                    mode=mode, step=step, yaw_deg=yaw_deg, bob_height=bob_height,
                    bob_tilt_deg=bob_tilt, bob_periods=bob_periods, jerk_deg=jerk, ground=ground,
                    climb=climb, texture=texture, noise_var=noise_var, ramp=ramp, shadow=shadow,
                    blank=blank, corrupt=corrupt, dropped=dropped, nominal=nominal)


# --------------------------------------------------------------------------- rendering


def _camera(sc: Scenario):
    if sc.fov == "navcam":
        return fov_camera(sc.width, sc.height, 45.0)
    return default_camera(sc.width, sc.height)


def _wave(rng: np.random.Generator, n: int, periods: tuple[float, ...]) -> np.ndarray:
    """(n,) a sum of sinusoids of those periods (frames), random phases, in [-1, 1]."""
    k = np.arange(n, dtype=float)
    w = rng.uniform(0.5, 1.0, len(periods))
    w /= w.sum()
    phase = rng.uniform(0.0, 2 * math.pi, len(periods))
    return sum(wi * np.sin(2 * math.pi * k / p + ph) for wi, p, ph in zip(w, periods, phase))


def path_of(sc: Scenario, rng: np.random.Generator) -> np.ndarray:
    """(frames, 3): the rover's turning centre x, y (m) and heading (rad) per frame."""
    n, step = sc.frames, sc.step * sc.cam_height
    yaw = math.radians(sc.yaw_deg)
    speed = 1.0 + 0.3 * smooth(rng, n, (10.0, 80.0))
    rate = smooth(rng, n, (10.0, 80.0))
    heading = float(rng.uniform(0.0, 2 * math.pi))
    pos = np.zeros(2)
    out = [(0.0, 0.0, heading)]
    run, turns, sign, arc = 0, 0, 1.0, 0.0
    for k in range(1, n):
        s = dpsi = 0.0
        if sc.mode == "smooth":
            s, dpsi = step * speed[k], yaw * rate[k]
        elif sc.mode == "zigzag":
            s, dpsi = step * rng.uniform(0.7, 1.0), yaw * rng.uniform(0.5, 1.0) * (-1.0) ** k
        elif sc.mode == "spin":
            if rng.random() < 0.3:
                sign = -sign
            dpsi = sign * yaw * rng.uniform(0.67, 1.0)
        elif sc.mode == "mer":
            if run == 0 and turns == 0:
                run, turns = int(rng.integers(3, 9)), int(rng.integers(1, 4))
                sign, arc = float(rng.choice([-1.0, 1.0])), math.radians(rng.uniform(-3.0, 3.0))
            if run > 0:
                s, dpsi, run = step * rng.uniform(0.8, 1.0), arc, run - 1
            else:
                dpsi, turns = sign * yaw * rng.uniform(0.67, 1.0), turns - 1
        mid = heading + 0.5 * dpsi
        pos = pos + s * np.array([math.cos(mid), math.sin(mid)])
        heading += dpsi
        out.append((pos[0], pos[1], heading))
    return np.array(out)


def _low_texture(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    pad = 32
    blurred = cv2.GaussianBlur(np.pad(image, pad, mode="wrap"), (0, 0), rng.uniform(3.0, 8.0))
    blurred = blurred[pad:-pad, pad:-pad]
    contrast = rng.uniform(0.1, 0.3) * TEXTURE_STD / max(float(blurred.std()), 1e-6)
    return ((blurred - blurred.mean()) * contrast + TEXTURE_MEAN).astype(np.float32)


def checker_texture(n: int, rng: np.random.Generator) -> np.ndarray:
    """A periodic checkerboard, n x n float32 (n a power of two): squares of 4-32 texels."""
    side = int(rng.choice([4, 8, 16, 32]))
    contrast = rng.uniform(20.0, 60.0)
    i = np.arange(n) // side
    board = ((i[:, None] + i[None, :]) % 2).astype(np.float32) * 2.0 - 1.0
    board = cv2.GaussianBlur(np.pad(board, 4, mode="wrap"), (0, 0), 0.5)[4:-4, 4:-4]
    return (TEXTURE_MEAN + contrast * board).astype(np.float32)


def photo_texture(n: int, rng: np.random.Generator) -> np.ndarray:
    """A photo-like periodic texture, n x n float32: a dead-leaves image (opaque discs of
    power-law radii, each occluding the ones before it) over 1/f noise, the two classic
    models of natural images' statistics (scale invariance, occlusion edges)."""
    fy = np.fft.fftfreq(n)[:, None]
    fx = np.fft.rfftfreq(n)[None, :]
    f = np.maximum(np.hypot(fx, fy), 1.0 / n)
    spec = (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape)) / f
    pink = np.fft.irfft2(spec, s=(n, n))
    pink = (pink - pink.mean()) / max(float(pink.std()), 1e-9)
    leaves = np.zeros((n, n), np.float32)
    r_min, r_max = 1.5 * n / 1024.0 + 1.0, n / 10.0
    # Radii with density ~ r^-3 have a mean area of 2 pi r_min^2 ln(r_max / r_min): enough
    # discs to cover the plane about three times over (the last ones drawn are on top).
    count = int(3.0 * n * n / (2.0 * math.pi * r_min ** 2 * math.log(r_max / r_min)))
    radii = np.minimum(r_min * (1.0 - rng.random(count)) ** (-0.5), r_max)
    xs, ys = rng.random(count) * n, rng.random(count) * n
    grey = rng.normal(0.0, 1.0, count)
    for x, y, r, g in zip(xs, ys, radii, grey):
        for dx in (-n, 0, n):
            if not -r <= x + dx < n + r:
                continue
            for dy in (-n, 0, n):
                if -r <= y + dy < n + r:
                    cv2.circle(leaves, (int(round((x + dx) * 16)), int(round((y + dy) * 16))),
                               int(round(r * 16)), float(g), -1, cv2.LINE_AA, 4)
    img = 0.7 * leaves + 0.3 * pink.astype(np.float32)
    img = cv2.GaussianBlur(np.pad(img, 4, mode="wrap"), (0, 0), 0.6)[4:-4, 4:-4]
    img = (img - img.mean()) * (TEXTURE_STD / max(float(img.std()), 1e-6)) + TEXTURE_MEAN
    return np.clip(img, 0.0, 255.0).astype(np.float32)


def texture_of(sc: Scenario, rng: np.random.Generator, metres_per_texel: float) -> np.ndarray:
    n = 512 if sc.tiny else 1024 if max(sc.width, sc.height) <= 256 else 2048
    tex_seed = int(rng.integers(0, 2**31))
    if sc.texture == "gravel":
        return gravel_texture(n, tex_seed, metres_per_texel=metres_per_texel)
    if sc.texture == "photo":
        return photo_texture(n, rng)
    if sc.texture == "checker":
        return checker_texture(n, rng)
    image = procedural_texture(n, tex_seed)
    return _low_texture(image, rng) if sc.texture == "low" else image


def _shadow_mask(sc: Scenario, k: int) -> np.ndarray:
    """(H, W) float32 multiplier of frame k: a soft half plane whose edge sweeps across."""
    dark, angle, sweep, edge = sc.shadow
    x, y = grid(sc.width, sc.height)
    a = angle + 0.3 * k / max(sc.frames - 1, 1)
    nx, ny = math.cos(a), math.sin(a)
    half = 0.5 * math.hypot(sc.width, sc.height)
    offset = (-0.5 + sweep * k / max(sc.frames - 1, 1)) * half
    s = (x - 0.5 * sc.width) * nx + (y - 0.5 * sc.height) * ny - offset
    inside = 1.0 / (1.0 + np.exp(np.clip(s / edge, -50, 50)))
    return (1.0 - dark * inside).astype(np.float32)


def _horizon_clearance(cam, poses: list[np.ndarray], gradient: tuple[float, float]) -> float:
    """The smallest angle (deg) by which rays through the border of any frame dip below the
    plane of slope ``gradient`` (the terrain's mean ground): negative when the horizon shows."""
    n = np.array([-gradient[0], -gradient[1], 1.0])
    n /= np.linalg.norm(n)
    t = np.linspace(0.0, 1.0, 6)
    u, v = -0.5 + t * cam.width, -0.5 + t * cam.height  # along the top/bottom, left/right
    left, right, top, bottom = -0.5, cam.width - 0.5, -0.5, cam.height - 0.5
    xs = np.r_[u, u, np.full(6, left), np.full(6, right)]
    ys = np.r_[np.full(6, top), np.full(6, bottom), v, v]
    rays = np.column_stack([(xs - cam.cx) / cam.fx, (ys - cam.cy) / cam.fy, np.ones(len(xs))])
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    worst = min(float(np.min(-(g[:3, :3] @ rays.T).T @ n)) for g in poses)
    return math.degrees(math.asin(max(-1.0, min(1.0, worst))))


def _corrupt_bytes(png: bytes, kind: str, rng: np.random.Generator) -> bytes:
    if kind == "truncated":
        return png[:max(8, int(len(png) * rng.uniform(0.05, 0.9)))]
    if kind == "garbage":
        return rng.bytes(max(64, len(png) // 4))
    return b""


def render(sc: Scenario, seq: Path) -> None:
    """Write scenario ``sc`` as a sequence folder ``seq`` (frames/, init.yaml, ground truth)."""
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(
        [sc.seed, sc.index, int(sc.tiny), 1]).spawn(6)]
    motion_rng, bob_rng, jerk_rng, terrain_rng, tex_rng, noise_rng = rngs
    cam = _camera(sc)
    mount = camera_mount(sc.pitch_deg, sc.cam_height, forward=sc.forward)
    region = ground_region(cam, mount)
    if region is None:
        raise RuntimeError(f"{sc.describe()}: the camera sees no ground at its mount")
    x, y = grid(cam.width, cam.height)
    metres_per_texel = 0.85 * float(np.min(pixel_size_on_plane(plane_homography(cam, mount), x, y)))
    tex = GroundTexture(texture_of(sc, tex_rng, metres_per_texel), metres_per_texel)

    path = path_of(sc, motion_rng)
    n = sc.frames
    tilt = math.radians(sc.bob_tilt_deg)
    bob = np.column_stack([sc.bob_height * _wave(bob_rng, n, sc.bob_periods),
                           tilt * _wave(bob_rng, n, sc.bob_periods),
                           tilt * _wave(bob_rng, n, sc.bob_periods)])
    if sc.ground == "flat":
        terrain = None
        g_from_body = body_on_ground(path, lambda px, py: np.zeros_like(px))
        renderer = GroundRenderer(cam, tex)
    else:
        box = (float(path[:, 0].min() - ROCK_MARGIN), float(path[:, 1].min() - ROCK_MARGIN),
               float(path[:, 0].max() + ROCK_MARGIN), float(path[:, 1].max() + ROCK_MARGIN))
        terrain = make_terrain(sc.ground, terrain_rng, box)
        g_from_body = body_on_ground(path, terrain.height if sc.climb else terrain.base_height)
        renderer = TerrainRenderer(cam, tex, terrain,
                                   sun_azimuth=float(terrain_rng.uniform(0, 2 * math.pi)))
    jerks = [np.eye(4)] * n
    if sc.jerk_deg > 0:
        j = np.radians(sc.jerk_deg) * jerk_rng.standard_normal((n, 3)) * np.array([1.0, 1.0, 0.5])
        jerks = [make_pose(so3_exp(v), np.zeros(3)) for v in j]

    def poses_at(m: np.ndarray) -> list[np.ndarray]:
        return [g_from_body[k] @ bobbed_mount(bob[k], m) @ jerks[k] for k in range(n)]

    poses, pitch = poses_at(mount), sc.pitch_deg
    if terrain is not None:  # the ray caster marches grazing rays for kilometres: keep the
        # horizon of the terrain's mean plane out of every frame (a deterministic re-aim)
        while pitch < 90.0 and _horizon_clearance(cam, poses, terrain.gradient) < HORIZON_DEG:
            pitch = min(pitch + 5.0, 90.0)
            mount = camera_mount(pitch, sc.cam_height, forward=sc.forward)
            poses = poses_at(mount)
        region = ground_region(cam, mount)

    frames_dir = seq / "frames"
    frames_dir.mkdir(parents=True, exist_ok=True)
    corrupt = dict(sc.corrupt)
    present = [k for k in range(n) if k not in sc.dropped]
    for k in present:
        t = k / max(n - 1, 1)
        gain, bias = (1.0 + sc.ramp[0] * t, sc.ramp[1] * t) if sc.ramp else (1.0, 0.0)
        image = renderer.render(poses[k])
        if sc.shadow:
            image = image * _shadow_mask(sc, k)
        img = finish_frame(image, noise_rng, sc.noise_var, gain, bias)
        if k in sc.blank:
            img = np.full_like(img, int(noise_rng.integers(0, 256)))
        path_k = frames_dir / f"frame_{k:06d}.png"
        if k in corrupt:
            ok, buf = cv2.imencode(".png", img)
            path_k.write_bytes(_corrupt_bytes(buf.tobytes(), corrupt[k], noise_rng))
        else:
            write_png(path_k, img)
    if sc.nominal:
        plane_pose = mount
    else:  # frame 0's ground: the plane under its wheels, seen from camera 0
        plane_pose = se3_inv(g_from_body[0]) @ poses[0]
    params = {"generator": "benchmarks.soak", "class": sc.klass, **_plain(asdict(sc)),
              "pitch_deg_rendered": float(pitch)}
    write_sequence(seq, cam, [poses[k] for k in present], region, params, None,
                   plane_pose=plane_pose, nominal=sc.nominal)


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


# --------------------------------------------------------------------------- running and judging


def track_command(seq: Path, out: Path, threads: int) -> list[str]:
    """The ``monovo track`` arguments of a soak run (after ``monovo``)."""
    return ["track", str(seq), "-o", str(out), "--threads", str(threads), "-q",
            "--skip-bad-frames", "--overwrite"]


def run_subprocess(seq: Path, out: Path, threads: int) -> tuple[int, str]:
    """``python -m monovo_cli track ...`` as a user runs it: (exit status, stderr)."""
    r = subprocess.run([sys.executable, "-m", "monovo_cli", *track_command(seq, out, threads)],
                       capture_output=True, text=True, cwd=ROOT)
    return r.returncode, r.stderr


@dataclass
class Verdict:
    """What one scenario's run did against the invariants."""

    exit_code: int
    failures: list[str] = field(default_factory=list)  # invariant names
    details: list[str] = field(default_factory=list)
    untrusted: int = 0
    untrusted_ok: int = 0  # of them written ok or reanchored
    msd_bad: int = 0
    drift_pct: float = float("nan")
    drift_bad: bool = False
    thread_mismatch: bool = False
    rows: int = 0
    lost: int = 0
    z: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))


def _f(v: str) -> float:
    return float(v) if v not in ("", None) else float("nan")


def judge(sc: Scenario, seq: Path, out: Path, exit_code: int, stderr: str) -> Verdict:
    """Hold one run (its exit status, stderr and ``out``) to the invariants."""
    v = Verdict(exit_code)
    if exit_code not in (0, 3) or "Traceback (most recent call last)" in stderr:
        v.failures.append("exit")
        last = [ln for ln in stderr.splitlines() if ln.strip()]
        v.details.append(f"exit {exit_code}: {last[-1] if last else '(no message)'}")
    motion = out / "motion.csv"
    if not motion.is_file():
        if "exit" not in v.failures:
            v.failures.append("exit")
            v.details.append(f"exit {exit_code} without motion.csv")
        return v
    with open(seq / "groundtruth_motion.csv", newline="") as f:
        gt = {int(r["frame"]): r for r in csv.DictReader(f)}
    with open(motion, newline="") as f:
        rows = list(csv.DictReader(f))
    v.rows = len(rows)
    v.lost = sum(r["status"] == "lost" for r in rows)
    converged = [r for r in rows if r["status"] in ("ok", "reanchored")]
    msds = [_f(r["msd"]) for r in converged]
    level = max(float(np.median(msds)) if msds else 0.0, 2.0 * sc.noise_var + 1.0)
    z = []
    for r in rows:
        g = gt.get(int(r["frame"]))
        if g is None:
            continue
        e = np.array([_f(r[a]) - float(g[a]) for a in AXES])
        std = np.array([_f(r.get("std_" + a, "")) for a in AXES])
        msd = _f(r["msd"])
        if r["status"] in ("ok", "reanchored"):
            if np.all(np.isfinite(std)):
                z.append(e / np.maximum(std, 1e-12))
            if msd > MSD_FACTOR * level:
                v.msd_bad += 1
                v.details.append(f"msd: frame {r['frame']} {r['status']} msd {msd:.1f} > "
                                 f"{MSD_FACTOR:g} x {level:.1f}; {_row_words(e, std)}")
        if np.linalg.norm(e[:3]) <= OFF_M and np.linalg.norm(e[3:]) <= OFF_DEG:
            continue
        if np.all(np.isfinite(std)) and np.all(np.abs(e) <= COVER * std):
            continue
        v.untrusted += 1
        v.untrusted_ok += r["status"] in ("ok", "reanchored")
        v.details.append(f"untrusted: frame {r['frame']} {r['status']} msd {msd:.1f} "
                         f"(level {level:.1f}); {_row_words(e, std)}"
                         + (f"; reason {r['reason']}" if r.get("reason") else ""))
    v.z = np.array(z).reshape(-1, 6)
    if v.untrusted:
        v.failures.append("untrusted")
    if v.msd_bad:
        v.failures.append("msd")
    if exit_code == 0 and (out / "trajectory.tum").is_file():
        _, est = read_tum(out / "trajectory.tum")
        _, truth = read_tum(seq / "groundtruth.tum")
        err, dist, _ = final_drift(est, truth)
        v.drift_pct = 100.0 * err / dist if dist > 0 else float("inf") if err > 0 else 0.0
        bound = DRIFT_PCT[sc.klass] / 100.0 * dist + DRIFT_FLOOR * sc.cam_height
        if not err <= bound:
            v.drift_bad = True
            v.failures.append("drift")
            v.details.append(f"drift: end-point error {err:.3f} m over {dist:.2f} m "
                             f"({v.drift_pct:.2f} %) > {bound:.3f} m ({DRIFT_PCT[sc.klass]:g} % "
                             f"+ {DRIFT_FLOOR * sc.cam_height:.3f} m); {v.lost} of {v.rows} lost")
    return v


def _row_words(e: np.ndarray, std: np.ndarray) -> str:
    """|error| and the worst axis in units of its std."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(e) / std
    worst = int(np.nanargmax(ratio)) if np.any(np.isfinite(ratio)) else int(np.argmax(np.abs(e)))
    return (f"|e_t| {np.linalg.norm(e[:3]):.3f} m |e_r| {np.linalg.norm(e[3:]):.2f} deg, "
            f"worst {AXES[worst]} e {e[worst]:+.4f} std {std[worst]:.4f} "
            f"({ratio[worst]:.1f} std)")


def same_bytes(a: Path, b: Path) -> bool:
    """motion.csv and trajectory.csv of two output folders are byte-identical."""
    for name in ("motion.csv", "trajectory.csv"):
        pa, pb = a / name, b / name
        if pa.is_file() != pb.is_file() or (pa.is_file() and pa.read_bytes() != pb.read_bytes()):
            return False
    return True


def soak_one(job: tuple[int, int, bool, str | None]) -> dict:
    """Draw, render, track and judge one scenario (a worker's unit of work)."""
    seed, index, tiny, keep = job
    sc = draw(seed, index, tiny=tiny)
    root = Path(keep) / f"{index:04d}" if keep else Path(tempfile.mkdtemp(prefix="soak_"))
    if keep and root.exists():
        shutil.rmtree(root)
    seq, out = root / "seq", root / "out"
    t0 = time.perf_counter()
    try:
        render(sc, seq)
        t1 = time.perf_counter()
        code, err = run_subprocess(seq, out, 1)
        v = judge(sc, seq, out, code, err)
        if index % THREAD_EVERY == 0 and code in (0, 3):
            out2 = root / "out_threads2"
            run_subprocess(seq, out2, 2)
            if not same_bytes(out, out2):
                v.thread_mismatch = True
                v.failures.append("threads")
                v.details.append("threads: --threads 2 wrote other bytes than --threads 1")
        t2 = time.perf_counter()
    finally:
        if not keep:
            shutil.rmtree(root, ignore_errors=True)
    return {"scenario": sc, "verdict": v, "render_s": t1 - t0, "track_s": t2 - t1}


# --------------------------------------------------------------------------- report


def _honesty(z: np.ndarray) -> str:
    if len(z) < 2:
        return " | ".join(["-"] * 6)
    return " | ".join(f"{s:.2f}" for s in z.std(axis=0))


def table(results: list[dict]) -> str:
    """Markdown: failure counts and honesty by class and over all scenarios."""
    head = ("| class | scenarios | failing | exit 1 | other exit / traceback | untrusted rows (ok/reanch.) "
            "| msd rows | drift failures | thread mismatches (checked) | drift bound | "
            "converged rows | std(z) tx | ty | tz | rx | ry | rz |")
    lines = [head, "|" + " --- |" * (head.count("|") - 1)]
    groups = [(c, [r for r in results if r["scenario"].klass == c]) for c in CLASSES]
    groups.append(("all", results))
    for name, rs in groups:
        if not rs:
            continue
        vs = [r["verdict"] for r in rs]
        z = np.concatenate([v.z for v in vs]) if vs else np.zeros((0, 6))
        checked = sum(r["scenario"].index % THREAD_EVERY == 0 for r in rs)
        bound = f"{DRIFT_PCT[name]:g} %" if name in DRIFT_PCT else "-"
        lines.append(
            f"| {name} | {len(rs)} | {sum(bool(v.failures) for v in vs)} "
            f"({100.0 * sum(bool(v.failures) for v in vs) / len(rs):.0f} %) | "
            f"{sum(v.exit_code == 1 for v in vs)} | "
            f"{sum('exit' in v.failures and v.exit_code != 1 for v in vs)} | "
            f"{sum(v.untrusted for v in vs)} ({sum(v.untrusted_ok for v in vs)}) in "
            f"{sum(v.untrusted > 0 for v in vs)} | {sum(v.msd_bad for v in vs)} in "
            f"{sum(v.msd_bad > 0 for v in vs)} | {sum(v.drift_bad for v in vs)} | "
            f"{sum(v.thread_mismatch for v in vs)} ({checked}) | {bound} | {len(z)} | "
            f"{_honesty(z)} |")
    return "\n".join(lines)


def failure_lines(results: list[dict]) -> list[str]:
    """Each failing scenario: its class, seed, index, invariants and replay command, what
    was drawn and what went wrong (the first eight rows)."""
    lines = []
    for r in results:
        sc, v = r["scenario"], r["verdict"]
        if not v.failures:
            continue
        lines.append(f"FAIL [{sc.klass}] seed {sc.seed} index {sc.index}: {', '.join(v.failures)} "
                     f"-- replay: {sc.replay()}")
        lines.append(f"    {sc.describe()}")
        lines.extend(f"    {d}" for d in v.details[:8])
        if len(v.details) > 8:
            lines.append(f"    ... {len(v.details) - 8} more")
    return lines


def write_docs(command: str, text: str) -> None:
    """Replace the soak section at the end of docs/benchmarks.md (or append it)."""
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=ROOT).stdout.strip() or "?"
    section = "\n".join([
        BEGIN,
        f"## The scenario soak (issue 40) (`{command}`)",
        "",
        f"Commit {commit}; machine (and date): {machine()}.",
        "The box, the classes and the invariants are benchmarks/soak.py's docstring; every "
        "failing scenario's replay command is printed by the run.",
        "",
        text,
        END,
    ])
    doc = DOCS.read_text(encoding="utf-8")
    if BEGIN in doc and END in doc:
        head, rest = doc.split(BEGIN, 1)
        doc = head + section + rest.split(END, 1)[1]
    else:
        doc = doc.rstrip("\n") + "\n\n" + section + "\n"
    DOCS.write_text(doc, encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenarios", type=int, default=500)
    ap.add_argument("--seed", type=int, default=40)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--only", type=int, nargs="+", default=None, metavar="INDEX",
                    help="run only these scenario indices")
    ap.add_argument("--keep", type=Path, default=None, metavar="DIR",
                    help="keep every scenario's sequence and outputs in DIR/<index>/")
    ap.add_argument("--tiny", action="store_true",
                    help="the test slice's small scenarios (96-160 px, 8-15 frames)")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the soak section at the end of docs/benchmarks.md")
    args = ap.parse_args(argv)
    one_core()
    indices = args.only if args.only is not None else list(range(args.scenarios))
    jobs = [(args.seed, i, args.tiny, str(args.keep) if args.keep else None) for i in indices]
    command = "python -m benchmarks.soak " + " ".join(argv if argv is not None else sys.argv[1:])
    print(f"{command}\nMachine: {machine()}\n", flush=True)
    start = time.perf_counter()
    results = []
    signal.signal(signal.SIGTERM, _stop)
    try:
        if args.workers > 1:
            with ProcessPoolExecutor(max_workers=args.workers, initializer=one_core) as pool:
                for r in pool.map(soak_one, jobs):
                    results.append(r)
                    _progress(r, len(results), len(jobs), start)
        else:
            for job in jobs:
                results.append(soak_one(job))
                _progress(results[-1], len(results), len(jobs), start)
    except Stopped:
        print(f"\nSTOPPED (SIGTERM) after {len(results)} of {len(jobs)} scenarios: the table "
              "below covers those.", flush=True)
    lines = failure_lines(results)
    print("\nAll failures, in index order:\n" + ("\n".join(lines) if lines else "No scenario failed."))
    render_s = sum(r["render_s"] for r in results)
    track_s = sum(r["track_s"] for r in results)
    text = (table(results) + "\n\n"
            f"{len(results)} scenarios (seed {args.seed}{', tiny' if args.tiny else ''}) in "
            f"{time.perf_counter() - start:.0f} s wall ({render_s:.0f} s rendering, {track_s:.0f} s "
            f"tracking) on {args.workers} worker(s). Columns: failing = scenarios failing any "
            f"invariant; untrusted rows (of them written ok/reanchored) in N scenarios; "
            f"std(z) = std of error/std over the converged rows (target 0.5-2).")
    print("\n" + text)
    if args.write_docs:
        write_docs(command, text)
        print(f"\nwrote the soak section of {DOCS}")
    return 0


class Stopped(Exception):
    """SIGTERM arrived: report the scenarios done so far."""


def _stop(signum, frame):  # noqa: ARG001
    raise Stopped()


def _progress(r: dict, done: int, total: int, start: float) -> None:
    """One line on stderr per scenario; a failure's lines at once on stdout too (a long run
    that is stopped keeps them), and again, all together, before the table."""
    sc, v = r["scenario"], r["verdict"]
    if v.failures:
        print("\n".join(failure_lines([r])), flush=True)
    print(f"[{done}/{total} {time.perf_counter() - start:.0f} s] index {sc.index} {sc.klass}: "
          f"{'FAIL ' + ','.join(v.failures) if v.failures else 'ok'} "
          f"(render {r['render_s']:.1f} s, track {r['track_s']:.1f} s)", file=sys.stderr, flush=True)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
