"""A run's frames over time, drawn with OpenCV: status, msd, points and reported std.

Five panels share one horizontal axis, the frame index: a status strip (one cell per frame,
coloured ``ok``, ``reanchored``, ``reinit`` or ``lost``), the msd (grey levels^2), the
observation points, and the reported standard deviations of the frame-to-frame motion,
translation (mm, the norm of (tx, ty, tz)) and rotation (deg, the norm of (rx, ry, rz)).
Lost frames are marked by red and re-initialised frames by orange vertical lines through
every panel; a value that is not finite (no estimate), and the msd and points of a frame
that was not fitted (an unreadable frame: motion.csv's msd, iterations and points 0), leave a
gap in the curve.

Pure: arrays in, a BGR uint8 image out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from monovo_cli.core.status import FrameStatus
from monovo_cli.viz.plots import AXIS, BACKGROUND, FONT, GRID, label, nice_step

STATUS_COLOURS = {FrameStatus.OK: (120, 190, 120),          # green
                  FrameStatus.REANCHORED: (200, 140, 40),   # blue
                  FrameStatus.REINIT: (0, 150, 255),        # orange
                  FrameStatus.LOST: (0, 0, 230)}            # red
CURVE = (150, 80, 20)
TEXT = (40, 40, 40)


def _panel_ticks(lo: float, hi: float) -> list[float]:
    step = nice_step(hi - lo, target=4)
    return [i * step for i in range(math.ceil(lo / step), math.floor(hi / step) + 1)]


def timeline_curves(msd: np.ndarray, points: np.ndarray,
                    std: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The four curves of :func:`plot_timeline`, ``(name with unit, (N,) values)``, NaN where
    a frame has no value to draw: frame 0 (no estimate), and a frame whose fit used no
    observation point (``points`` 0: an unreadable frame skipped, a frame lost before any
    fit), whose msd 0 and points 0 in motion.csv are no measurement -- drawn, they would
    dip to a perfect fit. ``std`` (N, 6) as :func:`plot_timeline` takes it."""
    points = np.asarray(points, dtype=float)
    n = len(points)
    std = np.asarray(std, dtype=float).reshape(n, 6)
    est = np.arange(n) >= 1
    fitted = est & (points > 0)
    return [
        ("msd (grey levels^2)", np.where(fitted, np.asarray(msd, dtype=float), np.nan)),
        ("points", np.where(fitted, points, np.nan)),
        ("std translation (mm)", np.where(est, 1e3 * np.linalg.norm(std[:, :3], axis=1), np.nan)),
        ("std rotation (deg)", np.where(est, np.degrees(np.linalg.norm(std[:, 3:], axis=1)),
                                        np.nan)),
    ]


