"""Grey levels from decoded float pixels: the one rule for images and PDS products alike."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError


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
