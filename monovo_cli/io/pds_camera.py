"""The camera model in a PDS product's label: a PDS3 ``GEOMETRIC_CAMERA_MODEL*`` group
(``MODEL_TYPE`` CAHV, CAHVOR or CAHVORE, ``MODEL_COMPONENT_1..9``) or a PDS4
``geom:CAHV*_Model`` (``Vector_Center`` ... ``Entrance_Terms``, ``cahvore_model_type`` and
``cahvore_model_parameter``), read through :mod:`monovo_cli.io.pds`. CAHVORE's model type
gives its linearity: 1 perspective (1), 2 fish-eye (0), 3 general (the parameter).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from monovo_cli.errors import InputError
from monovo_cli.io.pds import label_value, open_product, product_image, walk_label


def _three(value: Any, what: str, path: Path) -> list[float]:
    if isinstance(value, Mapping):
        value = list(value.values())
    if isinstance(value, str):
        value = [v for v in re.split(r"[\s,()]+", value) if v]
    try:
        out = [float(str(v).split("<")[0]) for v in value]
    except (TypeError, ValueError):
        out = []
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise InputError(f"{path}: camera model {what} must be 3 numbers, got {value!r}")
    return out


@dataclass(frozen=True)
class LabelCamera:
    """A camera model found in a label: ``kind`` (cahv, cahvor, cahvore), its vectors
    ``C A H V O R E`` (lists of 3 floats, model frame), ``linearity``, the image size and the
    label's name of the model's frame (``None`` if it gives none)."""

    kind: str
    vectors: dict[str, list[float]]
    linearity: float
    width: int
    height: int
    frame: str | None


def _linearity(mtype: Any, mparm: Any, path: Path) -> float:
    """CAHVORE's linearity from its type (1 perspective, 2 fish-eye, 3 general) and parameter."""
    try:
        t = int(float(str(mtype))) if mtype is not None else 1
        p = float(str(mparm)) if mparm is not None else 0.0
    except ValueError:
        raise InputError(f"{path}: CAHVORE model type {mtype!r} / parameter {mparm!r} are not "
                         "numbers") from None
    if t == 1:
        return 1.0
    if t == 2:
        return 0.0
    if t == 3:
        return p
    raise InputError(f"{path}: CAHVORE model type {t} unknown (expected 1 perspective, "
                     "2 fish-eye or 3 general)")


def _pds3_camera(meta: Any, path: Path) -> tuple[str, dict, float, str | None] | None:
    group = None
    for key, value in walk_label(meta):
        if key.upper().startswith("GEOMETRIC_CAMERA_MODEL") and isinstance(value, Mapping):
            group = value
            break
    if group is None:
        return None
    kind = str(group.get("MODEL_TYPE", "")).strip().strip('"').upper()
    names = {"CAHV": "CAHV", "CAHVOR": "CAHVOR", "CAHVORE": "CAHVORE"}
    if kind not in names:
        raise InputError(f"{path}: camera model type {kind or 'missing'!r} is not supported "
                         "(expected CAHV, CAHVOR or CAHVORE)")
    vectors = {}
    for i, name in enumerate(kind, start=1):
        value = group.get(f"MODEL_COMPONENT_{i}")
        if value is None:
            raise InputError(f"{path}: camera model MODEL_COMPONENT_{i} ({name}) is missing")
        vectors[name] = _three(value, f"MODEL_COMPONENT_{i} ({name})", path)
    linearity = 1.0
    if kind == "CAHVORE":
        linearity = _linearity(group.get("MODEL_COMPONENT_8"), group.get("MODEL_COMPONENT_9"), path)
    frame = group.get("REFERENCE_COORD_SYSTEM_NAME")
    return kind.lower(), vectors, linearity, None if frame is None else str(frame)


_PDS4_VECTORS = {"C": "Vector_Center", "A": "Vector_Axis", "H": "Vector_Horizontal",
                 "V": "Vector_Vertical", "O": "Vector_Optical", "R": "Radial_Terms",
                 "E": "Entrance_Terms"}


def _pds4_camera(meta: Any, path: Path) -> tuple[str, dict, float, str | None] | None:
    for kind in ("CAHVORE", "CAHVOR", "CAHV"):
        block = label_value(meta, f"{kind}_Model")
        if isinstance(block, Mapping):
            break
    else:
        return None
    vectors = {}
    for name in kind:
        value = label_value(block, _PDS4_VECTORS[name])
        if value is None:
            raise InputError(f"{path}: camera model {kind}_Model has no {_PDS4_VECTORS[name]}")
        vectors[name] = _three(value, _PDS4_VECTORS[name], path)
    linearity = 1.0
    if kind == "CAHVORE":
        linearity = _linearity(label_value(block, "cahvore_model_type"),
                               label_value(block, "cahvore_model_parameter"), path)
    frame = label_value(meta, "coordinate_space_frame_type")
    return kind.lower(), vectors, linearity, None if frame is None else str(frame)


def read_camera_model(path: Path) -> LabelCamera:
    """The CAHV/CAHVOR/CAHVORE camera model of a product's label and its image size
    (from the image). InputError if the label has none or it is malformed."""
    path = Path(path)
    data = open_product(path)
    meta = data.metadata
    found = _pds3_camera(meta, path)
    if found is None:
        found = _pds4_camera(meta, path)
    if found is None:
        raise InputError(f"{path}: the label has no camera model (expected a PDS3 "
                         "GEOMETRIC_CAMERA_MODEL group or a PDS4 geom:CAHVOR_Model)")
    kind, vectors, linearity, frame = found
    height, width = product_image(data, path)[0].shape
    return LabelCamera(kind=kind, vectors=vectors, linearity=linearity, width=int(width),
                       height=int(height), frame=frame)
