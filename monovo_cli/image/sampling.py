"""Sampling an image at sub-pixel positions with OpenCV's remap (bilinear, bicubic, Lanczos-4).
"""

from __future__ import annotations

import cv2
import numpy as np

GRID_COLUMNS = 1024  # remap maps are (rows, GRID_COLUMNS): OpenCV limits a map side to 32767

INTERPOLATION = {"linear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC, "lanczos4": cv2.INTER_LANCZOS4}


# Bilinear and bicubic samples: outside the image the frame is OUTSIDE, so a sample that
# gives a pixel outside any weight above 1e-25 (a bicubic weight is ~f or ~f^2 for the
# sample's fraction f, and f is 0 or >= ~1e-7 in float32 away from the origin) comes out far
# above any grey level and is invalid; where it is valid it equals the sample with any border.
# (OUTSIDE times the kernel's absolute weights stays below float32's largest value.) A NaN
# border would say the same, but OpenCV 5's bicubic remap spreads a NaN border to
# neighbouring outputs; checking the positions against the kernel's reach is a second pass
# over the grid, a large share of the remap's own time (docs/algorithm.md section 3,
# "Interpolation"). OpenCV's Lanczos-4 remap does not keep a constant border apart (it
# returns wrong values beside it), so its validity comes from the positions: the kernel's
# reach, px left/up and right/down of the sample's cell.
OUTSIDE = 1e37
_VALID_BELOW = 1e12  # |sample| below this: no pixel outside the image was weighted
_REACH = {cv2.INTER_LANCZOS4: (3, 4)}


def sample_at(image: np.ndarray, grid: np.ndarray, n: int, flag: int) -> tuple[np.ndarray, np.ndarray]:
    """``image`` (H, W) float32 interpolated at the first ``n`` positions of ``grid``.

    ``grid`` (rows, GRID_COLUMNS, 2) float32 holds pixel positions (u, v), row-major. Returns
    the values (n,) float32 (0 where invalid) and the validity (n,) bool: every pixel the
    kernel weights inside the image (points within a few pixels of the border are dropped).
    A stack of planes (H, W, C) (an image and its gradients) is sampled in the same pass,
    values (n, C): OpenCV weights every plane alike, and the first plane's border says
    which are valid.
    """
    planes = image.shape[2:]  # (): one plane; (C,): a stack
    if flag in _REACH:
        lo, hi = _REACH[flag]
        h, w = image.shape[:2]
        valid = cv2.inRange(grid, (lo, lo), (w - 1 - hi, h - 1 - hi)).reshape(-1)[:n] != 0
        vals = cv2.remap(image, grid, None, flag,
                         borderMode=cv2.BORDER_REPLICATE).reshape((-1,) + planes)[:n]
    else:
        vals = cv2.remap(image, grid, None, flag, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=OUTSIDE).reshape((-1,) + planes)[:n]
        valid = np.abs(vals[:, 0] if planes else vals) < _VALID_BELOW
    vals *= valid[:, None] if planes else valid
    return vals, valid


def pixel_grid(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Positions (u, v) (N,) packed into a remap grid (rows, GRID_COLUMNS, 2) float32.

    The padding, and positions that are not finite, sit far outside every image (invalid).
    """
    n = len(u)
    out = np.empty((max(1, -(-n // GRID_COLUMNS)), GRID_COLUMNS, 2), np.float32)
    flat = out.reshape(-1, 2)
    flat[:n, 0] = u
    flat[:n, 1] = v
    flat[n:] = -1e6
    np.nan_to_num(flat, copy=False, nan=-1e6, posinf=-1e6, neginf=-1e6)
    return out


def sample_bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear interpolation of ``image`` (H, W) float32 at pixels (u, v) (N,): values (N,)
    float32 (0 where invalid) and validity (N,) bool (inside [0, W-1] x [0, H-1]); a stack
    (H, W, C) gives values (N, C), one remap for all its planes (:func:`sample_at`). OpenCV
    5's bilinear remap does not round the positions (no 1/32 px quantisation)."""
    return sample_at(np.ascontiguousarray(image, dtype=np.float32), pixel_grid(u, v), len(u),
                     cv2.INTER_LINEAR)
