"""Synthetic ground sequences with exact ground truth (``monovo synth``).

A pinhole camera looks at a textured plane (the ground, ``z_G = 0`` of a ground frame G
with z up). Every frame is rendered through the exact plane-induced homography from
ground coordinates to pixels:

* the texture is a periodic (seamlessly tiling) grey image with ``metres_per_texel``
  metres per texel, sampled bilinearly with wrap-around, through a mip-map pyramid
  (trilinear, level chosen per pixel from the pixel's size on the plane), so
  distant, foreshortened ground does not alias;
* each image is rendered at ``SUPERSAMPLE`` times its resolution and area-averaged down,
  which integrates every pixel over its area. Supersampled pixel ``(i, j)`` has its
  centre at original pixel coordinate ``((i + 0.5)/s - 0.5, (j + 0.5)/s - 0.5)``, so the
  top-left original pixel centre stays at (0, 0) (docs/guide.md "File formats");
* pixels whose ray misses the plane (above the horizon) get a plain sky value;
* optionally (``psf``) the camera's optics blur before the pixel: a Gaussian PSF of ``psf``
  px applied to the supersampled image, before its area average
  (:class:`~monovo_cli.synth.render.PsfRenderer`; the image is rendered with a margin so
  that its border pixels see the ground beyond the field of view);
* optional exposure change (gain, bias), then Gaussian noise, rounding, 8-bit PNG.

Poses: ``g_from_cam_k`` maps camera-k points to G. The world frame is camera 0's
(docs/guide.md "Conventions"), so the ground truth is ``T_0_k = inv(g_from_cam_0) @
g_from_cam_k`` and the relative motion ``T_{k-1}_k = inv(g_from_cam_{k-1}) @ g_from_cam_k``.
The plane in camera 0 is ``{X : n . X = d}`` with ``n = -R_0^T e_z`` (pointing from the
camera to the ground) and ``d`` the camera height.

Presets:

* ``drive`` -- a rover camera on a 1.5 m mast pitched 45 deg down, driving ~5 cm/frame
  with smooth turns and small roll/pitch/height wobble; one sequence.
* ``pairs`` -- the paper's experiment: camera 100 m from the plane, optical axis 25 deg
  (+- 5 deg) off the plane normal, one random motion per pair (rotation +-5 deg and
  translation +-10 m per axis); one 2-frame sequence per pair in ``pair_NNNN/``.
* ``mer`` -- MER visual odometry's spacing: 0.6-0.75 m steps and 12-18 deg turns in place,
  a 1024x1024 camera with a 45 deg field of view on a 1.5 m mast pitched 45 deg down.

With ``terrain=`` (always for ``mer``) the drive goes over a height field instead of the
plane (:mod:`~monovo_cli.synth.terrain`), rendered by ray casting
(:mod:`~monovo_cli.synth.raycast`); the rover's body lies on the ground under its wheels
and bobs (:mod:`~monovo_cli.synth.rover`); the ``drive`` camera is then pitched 40 deg.
init.yaml gets frame 0's ground (the body's plane under its wheels, seen from the bobbing
camera; ``init_pose="nominal"``: the nominal mount, declared as such) and ``terrain.npz``
the true height field.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from monovo_cli.errors import InputError, OutputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose
from monovo_cli.io.atomic import atomic_write_bytes, atomic_write_text
from monovo_cli.synth.gravel import gravel_texture
from monovo_cli.synth.motion import (
    BOB_HEIGHT,
    DRIVE_MAST_HEIGHT,
    DRIVE_PITCH_DEG,
    DRIVE_SPEED_VARIATION,
    DRIVE_STEP,
    MER_STEP,
    PAIR_DISTANCE,
    PAIR_EXTRA_TILT_DEG,
    PAIR_MAX_TRANSLATION,
    PAIR_TILT_DEG,
    bobbed_mount,
    body_from_camera,
    drive_poses,
    pair_poses,
    smooth,
)
from monovo_cli.synth.raycast import TERRAIN_SUPERSAMPLE, TerrainRenderer
from monovo_cli.synth.render import (
    MAX_PSF,
    SUPERSAMPLE,
    GroundRenderer,
    PsfRenderer,
    default_camera,
    finish_frame,
    grid,
    ground_region,
    pixel_size_on_plane,
    plane_homography,
    render_shaded,
)
from monovo_cli.synth.rover import MER_FRAMES, MER_SIZE, mer_camera, rover_mount, rover_scene
from monovo_cli.synth.sequence_files import INIT_POSES, make_dir, write_png, write_sequence
from monovo_cli.synth.terrain import TERRAINS, terrain_npz_bytes
from monovo_cli.synth.texture import (
    TEXTURE_MEAN,
    TEXTURE_STD,
    GroundTexture,
    load_texture,
    procedural_texture,
    procedural_texture_size,
)
from monovo_cli.version import __version__

PRESETS = ("drive", "pairs", "mer")
TEXTURES = ("procedural", "gravel")  # built-in names of texture=
MIN_SIZE = 32
MAX_SIZE = 8192

EXPOSURE_GAIN = 0.2  # gain in 1 +- this
EXPOSURE_BIAS = 15.0  # grey levels


@dataclass(frozen=True)
class SynthSummary:
    """What :func:`synthesize` wrote."""

    out_dir: Path
    sequences: int  # 1 for drive, N for pairs
    frames_per_sequence: int
    distance_m: float  # camera path length (drive) or sum of pair translations (pairs)


# --------------------------------------------------------------------------- entry point


def _check_number(name: str, value, *, low: float, high: float = math.inf,
                  integer: bool = False) -> None:
    kind = "a whole number" if integer else "a number"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} {value!r}: must be {kind}")
    if integer and int(value) != value:
        raise InputError(f"{name} {value!r}: must be {kind}")
    if not math.isfinite(float(value)) or not (low <= float(value) <= high):
        rng = f">= {low:g}" if high == math.inf else f"between {low:g} and {high:g}"
        raise InputError(f"{name} {value!r}: must be {kind} {rng}")


def synthesize(out_dir: Path, *, preset: str = "drive", frames: int | None = None,
               size: tuple[int, int] | None = None, noise_var: float = 10.0, seed: int = 0,
               texture: Path | str | None = None, max_translation: float | None = None,
               max_rotation_deg: float = 5.0, exposure: bool = False, shadow: float = 0.0,
               low_texture: bool = False, clean_frame0: bool = False, terrain: str | None = None,
               init_pose: str = "frame0", psf: float = 0.0, crest: float | None = None,
               progress: Callable[[int, int], None] | None = None) -> SynthSummary:
    """Write a synthetic sequence (``drive``, ``mer``) or set of 2-frame sequences (``pairs``).

    ``frames``: frames of the drive (default 300; mer 100) or number of pairs (default 100).
    ``size``: ``(width, height)`` px (default 512x512 drive, 1024x1024 mer, 688x544 pairs).
    ``texture``: an image file (a Path, or a str not in TEXTURES), or a built-in texture
    name (``procedural``, the default, or ``gravel``).
    ``terrain``: drive over a height field (one of TERRAINS) rendered by ray casting, the
    body on the ground under its wheels and bobbing (monovo_cli.synth.rover, .raycast); the
    drive's camera is then pitched 40 deg. ``mer``: MER-like 0.6-0.75 m steps and 12-18 deg
    turns in place, a 45 deg field of view pitched 45 deg, over ``terrain`` (default flat).
    With a terrain, init.yaml holds frame 0's ground (the body's plane at frame 0, its bob
    included, seen from the camera) and terrain.npz the true height field.
    ``init_pose``: ``frame0`` (init.yaml holds frame 0's ground, the init.yaml convention) or
    ``nominal`` (the rover's nominal mount, declared with ``ground.nominal: true``; drives
    only).
    ``max_translation``: pairs -- per-axis translation bound, m (default 10);
    drive -- peak forward step per frame, m (default 0.065 = 0.05 * 1.3).
    ``max_rotation_deg``: pairs -- per-axis bound of the rotation vector, degrees; the
    drive's turns are fixed (yaw rate up to 1 deg/frame) and ignore it.
    ``exposure``: vary gain (0.8..1.2) and bias (+-15 grey levels) per frame (smoothly along
    a drive, independently per pair frame); written to ``photometric.csv``.
    ``shadow``: darken (x0.5) this fraction of the image's bottom rows in every frame, a
    shadow fixed to the camera like the rover's own. ``low_texture``: a smooth ground with
    a quarter of the contrast and no fine detail. ``clean_frame0``: frame 0 (of the drive,
    of every pair) without noise, only rounded -- the paper's synthetic experiment, where the
    ground's texture is exactly known; the other frames' noise is the same as without it.
    ``psf``: the optics' blur, the standard deviation in pixels of a Gaussian point spread
    function applied before the pixel (to the noise-free supersampled image, before its area
    average, exposure and noise; the shadow lies on the ground, under the blur); 0 (the
    default) renders exactly as without it, and synth.yaml records ``psf`` only when > 0.
    ``crest``: a rover's drive only: frame 0's bobbing height above the mean, m (within
    +-BOB_HEIGHT), its pitch and roll at their means; None (the default): frame 0 at a
    crest of all three, as far from the mean as the bobbing goes (synth.yaml records
    ``crest`` only when given).
    ``progress(done, total)`` is called after each drive frame / each pair.
    Raises InputError for bad arguments, OutputError if ``out_dir`` exists and is not empty
    or cannot be written.
    """
    out_dir = Path(out_dir)
    if preset not in PRESETS:
        raise InputError(f"--preset {preset!r}: unknown preset, choose one of {', '.join(PRESETS)}")
    drive = preset != "pairs"
    rover = preset == "mer" or terrain is not None
    if rover and not drive:
        raise InputError("--terrain: only the drive and mer presets drive over terrain")
    if rover and terrain is None:
        terrain = "flat"
    if init_pose not in INIT_POSES:
        raise InputError(f"--init-pose {init_pose!r}: choose one of {', '.join(INIT_POSES)}")
    if init_pose == "nominal" and not drive:
        raise InputError("--init-pose nominal: only a drive has a nominal mount")
    if rover and terrain not in TERRAINS:
        raise InputError(f"--terrain {terrain!r}: unknown terrain, choose one of {', '.join(TERRAINS)}")
    if preset == "mer" and max_translation is not None:
        raise InputError("--max-translation: the mer preset's steps are fixed (0.6-0.75 m)")
    if preset == "mer":
        max_translation = MER_STEP[1]  # (recorded in synth.yaml; the steps are mer_path's)
    if frames is None:
        frames = {"drive": 300, "mer": MER_FRAMES}.get(preset, 100)
    _check_number("--frames", frames, low=2 if drive else 1, integer=True)
    frames = int(frames)
    if size is None:
        size = {"drive": (512, 512), "mer": MER_SIZE}.get(preset, (688, 544))
    if (not isinstance(size, (tuple, list)) or len(size) != 2
            or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in size)):
        raise InputError(f"--size {size!r}: must be two whole numbers WIDTHxHEIGHT")
    width, height = int(size[0]), int(size[1])
    if min(width, height) < MIN_SIZE or max(width, height) > MAX_SIZE:
        raise InputError(f"--size {width}x{height}: width and height must be between "
                         f"{MIN_SIZE} and {MAX_SIZE} px")
    _check_number("--noise-var", noise_var, low=0.0)
    _check_number("--seed", seed, low=0, high=2**63 - 1, integer=True)
    seed = int(seed)
    if max_translation is None:
        max_translation = DRIVE_STEP * (1.0 + DRIVE_SPEED_VARIATION) if drive else PAIR_MAX_TRANSLATION
    _check_number("max_translation", max_translation, low=0.0,
                  high=1.0 if drive else 0.5 * PAIR_DISTANCE)
    _check_number("max_rotation_deg", max_rotation_deg, low=0.0, high=30.0)
    _check_number("--shadow", shadow, low=0.0, high=1.0)
    _check_number("--psf", psf, low=0.0, high=MAX_PSF)
    if crest is not None:
        if not rover:
            raise InputError("--crest: only a drive over --terrain (or the mer preset) bobs")
        _check_number("--crest", crest, low=-BOB_HEIGHT, high=BOB_HEIGHT)
        crest = float(crest)
    if out_dir.exists():
        if not out_dir.is_dir():
            raise OutputError(f"{out_dir}: exists and is not a directory")
        if any(out_dir.iterdir()):
            raise OutputError(f"{out_dir}: already exists and is not empty")

    cam = mer_camera(width, height) if preset == "mer" else default_camera(width, height)
    ss = np.random.SeedSequence(seed)
    motion_rng, noise_rng, photo_rng, terrain_rng, bob_rng = (
        np.random.default_rng(s) for s in ss.spawn(5))  # (the first three as ever)

    # Texture scale: a texel is ~0.85 px at the nearest visible ground of the nominal view.
    if rover:
        nominal = rover_mount(preset)  # the body's plane is z = 0
    elif drive:
        nominal = make_pose(body_from_camera(math.radians(DRIVE_PITCH_DEG)),
                            np.array([0.0, 0.0, DRIVE_MAST_HEIGHT]))
    else:
        nominal = make_pose(body_from_camera(math.radians(90.0 - PAIR_TILT_DEG)),
                            np.array([0.0, 0.0, PAIR_DISTANCE]))
    x, y = grid(width, height)
    metres_per_texel = 0.85 * float(np.min(pixel_size_on_plane(plane_homography(cam, nominal), x, y)))
    if texture is None or (isinstance(texture, str) and texture in TEXTURES):
        n_tex = procedural_texture_size(width, height)
        if texture == "gravel":
            tex_image = gravel_texture(n_tex, seed, metres_per_texel=metres_per_texel)
        else:
            tex_image = procedural_texture(n_tex, seed)
        texture_desc = texture
    else:
        tex_image = load_texture(Path(texture))
        texture_desc = str(Path(texture).resolve())
    if low_texture:
        n_pad = 16
        blurred = cv2.GaussianBlur(np.pad(tex_image, n_pad, mode="wrap"), (0, 0), 4.0)
        blurred = blurred[n_pad:-n_pad, n_pad:-n_pad]
        tex_image = ((blurred - blurred.mean()) * (0.25 * TEXTURE_STD / max(float(blurred.std()), 1e-6))
                     + TEXTURE_MEAN).astype(np.float32)
    tex = GroundTexture(tex_image, metres_per_texel)
    period = np.array(tex.shape[::-1], dtype=float) * metres_per_texel  # (u, v) metres

    params = {
        "generator": f"monovo {__version__} synth",
        "preset": preset, "seed": seed, "frames": frames, "size": [width, height],
        "noise_var": float(noise_var), "max_translation": float(max_translation),
        "max_rotation_deg": float(max_rotation_deg), "exposure": bool(exposure),
        "texture": texture_desc, "shadow": float(shadow), "low_texture": bool(low_texture),
        "clean_frame0": bool(clean_frame0),
        **({"init_pose": init_pose} if init_pose != "frame0" else {}),
        "texture_texels": [int(tex.shape[1]), int(tex.shape[0])],
        "metres_per_texel": metres_per_texel, "supersample": SUPERSAMPLE,
    }
    if psf > 0:  # (absent at 0: the default's synth.yaml is as before the option)
        params["psf"] = float(psf)
    if crest is not None:
        params["crest"] = crest
    # All geometry first (it can still reject the arguments), then write.
    sequences: list[tuple[Path, list[np.ndarray], list[tuple[float, float]] | None, dict]] = []
    if drive:
        origin = tuple(motion_rng.uniform(0.0, 1.0, 2) * period)
        if rover:
            scene = rover_scene(preset, terrain, frames, motion_rng=motion_rng,
                                terrain_rng=terrain_rng, bob_rng=bob_rng,
                                peak_step=float(max_translation), origin=origin, crest=crest)
            poses = scene.poses
        else:
            poses = drive_poses(frames, motion_rng, peak_step=float(max_translation), origin=origin)
        photometric = None
        if exposure:
            gains = 1.0 + EXPOSURE_GAIN * smooth(photo_rng, frames, (30.0, 200.0))
            biases = EXPOSURE_BIAS * smooth(photo_rng, frames, (30.0, 200.0))
            photometric = [(float(g), float(b)) for g, b in zip(gains, biases)]
        params.update(mast_height=DRIVE_MAST_HEIGHT, pitch_deg=DRIVE_PITCH_DEG)
        if rover:
            params.update(terrain=terrain, pitch_deg=round(math.degrees(math.asin(-nominal[2, 2])), 9),
                          mast_forward=float(nominal[0, 3]), supersample=TERRAIN_SUPERSAMPLE,
                          sun_azimuth_deg=math.degrees(scene.sun_azimuth))
        sequences.append((out_dir, poses, photometric, params))
    else:
        params.update(plane_distance=PAIR_DISTANCE, tilt_deg=PAIR_TILT_DEG,
                      extra_tilt_deg=PAIR_EXTRA_TILT_DEG)
        for i in range(frames):
            origin = tuple(motion_rng.uniform(0.0, 1.0, 2) * period)
            g0, g1 = pair_poses(cam, motion_rng, max_translation=float(max_translation),
                                max_rotation_deg=float(max_rotation_deg), origin=origin)
            photometric = None
            if exposure:
                photometric = [(float(photo_rng.uniform(1 - EXPOSURE_GAIN, 1 + EXPOSURE_GAIN)),
                                float(photo_rng.uniform(-EXPOSURE_BIAS, EXPOSURE_BIAS)))
                               for _ in range(2)]
            sequences.append((out_dir / f"pair_{i:04d}", [g0, g1], photometric,
                              dict(params, pair=i)))
    regions = []
    for _, poses, _, _ in sequences:
        region = ground_region(cam, nominal if rover else poses[0])
        if region is None:
            raise InputError(f"--size {width}x{height}: the camera sees no ground at frame 0")
        regions.append(region)

    make_dir(out_dir)
    if not drive:
        atomic_write_text(out_dir / "synth.yaml",
                          yaml.safe_dump(params, default_flow_style=None, sort_keys=False))
    if rover:
        def make(c: PinholeCamera):
            return TerrainRenderer(c, tex, scene.terrain, sun_azimuth=scene.sun_azimuth)
        atomic_write_bytes(out_dir / "terrain.npz",
                           terrain_npz_bytes(scene.terrain, scene.heights_bounds, scene.poses))
    else:
        def make(c: PinholeCamera):
            return GroundRenderer(c, tex)
    renderer = PsfRenderer(cam, make, float(psf)) if psf > 0 else make(cam)
    shadow_row = int(round(height * (1.0 - shadow))) if shadow > 0 else None
    distance = 0.0
    for i, ((seq_dir, poses, photometric, seq_params), region) in enumerate(
            zip(sequences, regions)):
        frames_dir = seq_dir / "frames"
        make_dir(frames_dir)
        for k, g in enumerate(poses):
            gain, bias = photometric[k] if photometric else (1.0, 0.0)
            ground = render_shaded(renderer, g, shadow_row)
            img = finish_frame(ground, noise_rng, float(noise_var), gain, bias)
            if clean_frame0 and k == 0:  # (the noise was still drawn: frame 1's stays the same)
                img = finish_frame(ground, noise_rng, 0.0, gain, bias)
            write_png(frames_dir / f"frame_{k:06d}.png", img)
            if drive and progress is not None:
                progress(k + 1, frames)
        plane_pose = None
        if rover:
            plane_pose = nominal if init_pose == "nominal" else bobbed_mount(scene.bob[0], nominal)
        write_sequence(seq_dir, cam, poses, region, seq_params, photometric,
                        plane_pose=plane_pose, nominal=init_pose == "nominal")
        if rover:
            init = seq_dir / "init.yaml"
            atomic_write_text(init, INIT_POSES[init_pose] + init.read_text(encoding="utf-8"))
        distance += float(sum(np.linalg.norm(poses[k][:3, 3] - poses[k - 1][:3, 3])
                              for k in range(1, len(poses))))
        if not drive and progress is not None:
            progress(i + 1, frames)
    return SynthSummary(out_dir=out_dir, sequences=len(sequences),
                        frames_per_sequence=len(sequences[0][1]), distance_m=distance)


