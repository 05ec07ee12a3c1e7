"""The plots of a trajectory against ground truth (``monovo eval --plots``), drawn with OpenCV.

* :func:`plot_paths_from_above` -- both paths in the plane of the true drive (its two
  principal directions: "along" the drive and "across" it), equal scale, metres;
* :func:`plot_errors_over` -- APE and RPE (and the errors over segments of travelled
  distance) against time, frame or distance, one panel each;
* :func:`plot_axis_errors` -- the per-axis errors of the tracker's relative motions with
  the band of ± k reported standard deviations shaded, points outside it in red: an honest
  std keeps about 99.7 % of them inside ±3σ.

Pure: arrays in, a BGR uint8 image out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from monovo_cli.viz.plots import (
    AXIS,
    BACKGROUND,
    END,
    ESTIMATE,
    FONT,
    GRID,
    START,
    TRUTH,
    label,
    nice_step,
)

BAND = (225, 205, 185)        # light blue-grey: the ±k std band
OUTSIDE = (0, 0, 230)         # red: an error outside the band
SERIES = ((180, 100, 20), (40, 140, 40), (20, 110, 220), (140, 60, 160))
SHIFT = 4
TEXT = (40, 40, 40)
AXIS_NAMES = ("tx (m)", "ty (m)", "tz (m)", "rx (deg)", "ry (deg)", "rz (deg)")


def _text(img: np.ndarray, s: str, org: tuple[int, int], scale: float,
          colour: tuple[int, int, int] = TEXT) -> None:
    cv2.putText(img, s, (int(org[0]), int(org[1])), FONT, scale, colour, 1, cv2.LINE_AA)


def _title(img: np.ndarray, title: str | None, scale: float) -> None:
    if title:
        (tw, th), _ = cv2.getTextSize(title, FONT, scale * 1.1, 1)
        cv2.putText(img, title, (max(4, (img.shape[1] - tw) // 2), th + 10), FONT, scale * 1.1,
                    (30, 30, 30), 1, cv2.LINE_AA)


def _range(values: Sequence[np.ndarray], *, zero: bool = False) -> tuple[float, float]:
    v = np.concatenate([np.ravel(a) for a in values if np.size(a)] or [np.zeros(1)])
    v = v[np.isfinite(v)]
    lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
    if zero:
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    if hi - lo < 1e-12:
        pad = max(abs(hi), 1.0) * 0.5
        return lo - pad, hi + pad
    return lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)


class _Frame:
    """A panel's axes: data ranges mapped onto the pixel box ``(x0, y0, x1, y1)``."""

    def __init__(self, img: np.ndarray, box: tuple[int, int, int, int],
                 xr: tuple[float, float], yr: tuple[float, float], scale: float) -> None:
        self.img, self.box, self.xr, self.yr, self.scale = img, box, xr, yr, scale

    def px(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x0, y0, x1, y1 = self.box
        u = x0 + (np.asarray(x, float) - self.xr[0]) / (self.xr[1] - self.xr[0]) * (x1 - x0)
        v = y1 - (np.asarray(y, float) - self.yr[0]) / (self.yr[1] - self.yr[0]) * (y1 - y0)
        return np.stack([u, v], 1)

    def fixed(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.round(self.px(x, y) * (1 << SHIFT)).astype(np.int32).reshape(-1, 1, 2)

    def axes(self, xlabel: str | None, ylabel: str) -> None:
        img, (x0, y0, x1, y1), sc = self.img, self.box, self.scale
        for k, (lo, hi) in enumerate((self.xr, self.yr)):
            step = nice_step(hi - lo, 6 if k == 0 else 4)
            for i in range(math.ceil(lo / step), math.floor(hi / step) + 1):
                lab = label(i * step, step)
                (tw, th), _ = cv2.getTextSize(lab, FONT, sc, 1)
                if k == 0:
                    u = int(round(self.px(np.r_[i * step], np.r_[self.yr[0]])[0, 0]))
                    cv2.line(img, (u, y0), (u, y1), GRID, 1)
                    if xlabel is not None:
                        _text(img, lab, (u - tw // 2, y1 + th + 6), sc, AXIS)
                else:
                    v = int(round(self.px(np.r_[self.xr[0]], np.r_[i * step])[0, 1]))
                    cv2.line(img, (x0, v), (x1, v), GRID, 1)
                    _text(img, lab, (x0 - tw - 6, v + th // 2), sc, AXIS)
        cv2.rectangle(img, (x0, y0), (x1, y1), AXIS, 1)
        _text(img, ylabel, (x0 + 6, y0 - 6), sc, TEXT)
        if xlabel is not None:
            (tw, th), _ = cv2.getTextSize(xlabel, FONT, sc, 1)
            _text(img, xlabel, ((x0 + x1 - tw) // 2, y1 + 2 * th + 14), sc, AXIS)

    def line(self, x: np.ndarray, y: np.ndarray, colour: tuple[int, int, int],
             thick: int = 1) -> None:
        ok = np.isfinite(np.asarray(y, float))
        if ok.sum() >= 2:
            cv2.polylines(self.img, [self.fixed(np.asarray(x)[ok], np.asarray(y)[ok])], False,
                          colour, thick, cv2.LINE_AA, SHIFT)

    def dots(self, x: np.ndarray, y: np.ndarray, colour: tuple[int, int, int], r: int) -> None:
        for c in self.fixed(x, y).reshape(-1, 2):
            cv2.circle(self.img, (int(c[0]), int(c[1])), r << SHIFT, colour, -1, cv2.LINE_AA,
                       SHIFT)

    def band(self, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """The area between ``lo`` and ``hi`` over ``x``, drawn as a step per sample."""
        x = np.asarray(x, float)
        if len(x) == 0:
            return
        half = np.diff(x) / 2 if len(x) > 1 else np.r_[0.5]
        left = x - np.r_[half[:1], half]
        right = x + np.r_[half, half[-1:]]
        for a, b, low, high in zip(left, right, lo, hi):
            pts = self.px(np.r_[a, b], np.r_[low, high])
            cv2.rectangle(self.img, (int(round(pts[0, 0])), int(round(pts[1, 1]))),
                          (int(round(pts[1, 0])), int(round(pts[0, 1]))), BAND, -1)


def _legend(img: np.ndarray, items: Sequence[tuple[str, tuple[int, int, int]]],
            at: tuple[int, int], scale: float) -> None:
    (_, lh), _ = cv2.getTextSize("Ag", FONT, scale, 1)
    x, y = at
    for text, colour in items:
        cv2.line(img, (x, y - lh // 2), (x + 22, y - lh // 2), colour, 3, cv2.LINE_AA)
        _text(img, text, (x + 28, y), scale)
        x += 40 + cv2.getTextSize(text, FONT, scale, 1)[0][0]


def plane_of_drive(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(origin, along, across)`` (3,) each: the centroid of ``positions`` (N, 3) and its two
    principal directions, ``along`` pointing from the first position towards the last (the
    plane a ground drive moves in, seen from above)."""
    p = np.asarray(positions, float)
    origin = p.mean(axis=0)
    if len(p) < 3 or np.ptp(p, axis=0).max() < 1e-12:
        return origin, np.r_[1.0, 0.0, 0.0], np.r_[0.0, 1.0, 0.0]
    _, _, Vt = np.linalg.svd(p - origin)
    along, across = Vt[0], Vt[1]
    if (p[-1] - p[0]) @ along < 0:
        along = -along
    if np.cross(along, across) @ Vt[2] < 0:
        across = -across
    return origin, along, across


def plot_paths_from_above(est_xyz: np.ndarray, gt_xyz: np.ndarray, *, title: str | None = None,
                          size: tuple[int, int] = (800, 800)) -> np.ndarray:
    """The estimated and the true positions (N, 3), (M, 3) m, in one world frame, seen from
    above the true drive's plane (:func:`plane_of_drive`), as a BGR uint8 image (H, W, 3):
    equal scale on both axes, start and end marked."""
    w, h = size
    origin, along, across = plane_of_drive(gt_xyz)

    def flat(p: np.ndarray) -> np.ndarray:
        d = np.asarray(p, float) - origin
        return np.stack([d @ along, d @ across], 1)

    est, gt = flat(est_xyz), flat(gt_xyz)
    pts = np.concatenate([est, gt])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = float(max(hi[0] - lo[0], hi[1] - lo[1], 0.05))
    c = 0.5 * (lo + hi)
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    sc = max(0.4, w / 1600.0)
    left, top, bottom, right = int(0.11 * w), int(0.09 * h), int(0.11 * h), int(0.04 * w)
    side = min(w - left - right, h - top - bottom)
    box = (left, top, left + side, top + side)
    f = _Frame(img, box, (c[0] - 0.55 * span, c[0] + 0.55 * span),
               (c[1] - 0.55 * span, c[1] + 0.55 * span), sc)
    f.axes("along the drive (m)", "across (m)")
    thick = max(1, int(round(w / 400.0)))
    f.line(gt[:, 0], gt[:, 1], TRUTH, 4 * thick)
    f.line(est[:, 0], est[:, 1], ESTIMATE, thick)
    r = max(3, int(round(w / 130.0)))
    f.dots(gt[:1, 0], gt[:1, 1], START, r)
    f.dots(gt[-1:, 0], gt[-1:, 1], END, r)
    f.dots(est[-1:, 0], est[-1:, 1], ESTIMATE, max(2, r // 2))
    _legend(img, [("estimate", ESTIMATE), ("ground truth", TRUTH), ("start", START),
                  ("true end", END)], (left + 8, top + 24), sc)
    _title(img, title, sc)
    return img


def plot_errors_over(x: np.ndarray, ape: np.ndarray, rpe_t: np.ndarray, rpe_r: np.ndarray, *,
                     xlabel: str, title: str | None = None,
                     segments: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                     ape_label: str = "APE (m)",
                     size: tuple[int, int] = (1000, 900)) -> np.ndarray:
    """Errors against ``x`` (N,) (time s, frame, or distance m) as a BGR uint8 image
    (H, W, 3), one panel each: the APE ``ape`` (N,) m; the RPE ``rpe_t`` (N-1,) m and
    ``rpe_r`` (N-1,) deg, drawn at the later pose of each pair; and with ``segments`` =
    ``(x_first (M,), translation % (M,), length m (M,))`` the errors over segments of
    travelled distance, one colour per length, at each segment's first pose; ``ape_label``
    titles the APE's panel (say the alignment there)."""
    w, h = size
    x = np.asarray(x, float)
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    sc = max(0.4, w / 2000.0)
    panels = [(ape_label, [(x, ape, SERIES[0])]),
              ("RPE translation per pose (m)", [(x[1:], rpe_t, SERIES[1])]),
              ("RPE rotation per pose (deg)", [(x[1:], rpe_r, SERIES[2])])]
    legend = []
    if segments is not None and len(segments[0]):
        xs, err, length = (np.asarray(a, float) for a in segments)
        series = []
        for i, L in enumerate(np.unique(length)):
            sel = length == L
            series.append((xs[sel], err[sel], SERIES[(i + 1) % len(SERIES)]))
            legend.append((f"{L:g} m", SERIES[(i + 1) % len(SERIES)]))
        panels.append(("translation error over segments (%)", series))
    left, right, top, bottom = int(0.09 * w), int(0.03 * w), int(0.07 * h), int(0.08 * h)
    gap = int(0.045 * h)
    ph = (h - top - bottom - gap * (len(panels) - 1)) // len(panels)
    xr = _range([x])
    for k, (ylabel, series) in enumerate(panels):
        y0 = top + k * (ph + gap)
        f = _Frame(img, (left, y0, w - right, y0 + ph), xr,
                   _range([s[1] for s in series], zero=True), sc)
        f.axes(xlabel if k == len(panels) - 1 else None, ylabel)
        for xs, ys, colour in series:
            if len(xs) > 1 and len(series) == 1:
                f.line(xs, ys, colour, 1 + w // 800)
            else:
                f.dots(xs, ys, colour, 2)
        if k == len(panels) - 1 and legend:
            _legend(img, legend, (w - right - 110 * len(legend), y0 - 6), sc)
    _title(img, title, sc)
    return img


def plot_axis_errors(x: np.ndarray, errors: np.ndarray, std: np.ndarray, *,
                     sigmas: float = 3.0, xlabel: str, title: str | None = None,
                     size: tuple[int, int] = (1000, 1200)) -> np.ndarray:
    """Per-axis signed errors ``errors`` (M, 6) of relative motions at ``x`` (M,) with the
    band ``± sigmas * std`` ((M, 6) reported std, same units: (tx, ty, tz) m, (rx, ry, rz)
    deg) shaded, as a BGR uint8 image (H, W, 3): one panel per axis, errors outside the
    band in red, each panel saying the share inside."""
    w, h = size
    x = np.asarray(x, float)
    e, s = np.asarray(errors, float), np.asarray(std, float)
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    sc = max(0.4, w / 2000.0)
    left, right, top, bottom = int(0.09 * w), int(0.03 * w), int(0.06 * h), int(0.06 * h)
    gap = int(0.03 * h)
    ph = (h - top - bottom - 5 * gap) // 6
    xr = _range([x])
    for a in range(6):
        y0 = top + a * (ph + gap)
        lo, hi = -sigmas * s[:, a], sigmas * s[:, a]
        f = _Frame(img, (left, y0, w - right, y0 + ph), xr, _range([e[:, a], lo, hi]), sc)
        f.band(x, lo, hi)
        f.axes(xlabel if a == 5 else None, AXIS_NAMES[a])
        f.line(x, e[:, a], SERIES[0], 1)
        out = np.abs(e[:, a]) > hi
        f.dots(x[~out], e[~out, a], SERIES[0], 2)
        f.dots(x[out], e[out, a], OUTSIDE, 3)
        share = f"{100.0 * (1 - out.mean()):.1f} % inside +-{sigmas:g} std" if len(out) else ""
        (tw, _), _ = cv2.getTextSize(share, FONT, sc, 1)
        _text(img, share, (w - right - tw - 6, y0 - 6), sc)
    _title(img, title, sc)
    return img