def plot_timeline(index: np.ndarray, status: Sequence[str], msd: np.ndarray,
                  points: np.ndarray, std: np.ndarray, *,
                  size: tuple[int, int] = (1000, 560)) -> np.ndarray:
    """The timeline of N frames as a BGR uint8 image (H, W, 3), ``size`` = (W, H) px.

    ``index`` (N,) frame indices; ``status`` (N,) :class:`FrameStatus` values; ``msd`` (N,)
    grey levels^2; ``points`` (N,) observation points; ``std`` (N, 6) of (tx, ty, tz) m and
    (rx, ry, rz) rad (NaN where none). Frame 0 (the first) carries no estimate: its values
    are not drawn; nor are the msd and points of a frame fitted on no point
    (:func:`timeline_curves`).
    """
    w, h = size
    idx = np.asarray(index, dtype=float)
    st = [FrameStatus(s) for s in status]
    n = len(idx)
    if n == 0 or len(st) != n:
        raise ValueError(f"timeline: expected N >= 1 frames with N statuses, got {n} and {len(st)}")
    curves = timeline_curves(msd, points, std)
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    ts = max(0.4, w / 2200.0)
    (_, lh), _ = cv2.getTextSize("Ag", FONT, ts, 1)
    left, right, top, bottom = int(0.09 * w), int(0.02 * w), lh + 10, 2 * lh + 18
    strip = max(12, h // 22)
    gap = lh + 12
    ph = (h - top - bottom - strip - gap * len(curves)) // len(curves)
    x0, x1 = left, w - right
    lo_i, hi_i = float(idx[0]), float(max(idx[-1], idx[0] + 1))

    def to_x(v: np.ndarray | float) -> np.ndarray:
        return x0 + (np.asarray(v, dtype=float) - lo_i) / (hi_i - lo_i) * (x1 - x0)

    # status strip: one cell per frame
    y = top
    edges = to_x(np.concatenate([idx - 0.5, [idx[-1] + 0.5]]))
    edges = np.clip(edges, x0, x1)
    for k in range(n):
        a, b = int(round(edges[k])), max(int(round(edges[k + 1])), int(round(edges[k])) + 1)
        cv2.rectangle(img, (a, y), (b - 1, y + strip - 1), STATUS_COLOURS[st[k]], -1)
    cv2.putText(img, "status", (4, y + strip - 2), FONT, ts, TEXT, 1, cv2.LINE_AA)
    panels = []
    y += strip + gap
    for name, values in curves:
        panels.append((y, y + ph, name, values))
        y += ph + gap
    y_end = panels[-1][1]

    # lost and re-initialised frames through every panel
    for k in range(1, n):
        if st[k] in (FrameStatus.LOST, FrameStatus.REINIT):
            x = int(round(float(to_x(idx[k]))))
            cv2.line(img, (x, top), (x, y_end), STATUS_COLOURS[st[k]], 1)

    for p0, p1, name, values in panels:
        finite = values[np.isfinite(values)]
        lo, hi = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
        lo = min(lo, 0.0)
        if hi - lo < 1e-12:
            hi = lo + 1.0
        hi += 0.05 * (hi - lo)
        cv2.rectangle(img, (x0, p0), (x1, p1), AXIS, 1)
        for t in _panel_ticks(lo, hi):
            yy = int(round(p1 - (t - lo) / (hi - lo) * (p1 - p0)))
            cv2.line(img, (x0 + 1, yy), (x1 - 1, yy), GRID, 1)
            lab = label(t, nice_step(hi - lo, target=4))
            (tw, th), _ = cv2.getTextSize(lab, FONT, ts, 1)
            cv2.putText(img, lab, (x0 - tw - 6, yy + th // 2), FONT, ts, AXIS, 1, cv2.LINE_AA)
        cv2.putText(img, name, (x0 + 4, p0 - 5), FONT, ts, TEXT, 1, cv2.LINE_AA)
        ys = p1 - (values - lo) / (hi - lo) * (p1 - p0)
        xs = to_x(idx)
        ok = np.isfinite(ys)
        # one polyline per run of finite values
        starts = np.flatnonzero(ok & ~np.concatenate([[False], ok[:-1]]))
        for s in starts:
            e = s
            while e + 1 < n and ok[e + 1]:
                e += 1
            pts = np.round(np.stack([xs[s:e + 1], ys[s:e + 1]], 1) * 16).astype(np.int32)
            if len(pts) == 1:
                cv2.circle(img, tuple(int(v) for v in pts[0]), 2 * 16, CURVE, -1, cv2.LINE_AA, 4)
            else:
                cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, CURVE, 1, cv2.LINE_AA, 4)

    # frame axis
    step = max(1.0, nice_step(hi_i - lo_i, target=10))
    for i in range(math.ceil(lo_i / step), math.floor(hi_i / step) + 1):
        x = int(round(float(to_x(i * step))))
        cv2.line(img, (x, y_end), (x, y_end + 4), AXIS, 1)
        lab = f"{int(i * step)}"
        (tw, th), _ = cv2.getTextSize(lab, FONT, ts, 1)
        cv2.putText(img, lab, (x - tw // 2, y_end + th + 8), FONT, ts, AXIS, 1, cv2.LINE_AA)
    cv2.putText(img, "frame", ((x0 + x1) // 2 - 20, h - 6), FONT, ts, AXIS, 1, cv2.LINE_AA)

    # legend of the status colours, top right
    x = x1
    for s in reversed(list(STATUS_COLOURS)):
        text = f"{s.value}"
        (tw, th), _ = cv2.getTextSize(text, FONT, ts, 1)
        x -= tw + 6
        cv2.putText(img, text, (x, top - 4), FONT, ts, TEXT, 1, cv2.LINE_AA)
        x -= th + 4
        cv2.rectangle(img, (x, top - 4 - th), (x + th, top - 4), STATUS_COLOURS[s], -1)
        x -= 10
    return img
