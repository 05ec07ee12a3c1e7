"""The glued triangle draped over the learned terrain (``monovo overlay --terrain``).

A height map (:class:`~monovo_cli.mapping.terrain_map.HeightGrid`, ``monovo track
--terrain-out``) gives heights above the ground plane of its own ground frame
(``ground_from_world``: right, forward, up; world = camera 0). The triangle on the plane
(:mod:`monovo_cli.viz.overlay`) is subdivided into ``steps`` x ``steps`` small facets
(:func:`subdivide_triangle`), and every vertex is moved along the ground frame's up to the
height map's height at its (right, forward) (:func:`drape_points`): bilinear between the
centres of the four cells around it, over those that hold data. Where none of the four
does (off the driven strip, or a hole), the vertex stays on the plane: the overlay falls
back to the plane triangle there. The corners are first slid along the rays of the pixels
they were placed at onto the map (:func:`along_rays_onto_map`), so that the draped
triangle starts where it was placed (``--triangle``, or the default pixels); a corner
whose ray finds no map stays where the plane put it.

Drawing: each facet is clipped in 3D against the near plane and the widened view frustum
(:func:`~monovo_cli.viz.overlay.frustum_halfspaces`) and projected; the facets' union is
filled once with the style's opacity (so overlapping facets, where the terrain folds in
front of itself, are not darkened twice); the triangle's outline and every ``GRID_EVERY``-th
line of the subdivision (thin) are drawn as clipped, anti-aliased segments, so the ground's
bumps show as bent lines. Facets and segments are short, so with lens distortion they are
projected vertex by vertex. Whether a new triangle is placed (``advance``) is decided, as
without a map, on the flat triangle through the three corners.

Pure: arrays in, arrays out; no files, no printing.
"""

from __future__ import annotations

import cv2
import numpy as np

from monovo_cli.geometry.lie import se3_inv
from monovo_cli.mapping.terrain_map import HeightGrid
from monovo_cli.viz.draw import SHIFT
from monovo_cli.viz.overlay import OverlayRenderer, clip_polygon, frustum_halfspaces

DRAPE_STEPS = 16  # segments per triangle edge: DRAPE_STEPS^2 = 256 facets
GRID_EVERY = 4    # a thin line of the subdivision every this many segments
ITERATIONS = 40   # of the fixed-point search along a corner's ray
SETTLED = 1e-5    # m: the ray's point within this of the map's height


