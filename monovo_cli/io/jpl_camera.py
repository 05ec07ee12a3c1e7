"""JPL camera models in init.yaml: ``camera: {model: cahvor, ...}`` and PDS labels' models.

``camera:`` may give a CAHV, CAHVOR or CAHVORE model instead of pinhole intrinsics::

    camera:
      model: cahvor          # or cahv, cahvore
      width: 1024            # px, must match the frames
      height: 1024
      C: [0.0, 0.0, 0.0]     # lists of 3 numbers in the model's frame (m, unit, px)
      A: [0.0, 0.0, 1.0]
      H: [1222.5, 0.0, 511.5]
      V: [0.0, 1222.5, 511.5]
      O: [0.0, 0.0, 1.0]     # cahvor / cahvore
      R: [0.0, -0.004, 0.0]  # cahvor / cahvore
      E: [0.0, 0.0, 0.0]     # cahvore
      linearity: 1.0         # cahvore: 1 perspective, 0 fish-eye

and ``camera_file:`` may name a PDS3/PDS4 product (``.IMG``, ``.LBL``, ``.xml``) whose label
holds the model (its image gives the size). monovo converts the model to a pinhole camera
with OpenCV distortion (:func:`monovo_cli.geometry.cahvor.fit_pinhole`) and logs the
reprojection error of the conversion; above :data:`MAX_RMS_PX` the model is refused (a
fish-eye lens has no pinhole equivalent), above :data:`WARN_RMS_PX` a warning says so. A
fitted distortion term that moves no pixel of the image by more than
:data:`NEGLIGIBLE_DISTORTION_PX` is set to exactly zero (:func:`without_negligible_distortion`):
a CAHV, or a CAHVOR that is exactly a pinhole, becomes the pinhole camera itself and takes
its computations, not the distortion's. The
ground plane of init.yaml is then given in the camera frame derived from the model
(:mod:`monovo_cli.geometry.cahvor`: z = A, x = H across A).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from monovo_cli.errors import ConfigError, InputError
from monovo_cli.geometry.cahvor import FIT_GRID, CahvorModel, fit_pinhole
from monovo_cli.geometry.camera import PinholeCamera

log = logging.getLogger(__name__)

MODELS = ("cahv", "cahvor", "cahvore")
VECTORS = {"cahv": "CAHV", "cahvor": "CAHVOR", "cahvore": "CAHVORE"}
MAX_IMAGE_SIDE = 100_000
#: Conversions with a larger RMS reprojection error (px) are refused, ...
MAX_RMS_PX = 1.0
#: ... and those above this one are warned about.
WARN_RMS_PX = 0.05
#: px: a distortion term whose largest displacement over the image is below this is zero.
NEGLIGIBLE_DISTORTION_PX = 1e-6


def _fail(name: str, message: str) -> ConfigError:
    return ConfigError(f"{name}: {message}")


def _show(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return "a mapping"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _number(name: str, where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise _fail(name, f"{where} must be a number, got {_show(value)}")
    try:
        x = float(value)
    except (ValueError, OverflowError):
        raise _fail(name, f"{where} must be a number, got {_show(value)}") from None
    if not math.isfinite(x):
        raise _fail(name, f"{where} must be a finite number, got {_show(value)}")
    return x


def _size(name: str, where: str, value: Any) -> int:
    x = _number(name, where, value)
    if not x.is_integer() or not 1 <= x <= MAX_IMAGE_SIDE:
        raise _fail(name, f"{where} must be a whole number of pixels in 1..{MAX_IMAGE_SIDE}, "
                          f"got {_show(value)}")
    return int(x)


def _vector(name: str, where: str, value: Any) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise _fail(name, f"{where} must be a list of 3 numbers, got {_show(value)}")
    return [_number(name, f"{where}[{i}]", v) for i, v in enumerate(value)]


def without_negligible_distortion(cam: PinholeCamera) -> PinholeCamera:
    """``cam`` with each distortion term (OpenCV ``k1 k2 p1 p2 k3``) whose largest
    displacement alone over the image (px, bounded at its farthest corner from the
    principal point) is at most :data:`NEGLIGIBLE_DISTORTION_PX` set to exactly zero."""
    corners = np.array([[0.0, 0.0], [cam.width - 1.0, 0.0], [0.0, cam.height - 1.0],
                        [cam.width - 1.0, cam.height - 1.0]])
    r = float(np.max(np.hypot((corners[:, 0] - cam.cx) / cam.fx,
                              (corners[:, 1] - cam.cy) / cam.fy)))
    f = max(abs(cam.fx), abs(cam.fy))
    # |displacement| per unit of each term at radius r: r^3, r^5, sqrt(10) r^2 (twice), r^7
    reach = (r ** 3, r ** 5, 3.2 * r * r, 3.2 * r * r, r ** 7)
    terms = tuple(0.0 if abs(c) * f * g <= NEGLIGIBLE_DISTORTION_PX else float(c)
                  for c, g in zip(cam.distortion, reach))
    if terms == tuple(cam.distortion):
        return cam
    return PinholeCamera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy, terms)


def to_pinhole(name: str, model: CahvorModel, width: int, height: int) -> PinholeCamera:
    """``model`` as a pinhole camera of ``width`` x ``height`` px (module docstring);
    ConfigError (naming ``name``) if it has none within :data:`MAX_RMS_PX`."""
    kind = model.kind.upper()
    try:
        fit = fit_pinhole(model, width, height)
    except ValueError as exc:
        raise _fail(name, f"the {kind} camera model cannot be used: {exc}") from None
    cam = without_negligible_distortion(fit.camera)
    if not (fit.rms_px <= MAX_RMS_PX):
        raise _fail(name, f"the {kind} camera model has no pinhole + OpenCV distortion "
                          f"equivalent: RMS reprojection error {fit.rms_px:.3g} px (max "
                          f"{fit.max_px:.3g} px) over the image, limit {MAX_RMS_PX:g} px; "
                          "monovo needs a camera close to a pinhole (not a fish-eye)")
    level = logging.WARNING if fit.rms_px > WARN_RMS_PX else logging.INFO
    log.log(level, "%s: %s camera as pinhole fx %.3f fy %.3f cx %.3f cy %.3f distortion %s; "
            "reprojection error RMS %.4f px, max %.4f px (%dx%d grid)", name, kind, cam.fx,
            cam.fy, cam.cx, cam.cy, " ".join(f"{c:.6g}" for c in cam.distortion), fit.rms_px,
            fit.max_px, FIT_GRID, FIT_GRID)
    return cam


def _build(name: str, kind: str, vectors: dict[str, list[float]], linearity: float,
           where: str) -> CahvorModel:
    args = {k: np.array(v, dtype=float) for k, v in vectors.items()}
    try:
        return CahvorModel(**args, linearity=linearity, kind=kind)
    except ValueError as exc:
        raise _fail(name, f"{where} is not a usable {kind.upper()} model: {exc}") from None


def camera_from_yaml(name: str, cam: dict) -> PinholeCamera:
    """The pinhole camera of init.yaml's ``camera: {model: cahv|cahvor|cahvore, ...}``."""
    kind = cam.get("model")
    if not isinstance(kind, str) or kind.strip().lower() not in MODELS:
        raise _fail(name, f"camera.model must be one of {', '.join(MODELS)}, got {_show(kind)}")
    kind = kind.strip().lower()
    names = VECTORS[kind]
    allowed = ("model", "width", "height", *names) + (("linearity",) if kind == "cahvore" else ())
    for key in cam:
        if key not in allowed:
            raise _fail(name, f"unknown key 'camera.{key}' for model {kind} "
                              f"(expected {', '.join(allowed)})")
    for key in ("width", "height", *names):
        if key not in cam:
            raise _fail(name, f"camera.{key} is missing (model {kind} needs width, height, "
                              f"{', '.join(names)})")
    width = _size(name, "camera.width", cam["width"])
    height = _size(name, "camera.height", cam["height"])
    vectors = {k: _vector(name, f"camera.{k}", cam[k]) for k in names}
    linearity = 1.0
    if kind == "cahvore":
        linearity = _number(name, "camera.linearity", cam.get("linearity", 1.0))
    return to_pinhole(name, _build(name, kind, vectors, linearity, "camera"), width, height)


def camera_from_label(name: str, path: Path) -> PinholeCamera:
    """The pinhole camera of the CAHV* model in a PDS product's label (``camera_file:``)."""
    from monovo_cli.io.pds_camera import read_camera_model

    try:
        found = read_camera_model(Path(path))
    except InputError as exc:
        raise ConfigError(f"{exc} (camera_file of {name})") from None
    if found.frame:
        log.info("%s: camera model of %s is in the %s frame", name, path, found.frame)
    model = _build(str(path), found.kind, found.vectors, found.linearity, "the label's camera model")
    return to_pinhole(str(path), model, found.width, found.height)
