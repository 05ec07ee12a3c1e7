"""Gaussian image pyramids (cv2.pyrDown: 5-tap binomial filter, then every other pixel).

Level l has the camera ``PinholeCamera.scaled(l)``: pyrDown keeps the even pixels of the
smoothed image, so pixel x_l of level l is pixel x_0 = 2^l x_l of level 0.
"""

from __future__ import annotations

import cv2
import numpy as np


def num_levels(width: int, height: int, *, min_size: int = 32, max_levels: int = 6) -> int:
    """How many pyramid levels a ``width`` x ``height`` px image gets: halving until the
    smaller side would drop below ``min_size`` px, at most ``max_levels`` (level 0 counted)."""
    n, w, h = 1, width, height
    while n < max_levels and min((w + 1) // 2, (h + 1) // 2) >= min_size:
        w, h = (w + 1) // 2, (h + 1) // 2
        n += 1
    return n


def build_pyramid(image: np.ndarray, levels: int) -> list[np.ndarray]:
    """``levels`` float32 images, finest first; ``image`` (H, W) grey."""
    return extend_pyramid([np.ascontiguousarray(image, dtype=np.float32)], levels)


def extend_pyramid(pyramid: list[np.ndarray], levels: int) -> list[np.ndarray]:
    """``pyramid`` (finest first, float32) with at least ``levels`` levels: the coarser ones
    missing made from its coarsest, as :func:`build_pyramid` makes them. A keyframe built on
    another frame can keep more levels than the one a frame's pyramid was built for (its
    coarse levels kept where the first's were too sparse)."""
    pyr = list(pyramid)
    while len(pyr) < levels:
        pyr.append(cv2.pyrDown(pyr[-1], borderType=cv2.BORDER_REPLICATE))
    return pyr
