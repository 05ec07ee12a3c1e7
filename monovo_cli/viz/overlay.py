"""The glued triangle: a virtual planar triangle attached to the ground (section 10.3).

The paper judges its estimates on real sequences by a triangle "motion compensated with the
negative of the accumulated rover's 3D motion estimates" and projected into every frame
(Figs. 10.4-10.7): if the estimates are right it stays glued to the ground. Here the
triangle's vertices ``X`` (3, 3) live on the ground plane in camera-0 coordinates (the
world frame, docs/guide.md "Conventions"); in frame k with pose ``world_from_cam = T_0_k`` they are
``cam_from_world @ X`` with ``cam_from_world = inv(T_0_k)``.

Drawing: the polygon is clipped in 3D against the camera's near plane and its view frustum
(widened by ``FRUSTUM_MARGIN``) before it is projected, so a triangle partly behind the
camera or far outside the image is drawn correctly; with lens distortion its edges are
densified before projection, so they bend as the ground's straight lines do. Fill and
outline are anti-aliased at 1/16 px (``cv2.LINE_AA``, ``shift=4``); pixel centres are
integers (docs/guide.md "File formats").

Over a long drive the first triangle leaves the view; the renderer then places a new one
(:meth:`OverlayRenderer.advance`): at every keyframe (a frame whose status is
``reanchored`` or ``reinit``), and whenever less than ``MIN_VISIBLE`` of the current one is
in view, at the same image position as the first (the default triangle or ``--triangle``)
lifted onto the ground with that frame's pose. Each triangle is then glued to its patch of
ground until the next one, so every frame can be checked. (Over a height map instead of the
plane: :mod:`monovo_cli.viz.drape`.)

Optional observation points (``points=True``) are the ground model's points of the frame
the overlay anchors on (frame 0, then every re-anchored frame) projected with the pose and
coloured by their intensity residual ``|I_k(pi(T X)) - I_key|``: green when it is within the
noise, red at ``3 sqrt(2) sigma`` and above (the tracker's inlier bound).

Pure: arrays in, arrays out; no files, no printing.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from monovo_cli.core.estimator.ground import default_threshold, rectangle_corners, select_points
from monovo_cli.core.estimator.robust import inlier_bound
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import InputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import estimate_noise_sigma
from monovo_cli.image.sampling import sample_bilinear
from monovo_cli.viz.draw import SHIFT, draw_polygon, draw_text, residual_colours, to_bgr

NEAR_FRACTION = 1e-3      # near clipping plane at this fraction of the ground distance
FRUSTUM_MARGIN = 0.25     # clip to the view frustum widened by this share of the image per side
DISTORTED_EDGE_STEPS = 32  # segments per triangle edge when the lens distorts
MIN_VISIBLE = 0.5         # a new triangle when less than this share of the current one is in view
KEYFRAME_STATUSES = (FrameStatus.REANCHORED, "reinit")  # statuses that start a keyframe


@dataclass(frozen=True)
class OverlayStyle:
    """Colours (BGR), opacity and sizes of the overlay drawing."""

    fill: tuple[int, int, int] = (0, 140, 255)      # orange
    outline: tuple[int, int, int] = (0, 235, 255)   # yellow
    alpha: float = 0.45                             # opacity of the fill
    text: tuple[int, int, int] = (255, 255, 255)


# ----------------------------------------------------------------------------- the triangle


def default_triangle_pixels(region: tuple[int, int, int, int]) -> np.ndarray:
    """An equilateral triangle (3, 2) px, apex up, centred in ``region`` (x0, y0, x1, y1; x1, y1
    exclusive), its side a third of the region's smaller side."""
    x0, y0, x1, y1 = region
    cx, cy = 0.5 * (x0 + x1 - 1), 0.5 * (y0 + y1 - 1)
    side = min(x1 - x0, y1 - y0) / 3.0
    h = side * np.sqrt(3.0) / 2.0
    return np.array([[cx, cy - 2.0 * h / 3.0],
                     [cx + side / 2.0, cy + h / 3.0],
                     [cx - side / 2.0, cy + h / 3.0]])