def grid_heights(grid: HeightGrid, right: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """Heights (N,) m of ``grid`` at ground-frame points ``right``, ``forward`` (N,) m:
    bilinear between the four surrounding cell centres, weighted over those with data; NaN
    where none of the four has any."""
    right, forward = np.asarray(right, dtype=float), np.asarray(forward, dtype=float)
    gh, gw = grid.height.shape
    u = (right - grid.x0) / grid.cell - 0.5
    v = (forward - grid.y0) / grid.cell - 0.5
    i0, j0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - i0, v - j0
    total = np.zeros(len(u))
    weight = np.zeros(len(u))
    for di, dj, w in ((0, 0, (1 - fu) * (1 - fv)), (1, 0, fu * (1 - fv)),
                      (0, 1, (1 - fu) * fv), (1, 1, fu * fv)):
        i, j = i0 + di, j0 + dj
        inside = (i >= 0) & (i < gw) & (j >= 0) & (j < gh)
        h = np.full(len(u), np.nan)
        h[inside] = grid.height[j[inside], i[inside]]
        ok = np.isfinite(h) & (w > 0)
        total[ok] += w[ok] * h[ok]
        weight[ok] += w[ok]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(weight > 0, total / weight, np.nan)


def drape_points(X: np.ndarray, grid: HeightGrid,
                 ground_from_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) m moved along the ground frame's up onto the height map, and a mask
    (N,) of those that had data; the others are returned unchanged (on their plane)."""
    X = np.asarray(X, dtype=float).reshape(-1, 3)
    R, t = ground_from_world[:3, :3], ground_from_world[:3, 3]
    g = X @ R.T + t
    h = grid_heights(grid, g[:, 0], g[:, 1])
    on = np.isfinite(h)
    g[on, 2] = h[on]
    out = X.copy()
    out[on] = (g[on] - t) @ R  # world = R^T (ground - t)
    return out, on


def along_rays_onto_map(X: np.ndarray, centre: np.ndarray, grid: HeightGrid,
                        ground_from_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) m moved along their rays from the camera ``centre`` (3,) (world) to
    where the rays meet the height map, and a mask (N,) of those that did; the others (the
    map has no data on the way, or the iteration did not settle: a ray grazing a slope)
    are returned unchanged."""
    X = np.asarray(X, dtype=float).reshape(-1, 3)
    R, t0 = ground_from_world[:3, :3], ground_from_world[:3, 3]
    c = R @ np.asarray(centre, dtype=float) + t0
    d = X @ R.T + t0 - c  # ray directions in the ground frame, reaching X at t = 1
    t = np.ones(len(X))
    ok = d[:, 2] < -1e-12  # the ray goes down
    dz = np.where(ok, d[:, 2], -1.0)
    for _ in range(ITERATIONS):  # t += (h(p) - p_z) / d_z: a contraction on gentle slopes
        p = c + t[:, None] * d
        step = (grid_heights(grid, p[:, 0], p[:, 1]) - p[:, 2]) / dz
        ok &= np.isfinite(step)
        t = np.where(ok, t + step, t)
        ok &= t > 0
    p = c + t[:, None] * d
    ok &= np.abs(grid_heights(grid, p[:, 0], p[:, 1]) - p[:, 2]) < SETTLED
    out = X.copy()
    out[ok] = (p[ok] - t0) @ R
    return out, ok


def subdivide_triangle(triangle: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The triangle ``(A, B, C)`` (3, 3) split into ``steps^2`` similar facets: vertices
    (M, 3), M = (steps + 1)(steps + 2) / 2, at ``A + i/steps (B - A) + j/steps (C - A)``
    (i, j >= 0, i + j <= steps; the first is A, the corners are exact), and facets (steps^2, 3)
    of vertex indices, all wound as ``(A, B, C)``."""
    index, faces = _lattice(steps)
    ij = np.argwhere(index >= 0)  # (i, j) in the order of the indices
    ij = ij[np.argsort(index[ij[:, 0], ij[:, 1]])]
    A, B, C = np.asarray(triangle, dtype=float)
    V = A + (ij[:, :1] / steps) * (B - A) + (ij[:, 1:] / steps) * (C - A)
    return V, faces


def _lattice(steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex index (steps + 1, steps + 1) of lattice point (i, j) (-1 off the triangle) and
    the facets (steps^2, 3)."""
    n = int(steps)
    if n < 1:
        raise ValueError(f"steps: expected >= 1, got {steps!r}")
    index = np.full((n + 1, n + 1), -1, np.int64)
    k = 0
    for i in range(n + 1):
        for j in range(n + 1 - i):
            index[i, j] = k
            k += 1
    faces = []
    for i in range(n):
        for j in range(n - i):
            faces.append((index[i, j], index[i + 1, j], index[i, j + 1]))
            if i + j <= n - 2:
                faces.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
    return index, np.array(faces, np.int64)


def subdivision_lines(steps: int, every: int) -> tuple[np.ndarray, np.ndarray]:
    """Edges (E, 2) of vertex indices (:func:`subdivide_triangle`'s) of the triangle's outline,
    and of the interior lines parallel to its sides every ``every`` segments."""
    index, _ = _lattice(steps)
    n = int(steps)
    outline, inner = [], []
    for i in range(n + 1):
        for j in range(n + 1 - i):
            for di, dj, level in ((1, 0, j), (0, 1, i), (-1, 1, n - i - j)):
                # the edge to (i + di, j + dj) lies on the line j, i or i + j = const
                a, b = i + di, j + dj
                if a < 0 or b < 0 or a + b > n:
                    continue
                if level == 0:
                    outline.append((index[i, j], index[a, b]))
                elif level % every == 0:
                    inner.append((index[i, j], index[a, b]))
    return np.array(outline, np.int64).reshape(-1, 2), np.array(inner, np.int64).reshape(-1, 2)


def clip_segments(P: np.ndarray, Q: np.ndarray,
                  halfspaces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of the segments ``P[k] Q[k]`` (N, 3) where ``a . X + b >= 0`` for every row
    ``(a1, a2, a3, b)`` of ``halfspaces`` (K, 4): new ends (N, 3), (N, 3) and a mask (N,) of
    the segments with something left."""
    P, Q = np.asarray(P, dtype=float), np.asarray(Q, dtype=float)
    t0, t1 = np.zeros(len(P)), np.ones(len(P))
    keep = np.ones(len(P), bool)
    for h in np.asarray(halfspaces, dtype=float):
        sp, sq = P @ h[:3] + h[3], Q @ h[:3] + h[3]
        keep &= (sp >= 0) | (sq >= 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = sp / (sp - sq)
        t0 = np.where((sp < 0) & (sq >= 0), np.maximum(t0, t), t0)
        t1 = np.where((sq < 0) & (sp >= 0), np.minimum(t1, t), t1)
    keep &= t0 <= t1
    d = Q - P
    return P + t0[:, None] * d, P + t1[:, None] * d, keep


class DrapedOverlayRenderer(OverlayRenderer):
    """:class:`~monovo_cli.viz.overlay.OverlayRenderer` drawing each triangle draped over the
    height map ``grid`` whose ground frame is ``ground_from_world`` (4, 4) (module docstring);
    ``steps`` segments per edge. ``seen_from`` (4, 4): the pose of the camera whose pixels
    the triangle's corners were lifted from (frame 0's, the identity, for the first
    triangle); the corners then slide along those rays onto the map, so that they stay at
    those pixels. Each new triangle (:meth:`advance`) does the same from its frame. The other
    arguments are the base class's."""

    def __init__(self, *args, grid: HeightGrid, ground_from_world: np.ndarray,
                 steps: int = DRAPE_STEPS, seen_from: np.ndarray | None = None,
                 **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.grid = grid
        self.ground_from_world = np.asarray(ground_from_world, dtype=float)
        self.steps = int(steps)
        if seen_from is not None:
            self._onto_map(seen_from)
        _, self.faces = subdivide_triangle(np.eye(3), self.steps)
        self.outline_edges, self.inner_edges = subdivision_lines(self.steps, GRID_EVERY)
        self._mesh_of: np.ndarray | None = None
        self._mesh = (np.zeros((0, 3)), np.zeros(0, bool))

    def _onto_map(self, world_from_cam: np.ndarray) -> None:
        self.triangle, _ = along_rays_onto_map(self.triangle, world_from_cam[:3, 3], self.grid,
                                               self.ground_from_world)

    def advance(self, world_from_cam: np.ndarray | None, status: str | None = None) -> bool:
        """:meth:`OverlayRenderer.advance`, a newly placed triangle then draped onto the map."""
        placed = super().advance(world_from_cam, status)
        if placed:
            self._onto_map(world_from_cam)
        return placed

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The current triangle's draped vertices (M, 3) m (world frame) and the mask (M,) of
        those on the height map (the others lie on the plane)."""
        if self._mesh_of is not self.triangle:
            V, _ = subdivide_triangle(self.triangle, self.steps)
            self._mesh = drape_points(V, self.grid, self.ground_from_world)
            self._mesh_of = self.triangle
        return self._mesh

    def _camera_points(self, world_from_cam: np.ndarray) -> np.ndarray:
        cam_from_world = se3_inv(world_from_cam)
        return self.mesh()[0] @ cam_from_world[:3, :3].T + cam_from_world[:3, 3]

    def image_facets(self, world_from_cam: np.ndarray) -> list[np.ndarray]:
        """The facets' clipped image polygons, each (k, 2) px, in the frame ``world_from_cam``."""
        Vc = self._camera_points(world_from_cam)
        H = frustum_halfspaces(self.camera, self.near)
        s = (Vc @ H[:, :3].T + H[:, 3])[self.faces]  # (F, 3 vertices, K half-spaces)
        inside = np.all(s >= 0, axis=(1, 2))
        outside = np.any(np.all(s < 0, axis=1), axis=1)
        front = Vc[:, 2] >= self.near
        with np.errstate(invalid="ignore", divide="ignore"):
            uv = self.camera.project(np.where(front[:, None], Vc, 1.0))
        polys = list(uv[self.faces[inside]])
        for f in self.faces[~inside & ~outside]:
            clipped = clip_polygon(Vc[f], H)
            if len(clipped) >= 3:
                polys.append(self.camera.project(clipped))
        return polys

    def image_segments(self, world_from_cam: np.ndarray, edges: np.ndarray) -> np.ndarray:
        """The clipped image segments (E', 2, 2) px of ``edges`` (E, 2) (vertex indices) in the
        frame ``world_from_cam``."""
        Vc = self._camera_points(world_from_cam)
        P, Q, keep = clip_segments(Vc[edges[:, 0]], Vc[edges[:, 1]],
                                   frustum_halfspaces(self.camera, self.near))
        if not np.any(keep):
            return np.zeros((0, 2, 2))
        return np.stack([self.camera.project(P[keep]), self.camera.project(Q[keep])], axis=1)

    def _draw_triangle(self, out: np.ndarray, world_from_cam: np.ndarray) -> None:
        st = self.style
        polys = self.image_facets(world_from_cam)
        if not polys:
            return
        h, w = out.shape[:2]
        scale = 1 << SHIFT
        allpts = np.concatenate(polys)
        x0 = max(int(np.floor(allpts[:, 0].min())) - 1, 0)
        y0 = max(int(np.floor(allpts[:, 1].min())) - 1, 0)
        x1 = min(int(np.ceil(allpts[:, 0].max())) + 2, w)
        y1 = min(int(np.ceil(allpts[:, 1].max())) + 2, h)
        if x0 < x1 and y0 < y1:
            mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
            origin = np.array([x0, y0], float)
            for p in polys:
                local = np.round((p - origin) * scale).astype(np.int32)
                cv2.fillConvexPoly(mask, local, 255, cv2.LINE_8, SHIFT)
            roi = out[y0:y1, x0:x1]
            m = mask > 0
            blend = st.alpha * np.array(st.fill, float) + (1.0 - st.alpha) * roi[m]
            roi[m] = np.clip(np.rint(blend), 0, 255).astype(np.uint8)
        for edges, thick in ((self.inner_edges, max(1, self.thickness // 2)),
                             (self.outline_edges, self.thickness)):
            seg = self.image_segments(world_from_cam, edges)
            if len(seg):
                pts = np.round(seg * scale).astype(np.int32)
                cv2.polylines(out, list(pts.reshape(-1, 2, 1, 2)), False, st.outline, thick,
                              cv2.LINE_AA, SHIFT)
