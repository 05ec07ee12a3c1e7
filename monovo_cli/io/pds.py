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
- its camera model (:mod:`monovo_cli.io.pds_camera`), from a PDS3
  ``GEOMETRIC_CAMERA_MODEL*`` group or a PDS4 ``geom:CAHV*_Model``.

Every problem is an :class:`~monovo_cli.errors.InputError` with one line naming the file.
"""

from __future__ import annotations

import calendar
import contextlib
import io
import re
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.grey import grey_from_float

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


def open_product(path: Path):
    pdr = _pdr()
    try:
        with _quiet():
            return pdr.read(str(path))
    except Exception as exc:  # pdr raises many kinds; each is one bad file
        raise InputError(f"{path}: cannot read the PDS product ({_reason(exc)})") from None


def _local(key: Any) -> str:
    return str(key).rsplit(":", 1)[-1]


def walk_label(block: Any) -> Iterator[tuple[str, Any]]:
    """Every (local key, value) of a label, depth first, in label order."""
    if isinstance(block, Mapping):
        for key, value in block.items():
            yield _local(key), value
            yield from walk_label(value)
    elif isinstance(block, (list, tuple)):
        for item in block:
            if isinstance(item, (Mapping, list, tuple)):
                yield from walk_label(item)


def label_value(block: Any, *names: str, skip: tuple[str, ...] = ()) -> Any:
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
        t = parse_time(label_value(meta, key))
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


def declared_bits(meta: Any, storage_bits: int) -> int:
    """Significant bits of the samples (see the module docstring)."""
    skip = ("Commanded_Parameters",)
    for key in ("SAMPLE_BIT_MASK", "sample_bit_mask"):
        b = _bits_from_mask(label_value(meta, key, skip=skip))
        if b is not None:
            return min(b, storage_bits)
    for key in ("SAMPLE_BITS", "sample_bits"):
        value = label_value(meta, key, skip=skip)
        try:
            b = int(float(str(value))) if value is not None else None
        except ValueError:
            b = None
        if b is not None and 0 < b:
            return min(b, storage_bits)
    return storage_bits


def image_array(data: Any, path: Path) -> np.ndarray:
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


def to_gray(arr: np.ndarray, bits: int, path: Path) -> np.ndarray:
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
        f = grey_from_float(arr, path, "float product", "use raw counts, an EDR")
    else:
        raise InputError(f"{path}: unsupported sample type {arr.dtype} (expected integer or "
                         "float samples)")
    if f.ndim == 3:
        f = (np.float32(_LUMA[0]) * f[0] + np.float32(_LUMA[1]) * f[1]
             + np.float32(_LUMA[2]) * f[2])
    return np.ascontiguousarray(f, dtype=np.float32)


def product_image(data: Any, path: Path) -> tuple[np.ndarray, int]:
    """The grey image (H, W) float32 0..255 of an opened product and its significant bits."""
    arr = image_array(data, path)
    storage = arr.dtype.itemsize * 8
    bits = declared_bits(data.metadata, storage) if arr.dtype.kind in "ui" else storage
    return to_gray(arr, bits, path), bits


def read_product(path: Path) -> PdsFrame:
    """Read one PDS3/PDS4 product (module docstring); InputError if it cannot be used."""
    path = Path(path)
    data = open_product(path)
    image, bits = product_image(data, path)
    return PdsFrame(image=image, bits=bits, timestamp=_label_time(data.metadata), path=path)


def read_label_time(path: Path) -> float | None:
    """The time (s, UTC, Unix epoch) a product's label gives, without reading its image."""
    return _label_time(open_product(Path(path)).metadata)


def label_times(paths: list[Path], times_file: str) -> np.ndarray | None:
    """The products' label times (s), None when no label has one; InputError when only some
    have one or they do not increase (``times_file`` then gives the timestamps)."""
    times = [read_label_time(p) for p in paths]
    if all(t is None for t in times):
        return None
    fix = f"give the timestamps in {times_file} (one line per frame) instead"
    for p, t in zip(paths, times):
        if t is None:
            raise InputError(f"{p}: the label has no START_TIME / start_date_time but others "
                             f"have; {fix}")
    for k in range(1, len(times)):
        if times[k] <= times[k - 1]:
            raise InputError(f"{paths[k]}: label time {times[k]!r} s does not follow "
                             f"{paths[k - 1].name}'s {times[k - 1]!r} s; {fix}")
    return np.array(times, dtype=float)


_REFERENCE = re.compile(rb'<file_name>\s*([^<]+?)\s*</file_name>|\^\w+\s*=\s*\(?\s*"([^"]+)"')


def list_products(directory: Path) -> list[Path]:
    """The PDS products of a directory (unsorted): PDS3 detached labels (``.LBL``), PDS4
    labels (``.xml`` of a ``Product_Observational``) and the ``.IMG`` files no label names
    (their label is attached). Hidden files are skipped; dangling links count."""
    try:
        entries = [p for p in directory.iterdir() if not p.name.startswith(".")
                   and p.name.lower().endswith(PDS_EXTENSIONS)
                   and (p.is_file() or (p.is_symlink() and not p.exists()))]
    except OSError as exc:
        raise InputError(f"{directory}: cannot list the directory ({exc.strerror or exc})") from None
    labels = [p for p in entries if p.suffix.lower() in PDS_LABEL_EXTENSIONS
              and (p.suffix.lower() != ".xml" or is_pds4_label(p))]
    named = {p.stem.casefold() for p in labels}
    for label in labels:
        try:
            with open(label, "rb") as f:
                head = f.read(1 << 16)
        except OSError:
            continue
        for m in _REFERENCE.finditer(head):
            ref = (m.group(1) or m.group(2)).decode("utf-8", "replace")
            named.update((ref.casefold(), Path(ref).stem.casefold()))
    return labels + [p for p in entries if p.suffix.lower() in PDS_DATA_EXTENSIONS
                     and p.stem.casefold() not in named and p.name.casefold() not in named]
