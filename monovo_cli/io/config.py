"""The initial-pose file (``init.yaml``, docs/guide.md "File formats").

This module is the only place where raw YAML exists: :func:`load_init` turns a file
into a validated :class:`InitConfig` (a :class:`~monovo_cli.geometry.camera.PinholeCamera`,
the ground :class:`~monovo_cli.geometry.plane.Plane` and the ground region),
:func:`dump_init` writes one back. Every problem raises
:class:`~monovo_cli.errors.ConfigError` with one line: the file, what is wrong and what
would fix it, e.g. ``init.yaml: camera.fx must be > 0, got -3`` (the generic field readers
are in :mod:`monovo_cli.io.yaml_fields`).

Instead of ``normal`` + ``distance`` the ground may be given as ``height`` (m),
``pitch_deg`` and optional ``roll_deg`` (the convention is in
:mod:`monovo_cli.geometry.plane`; roll 0 gives ``normal = (0, cos p, sin p)``).
The optional ``sigma_distance`` (m) and ``sigma_deg`` give the width of the mounting prior:
how far the ground may depart from this plane in any later camera frame (suspension,
terrain); absent, the tracker's defaults apply (:mod:`monovo_cli.core.plane.belief`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from monovo_cli.errors import ConfigError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane, normal_from_pitch_roll
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.yaml_fields import (
    UniqueKeyLoader,
    check_keys,
    fail,
    flow_list,
    integer,
    mapping,
    number,
    numbers,
    positive,
    read_yaml,
    show,
    yaml_float,
)

log = logging.getLogger(__name__)

TOP_KEYS = ("camera", "camera_file", "ground")
CAMERA_KEYS = ("width", "height", "fx", "fy", "cx", "cy", "distortion")
GROUND_KEYS = ("normal", "distance", "height", "pitch_deg", "roll_deg", "region",
               "sigma_distance", "sigma_deg")
MAX_SIGMA_DEG = 45.0  # ground.sigma_deg: a wider prior on the tilt says nothing

MAX_IMAGE_SIDE = 100_000        # px; larger is certainly a typo
MIN_REGION_FRACTION = 0.01      # the ground region must cover >= 1% of the image
MIN_RAY_DOT = 1e-6              # n . ray at a region pixel: the ray must hit the plane
MAX_DEPTH_RATIO = 1e4           # region depth / plane distance: beyond this, too oblique
UNIT_TOLERANCE = 1e-6           # |normal| further than this from 1 is normalised (warning)


Region = tuple[int, int, int, int]


@dataclass(frozen=True)
class InitConfig:
    """A validated ``init.yaml``: the camera, the ground at frame 0 and the file it came from.

    ``plane`` is the ground in camera-0 coordinates; ``region`` the image rectangle
    ``(x0, y0, x1, y1)`` (px, x1 and y1 exclusive) the ground model covers at frame 0 (the
    whole frame when init.yaml gives none). ``sigma_distance`` (m) and ``sigma_deg``: the
    mounting prior's width (``ground.sigma_distance``, ``ground.sigma_deg``), None when
    init.yaml does not give it.
    """

    camera: PinholeCamera
    plane: Plane
    region: Region
    path: Path
    sigma_distance: float | None = None
    sigma_deg: float | None = None


# ----------------------------------------------------------------------------- parsing


def _distortion(name: str, where: str, value: Any) -> tuple[float, ...]:
    """OpenCV ``k1 k2 p1 p2 [k3 [k4 k5 k6]]`` normalised to 5 coefficients."""
    if value is None:
        return (0.0,) * 5
    d = numbers(name, where, value, (4, 5, 8),
                 "a list of 4, 5 or 8 numbers (OpenCV k1 k2 p1 p2 [k3 [k4 k5 k6]])")
    if len(d) == 8:
        if any(c != 0.0 for c in d[5:]):
            raise fail(name, f"{where}: the rational model (k4 k5 k6 = {d[5]:g} {d[6]:g} "
                              f"{d[7]:g}) is not supported; use k1 k2 p1 p2 k3 only")
        d = d[:5]
    return tuple(d + [0.0] * (5 - len(d)))


def _camera_section(name: str, value: Any) -> PinholeCamera:
    cam = mapping(name, "camera", value, "width, height, fx, fy, cx, cy[, distortion]")
    if "model" in cam:  # a JPL camera model (CAHV, CAHVOR, CAHVORE)
        from monovo_cli.io.jpl_camera import camera_from_yaml

        return camera_from_yaml(name, cam)
    check_keys(name, cam, CAMERA_KEYS, "camera.")
    for key in CAMERA_KEYS[:6]:
        if key not in cam:
            raise fail(name, f"camera.{key} is missing (camera needs width, height, fx, fy, cx, cy)")
    size = {}
    for key in ("width", "height"):
        n = integer(name, f"camera.{key}", cam[key])
        if n <= 0 or n > MAX_IMAGE_SIDE:
            raise fail(name, f"camera.{key} must be a whole number of pixels in 1..{MAX_IMAGE_SIDE}, "
                              f"got {show(cam[key])}")
        size[key] = n
    fx = positive(name, "camera.fx", cam["fx"])
    fy = positive(name, "camera.fy", cam["fy"])
    cx = number(name, "camera.cx", cam["cx"])
    cy = number(name, "camera.cy", cam["cy"])
    dist = _distortion(name, "camera.distortion", cam.get("distortion"))
    return PinholeCamera(size["width"], size["height"], fx, fy, cx, cy, dist)


def _camera_info(init_name: str, base_dir: Path, value: Any) -> PinholeCamera:
    """A camera from a ROS ``camera_info`` YAML (``camera_file:``, relative to init.yaml)."""
    if not isinstance(value, str) or not value.strip():
        raise fail(init_name, f"camera_file must be a file name (a ROS camera_info YAML), "
                               f"got {show(value)}")
    path = Path(value.strip()).expanduser()
    if not path.is_absolute():
        path = base_dir / path
    name = str(path)
    if path.suffix.lower() in (".img", ".lbl", ".xml"):  # a PDS product's camera model
        from monovo_cli.io.jpl_camera import camera_from_label

        return camera_from_label(init_name, path)
    data = read_yaml(path, name, f"the camera_file named in {init_name}")
    fix = "expected a ROS camera_info YAML with image_width, image_height, camera_matrix"
    if not isinstance(data, dict):
        raise fail(name, f"not a camera_info file ({fix})")
    for key in ("image_width", "image_height", "camera_matrix"):
        if key not in data:
            raise fail(name, f"not a camera_info file: {key} is missing ({fix})")
    size = []
    for key in ("image_width", "image_height"):
        n = integer(name, key, data[key])
        if n <= 0 or n > MAX_IMAGE_SIDE:
            raise fail(name, f"{key} must be a whole number of pixels in 1..{MAX_IMAGE_SIDE}, "
                              f"got {show(data[key])}")
        size.append(n)
    km = mapping(name, "camera_matrix", data["camera_matrix"], "rows, cols, data")
    for key in ("rows", "cols"):
        if key in km and integer(name, f"camera_matrix.{key}", km[key]) != 3:
            raise fail(name, f"camera_matrix.{key} must be 3, got {show(km[key])}")
    if "data" not in km:
        raise fail(name, "camera_matrix.data is missing (9 numbers, row-major K)")
    k = numbers(name, "camera_matrix.data", km["data"], (9,), "9 numbers (row-major K)")
    fx, skew, cx, k10, fy, cy, k20, k21, k22 = k
    if fx <= 0 or fy <= 0:
        raise fail(name, f"camera_matrix fx and fy must be > 0, got {fx:g} and {fy:g}")
    if k10 != 0.0 or k20 != 0.0 or k21 != 0.0 or abs(k22 - 1.0) > 1e-9:
        raise fail(name, "camera_matrix.data must be [fx, 0, cx, 0, fy, cy, 0, 0, 1]")
    if abs(skew) > 1e-9 * fx:
        raise fail(name, f"camera_matrix skew {skew:g} is not supported (must be 0)")
    model = data.get("distortion_model")
    if model is not None and model not in ("plumb_bob", "rational_polynomial"):
        raise fail(name, f"distortion_model {show(model)} is not supported "
                          "(use plumb_bob: k1 k2 p1 p2 k3)")
    dist: tuple[float, ...] = (0.0,) * 5
    dc = data.get("distortion_coefficients")
    if dc is not None:
        dc = mapping(name, "distortion_coefficients", dc, "rows, cols, data")
        coeffs = dc.get("data")
        if coeffs is not None and coeffs != []:
            dist = _distortion(name, "distortion_coefficients.data", coeffs)
    return PinholeCamera(size[0], size[1], fx, fy, cx, cy, dist)


def _unit_normal(name: str, value: Any) -> tuple[float, float, float]:
    v = np.array(numbers(name, "ground.normal", value, (3,), "a list of 3 numbers [nx, ny, nz]"))
    scale = float(np.max(np.abs(v)))
    if scale == 0.0:
        raise fail(name, "ground.normal must not be zero-length; give the unit normal "
                          "pointing from the camera to the ground")
    u = v / scale
    length = float(np.linalg.norm(u)) * scale
    if abs(length - 1.0) > 1e-12:  # not unit to float precision (keeps round trips exact)
        u = u / np.linalg.norm(u)
        if abs(length - 1.0) > UNIT_TOLERANCE:
            log.warning("%s: ground.normal %s has length %.6g; normalised to unit length",
                        name, [float(c) for c in v], length)
    else:
        u = v
    return (float(u[0]), float(u[1]), float(u[2]))


def _region(name: str, value: Any, width: int, height: int) -> Region:
    if value is None:
        return (0, 0, width, height)
    if not isinstance(value, (list, tuple)) or len(value) != 4:
        raise fail(name, f"ground.region must be a list of 4 whole numbers [x0, y0, x1, y1] (px), "
                          f"got {show(value)}")
    x0, y0, x1, y1 = (integer(name, f"ground.region[{i}]", v) for i, v in enumerate(value))
    shown = f"[{x0}, {y0}, {x1}, {y1}]"
    if x0 >= x1 or y0 >= y1:
        raise fail(name, f"ground.region {shown} is empty or inverted (need x0 < x1 and y0 < y1)")
    if x0 < 0 or y0 < 0 or x1 > width or y1 > height:
        raise fail(name, f"ground.region {shown} extends outside the {width}x{height} image "
                          f"(need 0 <= x0 < x1 <= {width} and 0 <= y0 < y1 <= {height})")
    fraction = (x1 - x0) * (y1 - y0) / (width * height)
    if fraction < MIN_REGION_FRACTION:
        raise fail(name, f"ground.region {shown} covers {100 * fraction:.2g}% of the image; "
                          f"make it at least {100 * MIN_REGION_FRACTION:g}%")
    return (x0, y0, x1, y1)


def _sigmas(name: str, g: dict) -> tuple[float | None, float | None]:
    """``ground.sigma_distance`` (m, > 0) and ``ground.sigma_deg`` (in (0, MAX_SIGMA_DEG])."""
    sd = sdeg = None
    if g.get("sigma_distance") is not None:
        sd = positive(name, "ground.sigma_distance", g["sigma_distance"])
    if g.get("sigma_deg") is not None:
        sdeg = positive(name, "ground.sigma_deg", g["sigma_deg"])
        if sdeg > MAX_SIGMA_DEG:
            raise fail(name, f"ground.sigma_deg must be at most {MAX_SIGMA_DEG:g} (degrees), "
                              f"got {show(g['sigma_deg'])}")
    return sd, sdeg


def _ground_section(name: str, value: Any, camera: PinholeCamera) -> tuple[Plane, Region]:
    g = mapping(name, "ground", value, "normal + distance (or height + pitch_deg) [+ region]")
    check_keys(name, g, GROUND_KEYS, "ground.")
    explicit = [k for k in ("normal", "distance") if k in g]
    angular = [k for k in ("height", "pitch_deg", "roll_deg") if k in g]
    if explicit and angular:
        raise fail(name, f"ground has both {' + '.join(explicit)} and {' + '.join(angular)}; "
                          "give either normal + distance or height + pitch_deg [+ roll_deg]")
    if not explicit and not angular:
        raise fail(name, "ground needs normal + distance, or height + pitch_deg [+ roll_deg]")
    if explicit:
        for key in ("normal", "distance"):
            if key not in g:
                raise fail(name, f"ground.{key} is missing (normal and distance go together)")
        normal = _unit_normal(name, g["normal"])
        distance = positive(name, "ground.distance", g["distance"])
    else:
        for key in ("height", "pitch_deg"):
            if key not in g:
                raise fail(name, f"ground.{key} is missing (height and pitch_deg go together)")
        distance = positive(name, "ground.height", g["height"])
        pitch = number(name, "ground.pitch_deg", g["pitch_deg"])
        if not 0.0 < pitch < 180.0:
            raise fail(name, f"ground.pitch_deg must be in (0, 180) (degrees down from "
                              f"horizontal, 90 = straight down), got {show(g['pitch_deg'])}")
        roll = 0.0
        if g.get("roll_deg") is not None:
            roll = number(name, "ground.roll_deg", g["roll_deg"])
            if not -90.0 < roll < 90.0:
                raise fail(name, f"ground.roll_deg must be in (-90, 90), got {show(g['roll_deg'])}")
        normal = normal_from_pitch_roll(pitch, roll)
    region = _region(name, g.get("region"), camera.width, camera.height)
    plane = Plane(normal, distance)
    _check_visible(name, camera, plane, region)
    return plane, region


def _check_visible(name: str, camera: PinholeCamera, plane: Plane, region: Region) -> None:
    """Every ray of the region must meet the plane in front of the camera.

    That is the whole condition: a camera looking level or slightly up at a road (normal z
    <= 0) is fine when the region is the part of the image that shows the road.
    """
    n = plane.normal
    x0, y0, x1, y1 = region
    # Sample the region's border (pixel centres): corners suffice without distortion,
    # where n . ray is affine in the pixel; the edge samples cover distorted cameras.
    us = np.unique(np.linspace(x0, x1 - 1, 9).round())
    vs = np.unique(np.linspace(y0, y1 - 1, 9).round())
    border = np.concatenate([
        np.stack([us, np.full_like(us, y0)], 1), np.stack([us, np.full_like(us, y1 - 1)], 1),
        np.stack([np.full_like(vs, x0), vs], 1), np.stack([np.full_like(vs, x1 - 1), vs], 1),
    ])
    shown = f"[{x0}, {y0}, {x1}, {y1}]"
    try:
        with np.errstate(all="ignore"):
            rays = camera.rays(border)
    except Exception:  # cv2.error from undistortion of absurd coefficients
        rays = np.full((len(border), 3), np.nan)
    if not np.all(np.isfinite(rays)):
        raise fail(name, "camera.distortion cannot be inverted over ground.region "
                          f"{shown}; check the distortion coefficients")
    with np.errstate(all="ignore"):
        dots = rays @ n
    worst = int(np.argmin(dots))
    u, v = int(border[worst, 0]), int(border[worst, 1])
    if not np.any(dots > MIN_RAY_DOT):
        raise fail(name, f"the ground plane is not in front of the camera: no ray of region {shown} "
                          "meets it (the normal points from the camera to the ground); check "
                          "normal/pitch_deg")
    if not dots[worst] > MIN_RAY_DOT:
        raise fail(name, f"the ground plane is not visible in region {shown} (behind the camera or "
                          f"parallel to the view at pixel ({u}, {v})); check normal/pitch_deg, or "
                          "set ground.region to the part of the image showing the ground")
    if dots[worst] < 1.0 / MAX_DEPTH_RATIO:
        raise fail(name, f"the ground plane is too oblique in region {shown}: its depth at pixel "
                          f"({u}, {v}) is {1.0 / dots[worst]:.3g} times the plane distance "
                          f"(limit {MAX_DEPTH_RATIO:g}); check normal/pitch_deg, or move "
                          "ground.region's top edge down")


def _parse(data: Any, name: str, base_dir: Path
           ) -> tuple[PinholeCamera, Plane, Region, tuple[float | None, float | None]]:
    if data is None:
        raise fail(name, "the file is empty; it needs 'camera:' and 'ground:' sections")
    if not isinstance(data, dict):
        raise fail(name, f"expected a mapping with 'camera:' and 'ground:' sections, got {show(data)}")
    check_keys(name, data, TOP_KEYS, "")
    if "camera" in data and "camera_file" in data:
        raise fail(name, "give either 'camera' or 'camera_file', not both")
    if "camera" not in data and "camera_file" not in data:
        raise fail(name, "missing 'camera' section (or 'camera_file' naming a ROS camera_info YAML)")
    if "ground" not in data:
        raise fail(name, "missing 'ground' section (normal + distance, or height + pitch_deg)")
    if "camera" in data:
        camera = _camera_section(name, data["camera"])
    else:
        camera = _camera_info(name, base_dir, data["camera_file"])
    plane, region = _ground_section(name, data["ground"], camera)
    return camera, plane, region, _sigmas(name, data["ground"])


# ----------------------------------------------------------------------------- public


def load_init(path: Path) -> InitConfig:
    """Read and validate an ``init.yaml``; raises ConfigError (one line) on any problem."""
    path = Path(path)
    name = str(path)
    if path.is_dir():
        raise fail(name, "is a directory; expected the init.yaml file")
    data = read_yaml(path, name, "the init file")
    camera, plane, region, (sigma_distance, sigma_deg) = _parse(data, name, path.parent)
    return InitConfig(camera=camera, plane=plane, region=region, path=path,
                      sigma_distance=sigma_distance, sigma_deg=sigma_deg)


def check_frame_size(cfg: InitConfig, width: int, height: int, frame_path: Path) -> None:
    """ConfigError unless the frames are as large as the configured camera."""
    cam = cfg.camera
    if (cam.width, cam.height) != (int(width), int(height)):
        raise ConfigError(f"{cfg.path}: camera is {cam.width}x{cam.height} but frames are "
                          f"{int(width)}x{int(height)} ({frame_path}); use the init.yaml of the "
                          "camera that took them")


def dump_init(path: Path, camera: PinholeCamera, plane: Plane, region: Region | None = None) -> None:
    """Write ``camera``, the ground ``plane`` and ``region`` (None: the whole frame) as an
    init.yaml (docs/guide.md "File formats", the normal + distance form), atomically.
    Raises ConfigError, writing nothing, if they would not load back."""
    path = Path(path)
    name = str(path)
    values = [camera.fx, camera.fy, camera.cx, camera.cy, *camera.distortion,
               *plane.normal, plane.distance]
    try:
        finite = all(math.isfinite(float(v)) for v in values)
    except (TypeError, ValueError, OverflowError):
        finite = False
    if not finite:
        raise fail(name, "cannot write a camera or ground plane with non-numeric or non-finite values")
    lines = [
        "# monovo initial-pose file: camera intrinsics and the ground plane at frame 0",
        "camera:",
        f"  width: {int(camera.width)}",
        f"  height: {int(camera.height)}",
        f"  fx: {yaml_float(camera.fx)}",
        f"  fy: {yaml_float(camera.fy)}",
        f"  cx: {yaml_float(camera.cx)}",
        f"  cy: {yaml_float(camera.cy)}",
        f"  distortion: {flow_list(camera.distortion, yaml_float)}",
        "ground:",
        f"  normal: {flow_list(plane.normal, yaml_float)}",
        f"  distance: {yaml_float(plane.distance)}",
    ]
    if region is not None:
        lines.append(f"  region: {flow_list(region, lambda v: str(int(v)))}")
    text = "\n".join(lines) + "\n"
    # Validate exactly what will be read back.
    _parse(yaml.load(text, Loader=UniqueKeyLoader), name, path.parent)
    atomic_write_text(path, text)
