"""The trajectory seen from above, drawn with OpenCV (no plotting library needed).

Positions ``T_0_k[:3, 3]`` (camera-0 coordinates, m) are projected onto the ground plane of
init.yaml (given in camera-0 coordinates too) and drawn in plane coordinates: ``forward``
along camera 0's optical axis projected onto the plane (up in the plot), ``right`` =
``normal x forward`` (to the right), origin at the foot of camera 0 on the plane; equal
scale on both axes, metres. Start, end, re-anchored frames (keyframes) and lost frames are
marked; an optional ground truth is drawn beside the estimate in the same plane frame.

Pure: arrays in, a BGR uint8 image out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.plane import Plane

BACKGROUND = (255, 255, 255)
GRID = (230, 230, 230)
AXIS = (90, 90, 90)
ESTIMATE = (180, 100, 20)      # blue
TRUTH = (150, 215, 150)        # light green, drawn wide under the estimate
START = (40, 160, 40)
END = (40, 40, 200)
KEYFRAME = (0, 150, 255)       # orange
LOST = (0, 0, 230)             # red
FONT = cv2.FONT_HERSHEY_SIMPLEX


def plane_axes(plane: Plane) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(origin, right, forward)`` (3,) each of the plane's 2-D frame, camera-0 coordinates.

    ``forward`` is camera 0's optical axis z projected onto the plane (its image-up axis -y
    when it looks straight down), ``right = normal x forward``, the origin the foot of
    camera 0 on the plane.
    """
    n = np.asarray(plane.normal, dtype=float)
    n = n / np.linalg.norm(n)
    fwd = np.array([0.0, 0.0, 1.0]) - n[2] * n
    if np.linalg.norm(fwd) < 0.1:
        fwd = np.array([0.0, -1.0, 0.0]) + n[1] * n
    fwd /= np.linalg.norm(fwd)
    right = np.cross(n, fwd)
    return plane.distance * n, right, fwd


def on_plane(positions: np.ndarray, plane: Plane) -> np.ndarray:
    """Plane coordinates (N, 2) ``(right, forward)`` m of camera-0 positions (N, 3)."""
    origin, right, fwd = plane_axes(plane)
    d = np.asarray(positions, dtype=float) - origin
    return np.stack([d @ right, d @ fwd], axis=1)


def nice_step(span: float, target: int = 6) -> float:
    """A 1-2-5 grid step (same unit as ``span``) giving about ``target`` intervals over
    ``span``."""
    raw = max(span, 1e-9) / target
    p = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * p >= raw:
            return m * p
    return 10.0 * p


def label(v: float, step: float) -> str:
    """``v`` as a tick label on a grid of ``step``: as many decimals as the step needs."""
    decimals = max(0, -int(math.floor(math.log10(step)))) if step < 1 else 0
    return f"{v:.{decimals}f}"


