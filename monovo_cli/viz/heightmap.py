"""The height map of the driven strip as an image with a colour bar, drawn with OpenCV.

Cells of a :class:`~monovo_cli.mapping.terrain_map.HeightGrid` (ground frame of init.yaml's
plane: right, forward, m) are coloured by height (viridis), forward up, equal scale on both
axes, the camera path (optional) drawn over it. Far from the path a cell holds one or two
points seen once at a grazing angle: such sparse cells neither set the colour scale nor the
picture. A cell is well observed when it holds at least :data:`SUPPORT_FRACTION` of the
points of the cell a typical point lies in, and at least :data:`MIN_SUPPORT`
(:func:`well_observed`); the colour scale spans the 1st to 99th percentile of the well
observed cells' heights (:func:`height_range`), the picture their extent, and the sparse
cells inside it are grey, empty cells white. The colour bar has four to eight labelled ticks
in mm, cm or m, whichever suits the range (:func:`colour_bar_ticks`).

Pure: arrays in, a BGR uint8 image out.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from monovo_cli.mapping.terrain_map import HeightGrid
from monovo_cli.viz.plots import AXIS, BACKGROUND, FONT, label, nice_step

PATH = (40, 40, 40)
SPARSE = (205, 205, 205)  # grey: a cell with too few points to trust
SUPPORT_FRACTION = 0.25   # of the points in the cell where a typical point lies
MIN_SUPPORT = 2           # points: a cell with fewer is never well observed
MIN_TICKS = 4             # labelled ticks on the colour bar, at least


def support_threshold(grid: HeightGrid) -> float:
    """The points a well-observed cell holds at least: :data:`SUPPORT_FRACTION` of the
    count of the cell the median point lies in (the point-weighted median count), and at
    least :data:`MIN_SUPPORT`."""
    counts = np.sort(grid.count[(grid.count > 0) & np.isfinite(grid.height)].astype(float))
    if not len(counts):
        return float(MIN_SUPPORT)
    cum = np.cumsum(counts)
    typical = counts[int(np.searchsorted(cum, 0.5 * cum[-1]))]
    return max(float(MIN_SUPPORT), SUPPORT_FRACTION * typical)


def well_observed(grid: HeightGrid) -> np.ndarray:
    """(H, W) bool: the cells holding at least :func:`support_threshold` points; every
    non-empty cell when none does (a map of a few points)."""
    filled = (grid.count > 0) & np.isfinite(grid.height)
    ok = filled & (grid.count >= support_threshold(grid))
    return ok if ok.any() else filled


def height_range(grid: HeightGrid) -> tuple[float, float]:
    """The colour scale's ``(low, high)`` heights, m: the 1st and 99th percentiles of the
    well-observed cells' heights (:func:`well_observed`)."""
    h = grid.height[well_observed(grid)]
    if not len(h):
        return 0.0, 1.0
    lo, hi = (float(v) for v in np.percentile(h, [1.0, 99.0]))
    return (lo, hi) if hi > lo else (lo - 0.005, lo + 0.005)


def colour_bar_ticks(lo: float, hi: float) -> tuple[str, list[tuple[float, str]]]:
    """The colour bar's unit ("mm", "cm" or "m": the one whose numbers over ``lo`` .. ``hi``
    (m) read best) and its ticks, ``(height m, label)``: at least :data:`MIN_TICKS` on a
    1-2-5 step, every label with the step's decimals."""
    span = hi - lo
    unit, scale = ("m", 1.0) if span >= 0.5 else ("cm", 100.0) if span >= 0.005 else ("mm", 1e3)
    a, b = lo * scale, hi * scale
    target = 5
    while True:
        step = nice_step(b - a, target)
        values = [i * step for i in range(math.ceil(a / step - 1e-9), math.floor(b / step + 1e-9) + 1)]
        if len(values) >= MIN_TICKS or target > 40:
            break
        target += 2
    return unit, [(v / scale, label(0.0 if abs(v) < 1e-9 * step else v, step)) for v in values]


def cell_colours(grid: HeightGrid) -> np.ndarray:
    """(H, W, 3) BGR uint8, row j the grid's row j (forward grows with j): the well-observed
    cells by height over :func:`height_range` (viridis), the other non-empty cells
    :data:`SPARSE`, empty cells the background."""
    lo, hi = height_range(grid)
    norm = np.clip((grid.height - lo) / (hi - lo), 0.0, 1.0)
    colours = cv2.applyColorMap(np.nan_to_num(norm * 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    filled = (grid.count > 0) & np.isfinite(grid.height)
    colours[filled & ~well_observed(grid)] = SPARSE
    colours[~filled] = BACKGROUND
    return colours


def drawn_extent(grid: HeightGrid) -> tuple[slice, slice]:
    """The rows and columns of ``grid`` the picture shows: the box of the well-observed
    cells (:func:`well_observed`), so that sparse far cells do not shrink it."""
    ok = well_observed(grid)
    if not ok.any():
        return slice(0, grid.height.shape[0]), slice(0, grid.height.shape[1])
    j, i = np.nonzero(ok)
    return slice(int(j.min()), int(j.max()) + 1), slice(int(i.min()), int(i.max()) + 1)


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
    if grid.height.size == 0:
        cv2.putText(img, "no terrain points", (left, h // 2), FONT, text, AXIS, 1, cv2.LINE_AA)
        return img
    rows, cols = drawn_extent(grid)
    colours = cell_colours(grid)[rows, cols][::-1]  # forward is up
    lo, hi = height_range(grid)
    threshold = support_threshold(grid)
    grid = HeightGrid(grid.x0 + cols.start * grid.cell, grid.y0 + rows.start * grid.cell,
                      grid.cell, grid.height[rows, cols], grid.count[rows, cols])
    gh, gw = grid.height.shape
    ext_x, ext_y = gw * grid.cell, gh * grid.cell
    s = min(pw / ext_x, ph / ext_y)  # px per metre
    ox = left + 0.5 * (pw - s * ext_x)
    oy = top + 0.5 * (ph - s * ext_y)
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
    unit, ticks = colour_bar_ticks(lo, hi)
    for v, lab in ticks:
        y = int(round(by1 - (v - lo) / (hi - lo) * (by1 - by0)))
        (tw, th), _ = cv2.getTextSize(lab, FONT, text, 1)
        cv2.line(img, (bx1, y), (bx1 + 5, y), AXIS, 1)
        cv2.putText(img, lab, (bx1 + 8, y + th // 2), FONT, text, AXIS, 1, cv2.LINE_AA)
    (_, th), _ = cv2.getTextSize("Ag", FONT, text, 1)
    cv2.putText(img, f"height ({unit})", (bx0 - int(0.02 * w), max(th + 4, by0 - 10)), FONT, text,
                AXIS, 1, cv2.LINE_AA)
    if (colours == np.array(SPARSE, np.uint8)).all(axis=2).any():
        ky = by1 + th + 14
        cv2.rectangle(img, (bx0, ky - th), (bx0 + th, ky), SPARSE, -1)
        cv2.putText(img, f"< {threshold:.3g} points", (bx0 + th + 6, ky), FONT, text, AXIS, 1,
                    cv2.LINE_AA)
    if title:
        (tw, th), _ = cv2.getTextSize(title, FONT, text * 1.1, 1)
        cv2.putText(img, title, (max(4, (w - tw) // 2), th + 8), FONT, text * 1.1, (30, 30, 30),
                    1, cv2.LINE_AA)
    return img
