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
``ground`` is frame 0's ground, exact unless ``ground.std_distance`` (m) and/or
``ground.std_deg`` state its uncertainty. The optional ``sigma_distance`` (m) and ``sigma_deg``
give the width of the mounting prior: how far the ground under the rover departs from its
mean mount (suspension, terrain); absent, the tracker's defaults apply
(:mod:`monovo_cli.core.plane.belief`). The mean mount is estimated from the drive, unless it
is declared: ``ground.nominal: true`` says the plane is the nominal mount (frame 0's ground
then known only to the prior's width), and a top-level ``mount:`` block (``normal`` +
``distance`` or ``height`` + ``pitch_deg`` [+ ``roll_deg``]) gives it beside frame 0's ground
(:class:`~monovo_cli.core.plane.tracker.Mounting`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from monovo_cli.core.plane.tracker import Mounting
from monovo_cli.errors import ConfigError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.init_ground import Region, ground_section, initial_pose, sigmas
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

TOP_KEYS = ("camera", "camera_file", "ground", "mount")
CAMERA_KEYS = ("width", "height", "fx", "fy", "cx", "cy", "distortion")

MAX_IMAGE_SIDE = 100_000        # px; larger is certainly a typo



@dataclass(frozen=True)
class InitConfig:
    """A validated ``init.yaml``: the camera, the ground at frame 0 and the file it came from.

    ``plane`` is the ground in camera-0 coordinates; ``region`` the image rectangle
    ``(x0, y0, x1, y1)`` (px, x1 and y1 exclusive) the ground model covers at frame 0 (the
    whole frame when init.yaml gives none). ``sigma_distance`` (m) and ``sigma_deg``: the
    mounting prior's width (``ground.sigma_distance``, ``ground.sigma_deg``), None when
    init.yaml does not give it. ``nominal``: ``plane`` is the nominal mount rather than
    frame 0's ground; ``mount`` a nominal mount declared beside it (``mount:``);
    ``std_distance`` (m) and ``std_deg`` frame 0's stated uncertainty (None: exact).
    """

    camera: PinholeCamera
    plane: Plane
    region: Region
    path: Path
    sigma_distance: float | None = None
    sigma_deg: float | None = None
    nominal: bool = False
    mount: Plane | None = None
    std_distance: float | None = None
    std_deg: float | None = None

    @property
    def mounting(self) -> Mounting:
        """What the tracker takes from this file besides frame 0's plane."""
        if self.nominal:
            return Mounting.nominal(self.plane, self.sigma_distance, self.sigma_deg)
        initial = None
        if self.std_distance is not None or self.std_deg is not None:
            from monovo_cli.core.plane.belief import EXACT_STD

            initial = (self.std_distance if self.std_distance is not None
                       else EXACT_STD * self.plane.distance,
                       self.std_deg if self.std_deg is not None else math.degrees(EXACT_STD))
        return Mounting(self.sigma_distance, self.sigma_deg, mount=self.mount,
                        initial_std=initial)

    @property
    def convention(self) -> str:
        """How the file's ground reads, in words (for run.yaml and messages)."""
        if self.nominal:
            return "nominal mount"
        return "frame 0's ground, mount declared" if self.mount is not None else \
            "frame 0's ground, mean mount estimated"


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


def _parse(data: Any, name: str, base_dir: Path
           ) -> tuple[PinholeCamera, Plane, Region, tuple[float | None, float | None], dict]:
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
    plane, region = ground_section(name, data["ground"], camera)
    return (camera, plane, region, sigmas(name, data["ground"]),
            initial_pose(name, data, camera, region))


# ----------------------------------------------------------------------------- public


def load_init(path: Path) -> InitConfig:
    """Read and validate an ``init.yaml``; raises ConfigError (one line) on any problem."""
    path = Path(path)
    name = str(path)
    if path.is_dir():
        raise fail(name, "is a directory; expected the init.yaml file")
    data = read_yaml(path, name, "the init file")
    camera, plane, region, (sigma_distance, sigma_deg), pose = _parse(data, name, path.parent)
    return InitConfig(camera=camera, plane=plane, region=region, path=path,
                      sigma_distance=sigma_distance, sigma_deg=sigma_deg, **pose)


def check_frame_size(cfg: InitConfig, width: int, height: int, frame_path: Path) -> None:
    """ConfigError unless the frames are as large as the configured camera."""
    cam = cfg.camera
    if (cam.width, cam.height) != (int(width), int(height)):
        raise ConfigError(f"{cfg.path}: camera is {cam.width}x{cam.height} but frames are "
                          f"{int(width)}x{int(height)} ({frame_path}); use the init.yaml of the "
                          "camera that took them")


def dump_init(path: Path, camera: PinholeCamera, plane: Plane, region: Region | None = None,
              *, nominal: bool = False) -> None:
    """Write ``camera``, the ground ``plane`` and ``region`` (None: the whole frame) as an
    init.yaml (docs/guide.md "File formats", the normal + distance form), atomically;
    ``nominal``: the plane is the nominal mount, not frame 0's ground (``ground.nominal``).
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
    if nominal:
        lines.append("  nominal: true")
    text = "\n".join(lines) + "\n"
    # Validate exactly what will be read back.
    _parse(yaml.load(text, Loader=UniqueKeyLoader), name, path.parent)
    atomic_write_text(path, text)
