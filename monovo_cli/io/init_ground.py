"""The ``ground`` (and ``mount``) sections of ``init.yaml`` (:mod:`monovo_cli.io.config`
reads the rest): frame 0's plane, the region the ground model covers, the mounting prior's
width, and how the plane reads -- frame 0's ground, exact or with a stated std, or the
nominal mount (``ground.nominal``), or frame 0's ground beside a declared ``mount:``.
Every problem raises :class:`~monovo_cli.errors.ConfigError` with one line.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane, normal_from_pitch_roll
from monovo_cli.io.yaml_fields import (
    check_keys,
    fail,
    integer,
    mapping,
    number,
    numbers,
    positive,
    show,
)

log = logging.getLogger(__name__)

GROUND_KEYS = ("normal", "distance", "height", "pitch_deg", "roll_deg", "region",
               "sigma_distance", "sigma_deg", "std_distance", "std_deg", "nominal")
MOUNT_KEYS = ("normal", "distance", "height", "pitch_deg", "roll_deg")
MAX_SIGMA_DEG = 45.0  # ground.sigma_deg: a wider prior on the tilt says nothing
MIN_REGION_FRACTION = 0.01      # the ground region must cover >= 1% of the image
MIN_RAY_DOT = 1e-6              # n . ray at a region pixel: the ray must hit the plane
MAX_DEPTH_RATIO = 1e4           # region depth / plane distance: beyond this, too oblique
UNIT_TOLERANCE = 1e-6           # |normal| further than this from 1 is normalised (warning)

Region = tuple[int, int, int, int]


def _unit_normal(name: str, value: Any, where: str = "ground.normal") -> tuple[float, float, float]:
    v = np.array(numbers(name, where, value, (3,), "a list of 3 numbers [nx, ny, nz]"))
    scale = float(np.max(np.abs(v)))
    if scale == 0.0:
        raise fail(name, f"{where} must not be zero-length; give the unit normal "
                          "pointing from the camera to the ground")
    u = v / scale
    length = float(np.linalg.norm(u)) * scale
    if abs(length - 1.0) > 1e-12:  # not unit to float precision (keeps round trips exact)
        u = u / np.linalg.norm(u)
        if abs(length - 1.0) > UNIT_TOLERANCE:
            log.warning("%s: %s %s has length %.6g; normalised to unit length",
                        name, where, [float(c) for c in v], length)
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


def sigmas(name: str, g: dict) -> tuple[float | None, float | None]:
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


def _plane_fields(name: str, where: str, g: dict) -> Plane:
    """The plane of section ``where`` (``ground``, ``mount``): ``normal`` + ``distance``, or
    ``height`` + ``pitch_deg`` [+ ``roll_deg``]."""
    explicit = [k for k in ("normal", "distance") if k in g]
    angular = [k for k in ("height", "pitch_deg", "roll_deg") if k in g]
    if explicit and angular:
        raise fail(name, f"{where} has both {' + '.join(explicit)} and {' + '.join(angular)}; "
                          "give either normal + distance or height + pitch_deg [+ roll_deg]")
    if not explicit and not angular:
        raise fail(name, f"{where} needs normal + distance, or height + pitch_deg [+ roll_deg]")
    if explicit:
        for key in ("normal", "distance"):
            if key not in g:
                raise fail(name, f"{where}.{key} is missing (normal and distance go together)")
        normal = _unit_normal(name, g["normal"], f"{where}.normal")
        distance = positive(name, f"{where}.distance", g["distance"])
    else:
        for key in ("height", "pitch_deg"):
            if key not in g:
                raise fail(name, f"{where}.{key} is missing (height and pitch_deg go together)")
        distance = positive(name, f"{where}.height", g["height"])
        pitch = number(name, f"{where}.pitch_deg", g["pitch_deg"])
        if not 0.0 < pitch < 180.0:
            raise fail(name, f"{where}.pitch_deg must be in (0, 180) (degrees down from "
                              f"horizontal, 90 = straight down), got {show(g['pitch_deg'])}")
        roll = 0.0
        if g.get("roll_deg") is not None:
            roll = number(name, f"{where}.roll_deg", g["roll_deg"])
            if not -90.0 < roll < 90.0:
                raise fail(name, f"{where}.roll_deg must be in (-90, 90), got {show(g['roll_deg'])}")
        normal = normal_from_pitch_roll(pitch, roll)
    return Plane(normal, distance)


def ground_section(name: str, value: Any, camera: PinholeCamera) -> tuple[Plane, Region]:
    g = mapping(name, "ground", value, "normal + distance (or height + pitch_deg) [+ region]")
    check_keys(name, g, GROUND_KEYS, "ground.")
    plane = _plane_fields(name, "ground", g)
    region = _region(name, g.get("region"), camera.width, camera.height)
    _check_visible(name, camera, plane, region)
    return plane, region


def initial_pose(name: str, data: dict, camera: PinholeCamera, region: Region) -> dict:
    """The fields of InitConfig that say how ``ground`` reads: ``nominal``, ``mount``,
    ``std_distance``, ``std_deg``."""
    g = data["ground"]
    out: dict[str, Any] = {}
    nominal = g.get("nominal", False)
    if not isinstance(nominal, bool):
        raise fail(name, f"ground.nominal must be true or false, got {show(nominal)}")
    out["nominal"] = nominal
    for key in ("std_distance", "std_deg"):
        if g.get(key) is not None:
            out[key] = positive(name, f"ground.{key}", g[key])
    if nominal and out.keys() & {"std_distance", "std_deg"}:
        raise fail(name, "ground.nominal: true already says frame 0's ground is known to the "
                          "prior's width (sigma_distance, sigma_deg); drop std_distance/std_deg")
    if data.get("mount") is not None:
        if nominal:
            raise fail(name, "give either ground.nominal: true or a mount: block, not both")
        m = mapping(name, "mount", data["mount"], "normal + distance (or height + pitch_deg)")
        check_keys(name, m, MOUNT_KEYS, "mount.")
        out["mount"] = _plane_fields(name, "mount", m)
        _check_visible(name, camera, out["mount"], region)
    return out


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
