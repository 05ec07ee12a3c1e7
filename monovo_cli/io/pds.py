"""Planetary Data System products as frames: PDS3 ``.IMG`` (attached or detached ``.LBL``
label) and PDS4 (``.xml`` label beside its data file), read through ``pdr``.

Why ``pdr`` (the Planetary Data Reader of Million Concepts): one maintained, pure-Python reader
for both PDS3 and PDS4 (it bundles the PDS4 tools), which follows the labels' pointers,
record layouts, line prefixes and byte orders as the archive's own software does. It pulls
in pandas, so it is an optional extra (``pip install monovo[pds]``), imported only when a
sequence holds products.

What a product gives (:class:`PdsFrame`):

- the grey image, float32 on monovo's 0..255 scale. Integer samples keep the bits the label
  declares valid (PDS3 ``SAMPLE_BIT_MASK``, else ``SAMPLE_BITS``; PDS4 ``img:sample_bit_mask``
  or ``img:sample_bits``; else the storage size) and **b-bit samples are divided by
  2^(b - 8)**: a 12-bit MER/MSL sample by 16, so that its top 8 bits are the 8-bit grey
  level and msd, thresholds and the overlay mean what they mean for an 8-bit frame. Data
  of 8 bits or fewer is taken as is. Float samples must lie in 0..1 (scaled by 255) or
  0..255. A 3-band product is made grey with the luma weights of colour frames (bands R, G,
  B). Raw DNs are used: the label's scaling factor and offset (physical units) are not.
- its time, seconds since 1970-01-01 UTC (leap seconds ignored), from PDS3 ``START_TIME``
  (else ``IMAGE_TIME``) or PDS4 ``start_date_time``; None when the label has none.
- its camera model (:func:`read_camera_model`), from a PDS3 ``GEOMETRIC_CAMERA_MODEL*``
  group or a PDS4 ``geom:CAHV*_Model``.

Every problem is an :class:`~monovo_cli.errors.InputError` with one line naming the file.
"""

from __future__ import annotations

import calendar
import contextlib
import io
import math
import re
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from monovo_cli.errors import InputError

#: Extensions of PDS products (case-insensitive): PDS3 data with attached or detached label,
#: PDS3 detached labels, PDS4 labels.
PDS_DATA_EXTENSIONS = (".img",)
PDS_LABEL_EXTENSIONS = (".lbl", ".xml")
PDS_EXTENSIONS = PDS_DATA_EXTENSIONS + PDS_LABEL_EXTENSIONS
_PDS4_ROOT = b"<Product_Observational"
_LUMA = (0.299, 0.587, 0.114)
_NO_VALUE = {"", "N/A", "NULL", "UNK", "UNKNOWN", "NONE"}
_TIME_RE = re.compile(
    r"(?P<y>\d{4})-(?:(?P<m>\d{2})-(?P<d>\d{2})|(?P<doy>\d{3}))"
    r"(?:T(?P<H>\d{2}):(?P<M>\d{2})(?::(?P<S>\d{2}(?:\.\d*)?))?)?Z?")


@dataclass(frozen=True)
class PdsFrame:
    """One product: ``image`` (H, W) float32 grey 0..255, ``bits`` its significant bits,
    ``timestamp`` seconds (UTC, Unix epoch) or None, ``path`` the file it was read from."""

    image: np.ndarray
    bits: int
    timestamp: float | None
    path: Path


def _pdr():
    try:
        import pdr
    except ImportError:
        raise InputError("reading PDS products needs the 'pdr' package: "
                         "pip install 'monovo[pds]' (or pip install pdr)") from None
    return pdr


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:120]}" if text else type(exc).__name__


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """pdr's warnings and prints stay off the user's terminal (errors still raise)."""
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        yield


