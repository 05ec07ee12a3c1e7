"""The height map of the driven strip as an image with a colour bar, drawn with OpenCV.

Cells of a :class:`~monovo_cli.mapping.terrain_map.HeightGrid` (ground frame of init.yaml's
plane: right, forward, m) are coloured by height (viridis, over the 1st to 99th percentile
of the heights, so that a few wild cells do not wash the rest out), empty cells white;
forward is up, equal scale on both axes, the camera path (optional) drawn over it.

Pure: arrays in, a BGR uint8 image out.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from monovo_cli.mapping.terrain_map import HeightGrid
from monovo_cli.viz.plots import AXIS, BACKGROUND, FONT, label, nice_step

PATH = (40, 40, 40)


def height_range(grid: HeightGrid) -> tuple[float, float]:
    """The colour scale's ``(low, high)`` heights, m: the 1st and 99th percentiles."""
    h = grid.height[np.isfinite(grid.height)]
    if not len(h):
        return 0.0, 1.0
    lo, hi = (float(v) for v in np.percentile(h, [1.0, 99.0]))
    return (lo, hi) if hi > lo else (lo - 0.005, lo + 0.005)


def plot_height_map(grid: HeightGrid, *, path: np.ndarray | None = None,
                    title: str | None = None, size: tuple[int, int] = (900, 800)) -> np.ndarray:
    """The height map (H, W, 3) BGR uint8 of ``grid``; ``path`` (N, 2) the camera's (right,
    forward) positions in the ground frame, m."""
    w, h = size
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    text = max(0.4, w / 1800.0)
    bar_w = int(0.14 * w)
    left, right_m, top, bottom = int(0.1 * w), bar_w + int(0.03 * w), int(0.08 * h), int(0.09 * h)
    pw, ph = w - left - right_m, h - top - bottom
    gh, gw = grid.height.shape
    if gh == 0 or gw == 0:
        cv2.putText(img, "no terrain points", (left, h // 2), FONT, text, AXIS, 1, cv2.LINE_AA)
        return img
    ext_x, ext_y = gw * grid.cell, gh * grid.cell
    s = min(pw / ext_x, ph / ext_y)  # px per metre
    ox = left + 0.5 * (pw - s * ext_x)
    oy = top + 0.5 * (ph - s * ext_y)
    lo, hi = height_range(grid)
    norm = np.clip((grid.height - lo) / (hi - lo), 0.0, 1.0)
    colours = cv2.applyColorMap(np.nan_to_num(norm * 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    colours[~np.isfinite(grid.height)] = BACKGROUND
    colours = colours[::-1]  # forward is up
    x0, y0 = int(round(ox)), int(round(oy))
    x1, y1 = int(round(ox + s * ext_x)), int(round(oy + s * ext_y))
    img[y0:y1, x0:x1] = cv2.resize(colours, (x1 - x0, y1 - y0), interpolation=cv2.INTER_NEAREST)
    cv2.rectangle(img, (x0, y0), (x1, y1), AXIS, 1)
    step = nice_step(max(ext_x, ext_y))
    for i in range(math.ceil(grid.x0 / step), math.floor((grid.x0 + ext_x) / step) + 1):
        x = int(round(ox + (i * step - grid.x0) * s))
        lab = label(i * step, step)
        (tw, th), _ = cv2.getTextSize(lab, FONT, text, 1)
        cv2.line(img, (x, y1), (x, y1 + 5), AXIS, 1)
        cv2.putText(img, lab, (x - tw // 2, y1 + th + 9), FONT, text, AXIS, 1, cv2.LINE_AA)
    for i in range(math.ceil(grid.y0 / step), math.floor((grid.y0 + ext_y) / step) + 1):
        y = int(round(oy + (grid.y0 + ext_y - i * step) * s))
        lab = label(i * step, step)
        (tw, th), _ = cv2.getTextSize(lab, FONT, text, 1)
        cv2.line(img, (x0 - 5, y), (x0, y), AXIS, 1)
        cv2.putText(img, lab, (x0 - tw - 9, y + th // 2), FONT, text, AXIS, 1, cv2.LINE_AA)
    (tw, th), _ = cv2.getTextSize("right (m)", FONT, text, 1)
    cv2.putText(img, "right (m)", ((x0 + x1 - tw) // 2, h - 10), FONT, text, AXIS, 1, cv2.LINE_AA)
    cv2.putText(img, "forward (m)", (4, max(th + 4, y0 - 10)), FONT, text, AXIS, 1, cv2.LINE_AA)
    if path is not None and len(path) > 1:
        p = np.stack([ox + (path[:, 0] - grid.x0) * s,
                      oy + (grid.y0 + ext_y - path[:, 1]) * s], 1)
        cv2.polylines(img, [np.round(p * 16).astype(np.int32).reshape(-1, 1, 2)], False, PATH,
                      max(1, w // 500), cv2.LINE_AA, 4)
    # colour bar
    bx0, bx1 = w - bar_w + int(0.01 * w), w - bar_w + int(0.05 * w)
    by0, by1 = top, h - bottom
    ramp = np.linspace(255, 0, by1 - by0).astype(np.uint8)[:, None]
    img[by0:by1, bx0:bx1] = cv2.applyColorMap(np.repeat(ramp, bx1 - bx0, axis=1),
                                              cv2.COLORMAP_VIRIDIS)
    cv2.rectangle(img, (bx0, by0), (bx1, by1), AXIS, 1)
    bstep = nice_step(hi - lo, 5)
    for i in range(math.ceil(lo / bstep), math.floor(hi / bstep) + 1):
        v = i * bstep
        y = int(round(by1 - (v - lo) / (hi - lo) * (by1 - by0)))
        lab = f"{100 * v:.{max(0, -int(math.floor(math.log10(100 * bstep))))}f}"
        (tw, th), _ = cv2.getTextSize(lab, FONT, text, 1)
        cv2.line(img, (bx1, y), (bx1 + 5, y), AXIS, 1)
        cv2.putText(img, lab, (bx1 + 8, y + th // 2), FONT, text, AXIS, 1, cv2.LINE_AA)
    cv2.putText(img, "height (cm)", (bx0 - int(0.02 * w), max(th + 4, by0 - 10)), FONT, text,
                AXIS, 1, cv2.LINE_AA)
    if title:
        (tw, th), _ = cv2.getTextSize(title, FONT, text * 1.1, 1)
        cv2.putText(img, title, (max(4, (w - tw) // 2), th + 8), FONT, text * 1.1, (30, 30, 30),
                    1, cv2.LINE_AA)
    return img