def lift_pixels(camera: PinholeCamera, plane: Plane, uv: np.ndarray) -> np.ndarray:
    """Points (N, 3) m on ``plane`` seen at pixels ``uv`` (N, 2) of ``camera`` (distortion
    removed). InputError if a pixel's ray does not meet the plane (at or above the horizon)."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    X = plane.intersect(camera.rays(uv))
    bad = ~np.all(np.isfinite(X), axis=1)
    if np.any(bad):
        u, v = uv[int(np.argmax(bad))]
        raise InputError(f"triangle vertex ({u:g}, {v:g}) px: its viewing ray does not meet the "
                         "ground plane (at or above the horizon); pick pixels on the ground")
    return X


def triangle_on_ground(camera: PinholeCamera, plane: Plane,
                       uv: np.ndarray | None = None,
                       region: tuple[int, int, int, int] | None = None) -> np.ndarray:
    """The triangle's vertices (3, 3) m on the ground in camera-0 coordinates.

    ``uv`` (3, 2) are frame-0 pixels; None takes :func:`default_triangle_pixels` of ``region``
    (default: the whole frame). InputError for a degenerate triangle.
    """
    if uv is None:
        uv = default_triangle_pixels(region or (0, 0, camera.width, camera.height))
    uv = np.asarray(uv, dtype=float)
    if uv.shape != (3, 2) or not np.all(np.isfinite(uv)):
        raise InputError(f"triangle: expected 3 finite (x, y) pixel pairs, got shape {uv.shape}")
    d1, d2 = uv[1] - uv[0], uv[2] - uv[0]
    if abs(d1[0] * d2[1] - d1[1] * d2[0]) < 1.0:
        raise InputError("triangle: its 3 vertices are (nearly) on one line; give a real triangle")
    return lift_pixels(camera, plane, uv)


# ----------------------------------------------------------------------------- clipping


def clip_polygon(poly: np.ndarray, halfspaces: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: the part (M, 3) of the convex or concave polygon ``poly`` (N, 3)
    where ``a . X + b >= 0`` for every row ``(a1, a2, a3, b)`` of ``halfspaces`` (K, 4).
    Returns an empty (0, 3) array when nothing is left."""
    out = np.asarray(poly, dtype=float)
    for h in np.asarray(halfspaces, dtype=float):
        if len(out) == 0:
            break
        s = out @ h[:3] + h[3]
        nxt = np.roll(out, -1, axis=0)
        s_nxt = np.roll(s, -1)
        kept = []
        for p, q, sp, sq in zip(out, nxt, s, s_nxt):
            if sp >= 0:
                kept.append(p)
            if (sp >= 0) != (sq >= 0):
                kept.append(p + (sp / (sp - sq)) * (q - p))
        out = np.array(kept).reshape(-1, 3)
    return out


@lru_cache(maxsize=16)
def frustum_halfspaces(camera: PinholeCamera, near: float,
                       margin: float = FRUSTUM_MARGIN) -> np.ndarray:
    """Half-spaces (5, 4) of the near plane ``z >= near`` and of the view frustum through the
    image border widened by ``margin`` of the image on each side, in normalised coordinates
    (read-only, worked out once per camera, near plane and margin: not once per frame)."""
    w, h = camera.width, camera.height
    n = 16
    border = np.concatenate([
        np.stack([np.linspace(-0.5, w - 0.5, n), np.full(n, -0.5)], 1),
        np.stack([np.linspace(-0.5, w - 0.5, n), np.full(n, h - 0.5)], 1),
        np.stack([np.full(n, -0.5), np.linspace(-0.5, h - 0.5, n)], 1),
        np.stack([np.full(n, w - 0.5), np.linspace(-0.5, h - 0.5, n)], 1),
    ])
    r = camera.rays(border)
    xmin, xmax = float(r[:, 0].min()), float(r[:, 0].max())
    ymin, ymax = float(r[:, 1].min()), float(r[:, 1].max())
    mx, my = margin * (xmax - xmin), margin * (ymax - ymin)
    xmin, xmax, ymin, ymax = xmin - mx, xmax + mx, ymin - my, ymax + my
    out = np.array([[0.0, 0.0, 1.0, -near],                             # z >= near
                    [1.0, 0.0, -xmin, 0.0], [-1.0, 0.0, xmax, 0.0],     # xmin <= x / z <= xmax
                    [0.0, 1.0, -ymin, 0.0], [0.0, -1.0, ymax, 0.0]])    # ymin <= y / z <= ymax
    out.flags.writeable = False
    return out


