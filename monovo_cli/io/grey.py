"""Grey images from pixels: the one rule for every frame source, masks and textures.

Whatever a file or a container holds -- 8/16 bit or float, grey, grey+alpha, BGR(A) or a
palette -- becomes an (H, W) float32 grey image on monovo's 0..255 scale: 16-bit samples
scaled by 255/65535, float ones on 0..1 by 255, colour by the luma weights
0.299 R + 0.587 G + 0.114 B (alpha ignored). Every problem is an
:class:`~monovo_cli.errors.InputError` with one line naming the file.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.quiet import quiet_native_stderr

_CANNOT_DECODE = "cannot decode image (empty, truncated or not an image)"


def grey_from_float(values: np.ndarray, path: Path, what: str, hint: str) -> np.ndarray:
    """float32 on monovo's 0..255 scale from float ``values`` on 0..1 (scaled by 255) or
    0..255 (kept). ``what`` names them in errors ("float image", "float product"); ``hint``
    says what to use instead. Raises InputError for NaN/inf or any other range."""
    f = values.astype(np.float32)
    if not np.all(np.isfinite(f)):
        raise InputError(f"{path}: {what} contains NaN or infinite pixels")
    lo, hi = float(f.min()), float(f.max())
    if lo >= 0.0 and hi <= 1.0:
        return f * np.float32(255.0)
    if not (lo >= 0.0 and hi <= 255.0):
        raise InputError(f"{path}: {what} values span [{lo:g}, {hi:g}]; expected 0..1 or 0..255 "
                         f"({hint})")
    return f


def grey_from_pixels(img: np.ndarray, path: Path) -> np.ndarray:
    """(H, W) float32 grey on a 0..255 scale from an array in OpenCV's layout -- (H, W),
    (H, W, 1), (H, W, 2) grey+alpha, (H, W, 3/4) BGR[A] -- of uint8, uint16 or float pixels
    (what cv2.IMREAD_UNCHANGED returns); ``path`` names the source in errors."""
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (2, 3, 4)):
        raise InputError(f"{path}: unsupported image layout {img.shape} "
                         "(use grey, grey+alpha, colour or colour+alpha images)")
    if img.dtype == np.uint8:
        f = img.astype(np.float32)
    elif img.dtype == np.uint16:
        f = img.astype(np.float32) * np.float32(255.0 / 65535.0)
    elif img.dtype in (np.float32, np.float64):
        f = grey_from_float(img, path, "float image", "or use 8/16-bit images")
    else:
        raise InputError(f"{path}: unsupported pixel type {img.dtype} "
                         "(use 8- or 16-bit unsigned, or float, images)")
    if f.ndim == 3:
        channels = f.shape[2]
        if channels == 2:  # grey + alpha
            f = f[:, :, 0]
        else:  # usual luma weights 0.299 R + 0.587 G + 0.114 B, alpha ignored
            code = cv2.COLOR_BGR2GRAY if channels == 3 else cv2.COLOR_BGRA2GRAY
            f = cv2.cvtColor(np.ascontiguousarray(f), code)
    return np.ascontiguousarray(f, dtype=np.float32)


def decode_gray(data: bytes | np.ndarray, path: Path) -> np.ndarray:
    """Decode encoded image bytes (any format cv2 reads) to float32 grey; ``path`` names
    the source in errors."""
    buf = np.frombuffer(data, dtype=np.uint8) if isinstance(data, (bytes, bytearray)) else data
    if buf.size == 0:
        raise InputError(f"{path}: {_CANNOT_DECODE}")
    with quiet_native_stderr():
        try:
            img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
        except (cv2.error, MemoryError, ValueError, OverflowError):
            img = None
    if img is None or img.size == 0:
        raise InputError(f"{path}: {_CANNOT_DECODE}")
    return grey_from_pixels(img, path)


def read_gray(path: Path) -> np.ndarray:
    """Read one image file as a (H, W) float32 grey image on a 0..255 scale
    (16-bit scaled by 255/65535, float 0..1 by 255). Works with non-ASCII paths."""
    path = Path(path)
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise InputError(f"{path}: cannot read image ({reason})") from None
    return decode_gray(data, path)