def plot_trajectory(world_from_cam: np.ndarray, plane: Plane, *,
                    statuses: Sequence[str] | None = None,
                    groundtruth: np.ndarray | None = None,
                    title: str | None = None,
                    size: tuple[int, int] = (800, 800)) -> np.ndarray:
    """The path seen from above as a BGR uint8 image (H, W, 3).

    ``world_from_cam`` (N, 4, 4) are the poses ``T_0_k``; ``plane`` the ground in camera-0
    coordinates; ``statuses`` (N,) per frame (``ok``, ``reanchored`` or ``lost``; frame 0's is
    ignored) marks keyframes and lost frames; ``groundtruth`` (M, 4, 4) poses in the same
    world frame are drawn beside the estimate.
    """
    w, h = size
    est = on_plane(np.asarray(world_from_cam)[:, :3, 3], plane)
    gt = on_plane(np.asarray(groundtruth)[:, :3, 3], plane) if groundtruth is not None else None
    pts = est if gt is None else np.concatenate([est, gt])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = float(max(hi[0] - lo[0], hi[1] - lo[1], 0.05))
    centre = 0.5 * (lo + hi)
    lo, hi = centre - 0.55 * span, centre + 0.55 * span
    step = nice_step(span)
    img = np.full((h, w, 3), BACKGROUND, np.uint8)
    scale_text = max(0.4, w / 1600.0)
    left, right_m, top, bottom = int(0.11 * w), int(0.04 * w), int(0.09 * h), int(0.09 * h)
    pw, ph = w - left - right_m, h - top - bottom
    s = min(pw, ph) / (hi[0] - lo[0])                     # px per metre, equal on both axes
    ox = left + 0.5 * (pw - s * (hi[0] - lo[0]))
    oy = top + 0.5 * (ph - s * (hi[1] - lo[1]))
    px0, px1 = int(ox), int(ox + s * (hi[0] - lo[0]))
    py0, py1 = int(oy), int(oy + s * (hi[1] - lo[1]))

    def to_px(p: np.ndarray) -> np.ndarray:
        x = ox + (p[:, 0] - lo[0]) * s
        y = oy + (hi[1] - p[:, 1]) * s                   # forward is up
        return np.stack([x, y], 1)

    sh = 4
    fix = 1 << sh

    def poly(p: np.ndarray) -> np.ndarray:
        return np.round(to_px(p) * fix).astype(np.int32).reshape(-1, 1, 2)

    # grid and tick labels
    for i in range(math.ceil(lo[0] / step), math.floor(hi[0] / step) + 1):
        x = int(round(ox + (i * step - lo[0]) * s))
        cv2.line(img, (x, py0), (x, py1), GRID, 1)
        lab = label(i * step, step)
        (tw, th), _ = cv2.getTextSize(lab, FONT, scale_text, 1)
        cv2.putText(img, lab, (x - tw // 2, py1 + th + 8), FONT, scale_text, AXIS, 1, cv2.LINE_AA)
    for i in range(math.ceil(lo[1] / step), math.floor(hi[1] / step) + 1):
        y = int(round(oy + (hi[1] - i * step) * s))
        cv2.line(img, (px0, y), (px1, y), GRID, 1)
        lab = label(i * step, step)
        (tw, th), _ = cv2.getTextSize(lab, FONT, scale_text, 1)
        cv2.putText(img, lab, (px0 - tw - 8, y + th // 2), FONT, scale_text, AXIS, 1, cv2.LINE_AA)
    cv2.rectangle(img, (px0, py0), (px1, py1), AXIS, 1)
    xl = "right (m)"
    (tw, th), _ = cv2.getTextSize(xl, FONT, scale_text, 1)
    cv2.putText(img, xl, ((px0 + px1 - tw) // 2, h - 10), FONT, scale_text, AXIS, 1, cv2.LINE_AA)
    yl = "forward (m)"
    (tw, th), _ = cv2.getTextSize(yl, FONT, scale_text, 1)
    side = np.full((th + 8, tw + 4, 3), BACKGROUND, np.uint8)
    cv2.putText(side, yl, (2, th + 2), FONT, scale_text, AXIS, 1, cv2.LINE_AA)
    side = cv2.rotate(side, cv2.ROTATE_90_COUNTERCLOCKWISE)
    y0 = max(0, (py0 + py1 - side.shape[0]) // 2)
    img[y0:y0 + side.shape[0], 4:4 + side.shape[1]] = side[: h - y0]

    thick = max(1, int(round(w / 400.0)))
    r = max(3, int(round(w / 130.0)))
    if gt is not None:
        cv2.polylines(img, [poly(gt)], False, TRUTH, 4 * thick, cv2.LINE_AA, sh)
    cv2.polylines(img, [poly(est)], False, ESTIMATE, thick, cv2.LINE_AA, sh)
    e = to_px(est)
    if statuses is not None:
        st = list(statuses)
        for k in range(1, min(len(st), len(e))):
            c = (int(round(e[k, 0] * fix)), int(round(e[k, 1] * fix)))
            if st[k] == FrameStatus.REANCHORED:
                cv2.circle(img, c, (r * fix) // 2, KEYFRAME, -1, cv2.LINE_AA, sh)
            elif st[k] == FrameStatus.LOST:
                d = r * fix
                cv2.line(img, (c[0] - d, c[1] - d), (c[0] + d, c[1] + d), LOST, thick + 1,
                         cv2.LINE_AA, sh)
                cv2.line(img, (c[0] - d, c[1] + d), (c[0] + d, c[1] - d), LOST, thick + 1,
                         cv2.LINE_AA, sh)
    start = (int(round(e[0, 0] * fix)), int(round(e[0, 1] * fix)))
    cv2.circle(img, start, r * fix, START, -1, cv2.LINE_AA, sh)
    end = (int(round(e[-1, 0])), int(round(e[-1, 1])))
    cv2.rectangle(img, (end[0] - r, end[1] - r), (end[0] + r, end[1] + r), END, -1, cv2.LINE_AA)

    # legend
    items = [("estimate", ESTIMATE, "line")]
    if gt is not None:
        items.append(("ground truth", TRUTH, "line"))
    items += [("start", START, "dot"), ("end", END, "square")]
    if statuses is not None:
        st = list(statuses)[1:]
        if FrameStatus.REANCHORED in st:
            items.append((f"keyframe ({st.count(FrameStatus.REANCHORED)})", KEYFRAME, "small"))
        if FrameStatus.LOST in st:
            items.append((f"lost ({st.count(FrameStatus.LOST)})", LOST, "cross"))
    (_, lh), _ = cv2.getTextSize("Ag", FONT, scale_text, 1)
    row = int(lh * 1.9)
    lw = max(cv2.getTextSize(t, FONT, scale_text, 1)[0][0] for t, _, _ in items) + 4 * r + 20
    lx, ly = px0 + 8, py0 + 8
    box = img[ly:ly + row * len(items) + 8, lx:lx + lw]
    cv2.addWeighted(box, 0.15, np.full_like(box, 255), 0.85, 0, dst=box)
    cv2.rectangle(img, (lx, ly), (lx + lw, ly + row * len(items) + 8), GRID, 1)
    for i, (text, colour, kind) in enumerate(items):
        cy = ly + 4 + row * i + row // 2
        cx = lx + 6 + r
        if kind == "line":
            wide = 4 * thick if colour == TRUTH else thick + 1
            cv2.line(img, (cx - r, cy), (cx + r, cy), colour, wide, cv2.LINE_AA)
        elif kind == "dot":
            cv2.circle(img, (cx, cy), r, colour, -1, cv2.LINE_AA)
        elif kind == "small":
            cv2.circle(img, (cx, cy), max(2, r // 2), colour, -1, cv2.LINE_AA)
        elif kind == "square":
            cv2.rectangle(img, (cx - r, cy - r), (cx + r, cy + r), colour, -1)
        else:
            cv2.line(img, (cx - r, cy - r), (cx + r, cy + r), colour, thick + 1, cv2.LINE_AA)
            cv2.line(img, (cx - r, cy + r), (cx + r, cy - r), colour, thick + 1, cv2.LINE_AA)
        cv2.putText(img, text, (cx + r + 8, cy + lh // 2), FONT, scale_text, (40, 40, 40), 1,
                    cv2.LINE_AA)
    if title:
        (tw, th), _ = cv2.getTextSize(title, FONT, scale_text * 1.1, 1)
        cv2.putText(img, title, (max(4, (w - tw) // 2), max(th + 4, top - 12)), FONT,
                    scale_text * 1.1, (30, 30, 30), 1, cv2.LINE_AA)
    return img