def project_polygon(camera: PinholeCamera, poly_cam: np.ndarray, near: float) -> np.ndarray:
    """Image outline (M, 2) px of the polygon ``poly_cam`` (N, 3) m in camera coordinates,
    clipped to the near plane and the (widened) view frustum; (0, 2) when none of it is in view."""
    clipped = clip_polygon(poly_cam, frustum_halfspaces(camera, near))
    if len(clipped) < 3:
        return np.zeros((0, 2))
    if camera.has_distortion:
        t = np.linspace(0.0, 1.0, DISTORTED_EDGE_STEPS, endpoint=False)[:, None]
        nxt = np.roll(clipped, -1, axis=0)
        clipped = np.concatenate([p + t * (q - p) for p, q in zip(clipped, nxt)])
    return camera.project(clipped)


def polygon_area(uv: np.ndarray) -> float:
    """Area (px^2) of the simple polygon ``uv`` (N, 2) (shoelace formula); 0 for N < 3."""
    uv = np.asarray(uv, dtype=float)
    if len(uv) < 3:
        return 0.0
    x, y = uv[:, 0], uv[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def visible_fraction(camera: PinholeCamera, poly_cam: np.ndarray, near: float) -> float:
    """The share (0..1) of the image area of the polygon ``poly_cam`` (N, 3) m (camera
    coordinates, in front of the near plane) that falls inside the image; 0 when none of it
    is in front of the camera."""
    poly_cam = np.asarray(poly_cam, dtype=float)
    frustum = frustum_halfspaces(camera, near, margin=0.0)  # (the near plane's row first)
    if len(poly_cam) >= 3 and np.all(poly_cam @ frustum[:, :3].T + frustum[:, 3] >= 0):
        # every vertex in view (most frames of a drive): clipping would keep the polygon
        return 1.0 if polygon_area(camera.project(poly_cam)) > 0.0 else 0.0
    front = clip_polygon(poly_cam, np.array([[0.0, 0.0, 1.0, -near]]))
    if len(front) < 3:
        return 0.0
    whole = polygon_area(camera.project(front))
    inside = clip_polygon(front, frustum)
    if whole <= 0.0 or len(inside) < 3:
        return 0.0
    return min(1.0, polygon_area(camera.project(inside)) / whole)


def project_vertices(camera: PinholeCamera, X_world: np.ndarray,
                     world_from_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) of world points ``X_world`` (N, 3) seen from ``world_from_cam`` (4, 4), and
    a mask (N,) of those in front of the camera and inside the image."""
    cam_from_world = se3_inv(world_from_cam)
    Xc = X_world @ cam_from_world[:3, :3].T + cam_from_world[:3, 3]
    front = Xc[:, 2] > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = camera.project(np.where(front[:, None], Xc, np.nan))
    inside = front & (uv[:, 0] >= -0.5) & (uv[:, 0] <= camera.width - 0.5) \
        & (uv[:, 1] >= -0.5) & (uv[:, 1] <= camera.height - 0.5)
    return uv, inside


def vertex_errors(camera: PinholeCamera, X_world: np.ndarray, est_world_from_cam: np.ndarray,
                  gt_world_from_cam: np.ndarray) -> np.ndarray:
    """Image distance (N, V) px between the vertices ``X_world`` (V, 3) projected with the
    estimated and the true poses (N, 4, 4); NaN where the true vertex is not in view."""
    out = np.full((len(est_world_from_cam), len(X_world)), np.nan)
    for k, (est, gt) in enumerate(zip(est_world_from_cam, gt_world_from_cam)):
        uv_gt, seen = project_vertices(camera, X_world, gt)
        uv_est, _ = project_vertices(camera, X_world, est)
        d = np.linalg.norm(uv_est - uv_gt, axis=1)
        d = np.where(np.isfinite(d), d, np.inf)  # seen by the truth, behind the estimate
        out[k, seen] = d[seen]
    return out


# ----------------------------------------------------------------------------- points


@dataclass(frozen=True)
class AnchorPoints:
    """Observation points of the frame the overlay anchors on, in that frame's camera.

    ``X`` (N, 3) m, ``intensity`` (N,) grey levels, ``bound`` the residual shown red (grey
    levels), ``world_from_key`` (4, 4).
    """

    world_from_key: np.ndarray
    X: np.ndarray
    intensity: np.ndarray
    bound: float


def anchor_points(image: np.ndarray, camera: PinholeCamera, plane_key: Plane,
                  region: tuple[int, int, int, int], world_from_key: np.ndarray, *,
                  max_points: int = 1500) -> AnchorPoints:
    """The full-resolution observation points of ``image`` (H, W) float32 as the tracker picks
    them (Sobel above the default delta_1 inside the ground rectangle), at most ``max_points``."""
    sigma = estimate_noise_sigma(image)
    corners = rectangle_corners(camera, plane_key, region)
    pts = select_points(image, camera, plane_key, corners, level=0,
                        threshold=default_threshold(sigma), max_points=max_points)
    bound = inlier_bound(sigma)
    return AnchorPoints(np.array(world_from_key, dtype=float), pts.X,
                        pts.intensity.astype(np.float64), bound)


# ----------------------------------------------------------------------------- renderer


class OverlayRenderer:
    """Draws the glued triangle (and optionally the residual-coloured points) into frames.

    ``plane`` is the ground in camera-0 coordinates, ``triangle`` (3, 3) m its vertices there,
    ``region`` the ground rectangle (px) of init.yaml; ``max_points`` caps the points drawn
    (default: one per 150 px^2 of image). ``pixels`` (3, 2) px: where :meth:`advance` places
    each new triangle in the image (None: never a new one). ``scale`` resizes the output
    frames (lines and text keep a readable size). Keeps the current triangle and the anchor
    points between frames (when ``points``): they are re-picked on frames whose status is
    ``reanchored`` and when fewer than half of them stay in view.
    """

    def __init__(self, camera: PinholeCamera, plane: Plane, triangle: np.ndarray, *,
                 region: tuple[int, int, int, int] | None = None, points: bool = False,
                 max_points: int | None = None, style: OverlayStyle | None = None,
                 pixels: np.ndarray | None = None, scale: float = 1.0) -> None:
        if not 0.0 < scale <= 1.0:
            raise ValueError(f"scale: expected 0 < scale <= 1, got {scale!r}")
        self.camera = camera
        self.plane = plane
        self.triangle = np.asarray(triangle, dtype=float)
        self.pixels = None if pixels is None else np.asarray(pixels, dtype=float)
        self.region = region or (0, 0, camera.width, camera.height)
        self.points = points
        # about one point per 150 px^2 of image: dense enough to see, sparse enough to read
        self.max_points = max_points or max(100, camera.width * camera.height // 150)
        self.style = style or OverlayStyle()
        self.near = NEAR_FRACTION * plane.distance
        self.scale = float(scale)
        self.size = (max(1, int(round(camera.width * scale))),
                     max(1, int(round(camera.height * scale))))
        self.triangles = 1  # placed so far
        self._anchor: AnchorPoints | None = None
        self._new_triangle = False
        # sizes chosen for the output frame, drawn at full resolution before the resize
        side = min(self.size)
        self.thickness = max(1, int(round(max(1, round(side / 300.0)) / self.scale)))
        self.dot = max(1, int(round(max(1, round(side / 400.0)) / self.scale)))

    def advance(self, world_from_cam: np.ndarray | None, status: str | None = None) -> bool:
        """Move to a frame with pose ``world_from_cam`` (None: no pose) and ``status``; call
        it for every frame, drawn or not. Places a new triangle (at ``pixels``, lifted onto the
        ground with this pose) on a keyframe and when less than ``MIN_VISIBLE`` of the
        current one is in view; returns whether it did. A pose whose rays at ``pixels`` miss
        the ground keeps the current triangle."""
        if self.pixels is None or world_from_cam is None:
            return False
        if status not in KEYFRAME_STATUSES and self.visible(world_from_cam) >= MIN_VISIBLE:
            return False
        plane_cur = self.plane.in_frame(se3_inv(world_from_cam))
        X = plane_cur.intersect(self.camera.rays(self.pixels))
        if not np.all(np.isfinite(X)):
            return False
        self.triangle = X @ world_from_cam[:3, :3].T + world_from_cam[:3, 3]
        self.triangles += 1
        self._new_triangle = True
        return True

    def visible(self, world_from_cam: np.ndarray) -> float:
        """The share (0..1) of the triangle's image area inside the frame with ``world_from_cam``."""
        cam_from_world = se3_inv(world_from_cam)
        X = self.triangle @ cam_from_world[:3, :3].T + cam_from_world[:3, 3]
        return visible_fraction(self.camera, X, self.near)

    def triangle_outline(self, world_from_cam: np.ndarray) -> np.ndarray:
        """The triangle's clipped image outline (M, 2) px in the frame with ``world_from_cam``."""
        cam_from_world = se3_inv(world_from_cam)
        X = self.triangle @ cam_from_world[:3, :3].T + cam_from_world[:3, 3]
        return project_polygon(self.camera, X, self.near)

    def render(self, index: int, image: np.ndarray, world_from_cam: np.ndarray | None, *,
               status: str | None = None, msd: float | None = None,
               last: int | None = None) -> np.ndarray:
        """Frame ``index``: ``image`` (H, W) grey float32 0..255 with the overlay, BGR uint8
        of ``size`` (the frame's size times ``scale``).

        ``world_from_cam`` None (no pose) draws no triangle. ``status``/``msd`` (from
        motion.csv) and ``last`` (the last frame's index) go into the text line, and "new
        triangle" when :meth:`advance` placed one since the last frame drawn.
        """
        out = to_bgr(image)
        if world_from_cam is not None:
            if self.points:
                self._draw_points(out, index, image, world_from_cam, status)
            self._draw_triangle(out, world_from_cam)
        if self.size != (out.shape[1], out.shape[0]):
            out = cv2.resize(out, self.size, interpolation=cv2.INTER_AREA)
        text = f"frame {index}" + (f"/{last}" if last is not None else "")
        if world_from_cam is None:
            text += "  no pose"
        elif status:
            text += f"  {status}"
        if msd is not None and np.isfinite(msd):
            text += f"  msd {msd:.1f}"
        if self._new_triangle:
            text += "  new triangle"
            self._new_triangle = False
        draw_text(out, text, self.style.text)
        return out

    def _draw_triangle(self, out: np.ndarray, world_from_cam: np.ndarray) -> None:
        """The triangle into ``out`` (H, W, 3) BGR uint8, full size, in place."""
        st = self.style
        draw_polygon(out, self.triangle_outline(world_from_cam), fill=st.fill,
                     outline=st.outline, alpha=st.alpha, thickness=self.thickness)

    def _draw_points(self, out: np.ndarray, index: int, image: np.ndarray,
                     world_from_cam: np.ndarray, status: str | None) -> None:
        if self._anchor is None:
            self._reanchor(image, world_from_cam)
        a = self._anchor
        cur_from_key = se3_inv(world_from_cam) @ a.world_from_key
        Xc = a.X @ cur_from_key[:3, :3].T + cur_from_key[:3, 3]
        front = Xc[:, 2] > self.near
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = self.camera.project(np.where(front[:, None], Xc, np.nan))
        vals, valid = sample_bilinear(image, uv[:, 0], uv[:, 1])
        valid &= front
        r = vals.astype(np.float64) - a.intensity
        colours = residual_colours(r[valid], a.bound)
        scale = 1 << SHIFT
        centres = np.round(uv[valid] * scale).astype(np.int64)
        for (x, y), c in zip(centres, colours):
            cv2.circle(out, (int(x), int(y)), self.dot * scale, tuple(int(v) for v in c), -1,
                       cv2.LINE_AA, SHIFT)
        if status == FrameStatus.REANCHORED or valid.sum() <= 0.5 * len(valid):
            self._reanchor(image, world_from_cam)

    def _reanchor(self, image: np.ndarray, world_from_cam: np.ndarray) -> None:
        plane_cur = self.plane.in_frame(se3_inv(world_from_cam))
        self._anchor = anchor_points(image, self.camera, plane_cur, self.region, world_from_cam,
                                     max_points=self.max_points)
