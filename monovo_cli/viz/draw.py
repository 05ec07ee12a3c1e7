"""Drawing primitives of the overlay: BGR frames, anti-aliased polygons and dots at 1/16 px,
residual colours, a text line.

Pixel centres are integers (docs/guide.md "Conventions"); coordinates are drawn with
``SHIFT`` fractional bits. Pure: arrays in, arrays out.
"""

from __future__ import annotations

import cv2
import numpy as np

SHIFT = 4                 # fractional bits of the drawing coordinates (1/16 px)


def to_bgr(image: np.ndarray) -> np.ndarray:
    """A grey float image (H, W) on 0..255 (or an 8-bit grey / BGR image) as BGR uint8 (H, W, 3)."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.ndim == 3 and img.shape[2] == 3:
        return img.copy()
    raise ValueError(f"expected a (H, W) or (H, W, 3) image, got shape {img.shape}")


def draw_polygon(img: np.ndarray, uv: np.ndarray, *, fill: tuple[int, int, int],
                 outline: tuple[int, int, int], alpha: float, thickness: int) -> None:
    """Draw the polygon ``uv`` (N, 2) px into ``img`` (H, W, 3) uint8 in place: filled with
    opacity ``alpha`` and outlined, both anti-aliased at 1/16 px."""
    if len(uv) < 3:
        return
    h, w = img.shape[:2]
    scale = 1 << SHIFT
    pts = np.round(np.asarray(uv) * scale).astype(np.int32)
    pad = thickness + 2
    x0 = max(int(np.floor(uv[:, 0].min())) - pad, 0)
    y0 = max(int(np.floor(uv[:, 1].min())) - pad, 0)
    x1 = min(int(np.ceil(uv[:, 0].max())) + pad + 1, w)
    y1 = min(int(np.ceil(uv[:, 1].max())) + pad + 1, h)
    if x0 >= x1 or y0 >= y1:
        return
    roi = img[y0:y1, x0:x1]
    layer = roi.copy()
    local = (pts - np.array([x0 * scale, y0 * scale], dtype=np.int32)).reshape(-1, 1, 2)
    cv2.fillPoly(layer, [local], fill, cv2.LINE_AA, SHIFT)
    cv2.addWeighted(layer, alpha, roi, 1.0 - alpha, 0.0, dst=roi)
    cv2.polylines(img, [pts.reshape(-1, 1, 2)], True, outline, thickness, cv2.LINE_AA, SHIFT)


def residual_colours(r: np.ndarray, bound: float) -> np.ndarray:
    """BGR colours (N, 3) uint8 of residuals ``r`` (N,): green at 0, yellow at ``bound / 2``,
    red at ``bound`` and above."""
    s = np.clip(np.abs(r) / max(bound, 1e-9), 0.0, 1.0)
    g = np.clip(2.0 * (1.0 - s), 0.0, 1.0) * 255
    red = np.clip(2.0 * s, 0.0, 1.0) * 255
    return np.stack([np.zeros_like(s), g, red], 1).astype(np.uint8)


def draw_text(img: np.ndarray, text: str, colour: tuple[int, int, int]) -> None:
    """One line of text in the top-left corner of ``img`` on a dark band, in place."""
    h, w = img.shape[:2]
    scale = max(0.35, min(w, h) / 700.0)
    thick = 1 if scale < 0.8 else 2
    font = cv2.FONT_HERSHEY_SIMPLEX
    (tw, th), base = cv2.getTextSize(text, font, scale, thick)
    pad = max(2, int(round(4 * scale)))
    x1, y1 = min(w, tw + 2 * pad), min(h, th + base + 2 * pad)
    band = img[0:y1, 0:x1]
    cv2.addWeighted(band, 0.4, np.zeros_like(band), 0.6, 0.0, dst=band)
    cv2.putText(img, text, (pad, pad + th), font, scale, colour, thick, cv2.LINE_AA)