def is_pds4_label(path: Path) -> bool:
    """True when ``path`` (an ``.xml`` file) is a PDS4 observational product's label."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    return _PDS4_ROOT in head


def _open(path: Path):
    pdr = _pdr()
    try:
        with _quiet():
            return pdr.read(str(path))
    except Exception as exc:  # pdr raises many kinds; each is one bad file
        raise InputError(f"{path}: cannot read the PDS product ({_reason(exc)})") from None


def _local(key: Any) -> str:
    return str(key).rsplit(":", 1)[-1]


def _walk(block: Any) -> Iterator[tuple[str, Any]]:
    """Every (local key, value) of a label, depth first, in label order."""
    if isinstance(block, Mapping):
        for key, value in block.items():
            yield _local(key), value
            yield from _walk(value)
    elif isinstance(block, (list, tuple)):
        for item in block:
            if isinstance(item, (Mapping, list, tuple)):
                yield from _walk(item)


def _first(block: Any, *names: str, skip: tuple[str, ...] = ()) -> Any:
    """The first value whose local key is one of ``names`` (case-insensitive), outside the
    blocks named in ``skip``."""
    wanted = {n.lower() for n in names}
    skipped = {n.lower() for n in skip}

    def search(b: Any) -> Any:
        if isinstance(b, Mapping):
            for key, value in b.items():
                name = _local(key).lower()
                if name in skipped:
                    continue
                if name in wanted:
                    return value
                found = search(value)
                if found is not None:
                    return found
        elif isinstance(b, (list, tuple)):
            for item in b:
                if isinstance(item, (Mapping, list, tuple)):
                    found = search(item)
                    if found is not None:
                        return found
        return None

    return search(block)


def parse_time(value: Any) -> float | None:
    """Seconds since 1970-01-01 UTC of a PDS time (``2004-01-15T10:20:30.25Z`` or day of year
    ``2004-015T10:20:30.25``); None for no value (``N/A``, ``UNK``, ...) or another form."""
    if value is None:
        return None
    text = str(value).strip().strip('"').strip()
    if text.upper() in _NO_VALUE:
        return None
    m = _TIME_RE.fullmatch(text)
    if m is None:
        return None
    year = int(m["y"])
    if m["doy"] is not None:
        day_of_year = int(m["doy"])
        if not 1 <= day_of_year <= (366 if calendar.isleap(year) else 365):
            return None
        days = calendar.timegm((year, 1, 1, 0, 0, 0)) // 86400 + day_of_year - 1
        midnight = days * 86400
    else:
        month, day = int(m["m"]), int(m["d"])
        if not (1 <= month <= 12 and 1 <= day <= calendar.monthrange(year, month)[1]):
            return None
        midnight = calendar.timegm((year, month, day, 0, 0, 0))
    hours, minutes = int(m["H"] or 0), int(m["M"] or 0)
    seconds = float(m["S"] or 0.0)
    if hours > 23 or minutes > 59 or seconds >= 61.0:
        return None
    return float(midnight + 3600 * hours + 60 * minutes) + seconds


def _label_time(meta: Any) -> float | None:
    for key in ("START_TIME", "IMAGE_TIME", "start_date_time"):
        t = parse_time(_first(meta, key))
        if t is not None:
            return t
    return None


def _bits_from_mask(value: Any) -> int | None:
    """Number of significant bits of a PDS bit mask (an int, or text ``2#0000111111111111#``)."""
    if value is None:
        return None
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        mask = int(value)
    else:
        text = str(value).strip().strip("#")
        base, _, digits = text.partition("#")
        try:
            mask = int(digits.strip("#"), int(base)) if digits else int(text)
        except ValueError:
            return None
    return mask.bit_length() if mask > 0 else None


def _declared_bits(meta: Any, storage_bits: int) -> int:
    """Significant bits of the samples (see the module docstring)."""
    skip = ("Commanded_Parameters",)
    for key in ("SAMPLE_BIT_MASK", "sample_bit_mask"):
        b = _bits_from_mask(_first(meta, key, skip=skip))
        if b is not None:
            return min(b, storage_bits)
    for key in ("SAMPLE_BITS", "sample_bits"):
        value = _first(meta, key, skip=skip)
        try:
            b = int(float(str(value))) if value is not None else None
        except ValueError:
            b = None
        if b is not None and 0 < b:
            return min(b, storage_bits)
    return storage_bits


def _image_array(data: Any, path: Path) -> np.ndarray:
    """The product's image: the ``IMAGE`` object (PDS3) or the first 2-D/3-D image array."""
    keys = [k for k in data.keys() if str(k).upper() != "LABEL"]
    preferred = [k for k in keys if str(k).upper() == "IMAGE"]
    others = [k for k in keys if k not in preferred and "HEADER" not in str(k).upper()
              and "TABLE" not in str(k).upper()]
    for key in preferred + others:
        try:
            with _quiet():
                arr = data[key]
        except Exception as exc:
            if key in preferred:
                raise InputError(f"{path}: cannot read the image of the PDS product "
                                 f"({_reason(exc)})") from None
            continue
        if isinstance(arr, np.ndarray) and arr.ndim in (2, 3) and arr.size > 0:
            return arr
    raise InputError(f"{path}: no image in the PDS product (expected an IMAGE object or an "
                     "Array_2D_Image / Array_3D_Image)")


def _to_gray(arr: np.ndarray, bits: int, path: Path) -> np.ndarray:
    if arr.ndim == 3:
        if arr.shape[0] == 1:
            arr = arr[0]
        elif arr.shape[0] == 3:
            pass
        elif arr.shape[2] in (1, 3) and arr.shape[0] > 4:  # band-interleaved-by-pixel
            arr = np.moveaxis(arr, 2, 0)
            if arr.shape[0] == 1:
                arr = arr[0]
        else:
            raise InputError(f"{path}: image has {arr.shape[0]} bands; expected 1 (grey) or 3 "
                             "(R, G, B)")
    if np.ma.isMaskedArray(arr):
        arr = np.ma.getdata(arr)
    if arr.dtype.kind in "ui":
        a = arr.astype(np.int64)
        if a.min(initial=0) < 0 and bits >= arr.dtype.itemsize * 8:
            raise InputError(f"{path}: signed samples below 0 (min {int(a.min())}); expected "
                             "raw counts (an EDR), not a calibrated product")
        a &= (1 << bits) - 1
        scale = 1.0 if bits <= 8 else 2.0 ** (8 - bits)
        f = a.astype(np.float32) * np.float32(scale)
    elif arr.dtype.kind == "f":
        f = arr.astype(np.float32)
        if not np.all(np.isfinite(f)):
            raise InputError(f"{path}: float image contains NaN or infinite samples")
        lo, hi = float(f.min()), float(f.max())
        if lo >= 0.0 and hi <= 1.0:
            f = f * np.float32(255.0)
        elif not (lo >= 0.0 and hi <= 255.0):
            raise InputError(f"{path}: float samples span [{lo:g}, {hi:g}]; expected 0..1 or "
                             "0..255 (use raw counts, an EDR)")
    else:
        raise InputError(f"{path}: unsupported sample type {arr.dtype} (expected integer or "
                         "float samples)")
    if f.ndim == 3:
        f = (np.float32(_LUMA[0]) * f[0] + np.float32(_LUMA[1]) * f[1]
             + np.float32(_LUMA[2]) * f[2])
    return np.ascontiguousarray(f, dtype=np.float32)


def read_product(path: Path) -> PdsFrame:
    """Read one PDS3/PDS4 product (module docstring); InputError if it cannot be used."""
    path = Path(path)
    data = _open(path)
    arr = _image_array(data, path)
    storage = arr.dtype.itemsize * 8
    bits = _declared_bits(data.metadata, storage) if arr.dtype.kind in "ui" else storage
    return PdsFrame(image=_to_gray(arr, bits, path), bits=bits,
                    timestamp=_label_time(data.metadata), path=path)


def read_label_time(path: Path) -> float | None:
    """The time (s, UTC, Unix epoch) a product's label gives, without reading its image."""
    return _label_time(_open(Path(path)).metadata)


# ----------------------------------------------------------------------------- camera model


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
    for key, value in _walk(meta):
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
        block = _first(meta, f"{kind}_Model")
        if isinstance(block, Mapping):
            break
    else:
        return None
    vectors = {}
    for name in kind:
        value = _first(block, _PDS4_VECTORS[name])
        if value is None:
            raise InputError(f"{path}: camera model {kind}_Model has no {_PDS4_VECTORS[name]}")
        vectors[name] = _three(value, _PDS4_VECTORS[name], path)
    linearity = 1.0
    if kind == "CAHVORE":
        linearity = _linearity(_first(block, "cahvore_model_type"),
                               _first(block, "cahvore_model_parameter"), path)
    frame = _first(meta, "coordinate_space_frame_type")
    return kind.lower(), vectors, linearity, None if frame is None else str(frame)


def read_camera_model(path: Path) -> LabelCamera:
    """The CAHV/CAHVOR/CAHVORE camera model of a product's label and its image size
    (from the image). InputError if the label has none or it is malformed."""
    path = Path(path)
    data = _open(path)
    meta = data.metadata
    found = _pds3_camera(meta, path)
    if found is None:
        found = _pds4_camera(meta, path)
    if found is None:
        raise InputError(f"{path}: the label has no camera model (expected a PDS3 "
                         "GEOMETRIC_CAMERA_MODEL group or a PDS4 geom:CAHVOR_Model)")
    kind, vectors, linearity, frame = found
    arr = _image_array(data, path)
    bits = _declared_bits(meta, arr.dtype.itemsize * 8) if arr.dtype.kind in "ui" else 32
    height, width = _to_gray(arr, bits, path).shape
    return LabelCamera(kind=kind, vectors=vectors, linearity=linearity, width=int(width),
                       height=int(height), frame=frame)
