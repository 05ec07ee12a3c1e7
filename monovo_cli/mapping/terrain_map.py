"""What tracking learned of the ground: the keyframes' observation points in the world frame
(docs/algorithm.md section 9, "The terrain products").

Every keyframe's finest-level observation points (keyframe camera, on its plane) are moved
into the world frame (camera 0's) with the keyframe's pose; a keyframe rebuilt in place (the
frame-0 plane corrected) replaces its points.

**Smoothed planes.** A keyframe's plane is the filter's belief when it was anchored
(:mod:`monovo_cli.core.plane.belief`): frame 0's is init.yaml's, whose distance the
mounting prior only corrects over the following keyframes (a camera that starts at a crest
of its suspension). The map is written at the end of the run, so each keyframe's points are
put on its plane as the whole chain knows it: the Rauch-Tung-Striebel backward pass over the
keyframe planes, with the filter's own covariances, process noise and innovations
(:class:`~monovo_cli.core.plane.belief.PlaneLink`); a point keeps its height off the plane
(its terrain grid) and moves along its ray, and goes into the world frame with its keyframe's
pose re-scaled with the smoothed planes, as trajectory.csv has it
(:mod:`monovo_cli.mapping.smoothing`); motion.csv stays the filter's, as streamed. Without
it the map's error sits in the first keyframes.

**What the terrain grid misses.** When a keyframe is left, its points are searched along their
rays against its successor's image (or the last frame's) at the successor's pose
(``refine="sweep"``, the default: :func:`~monovo_cli.mapping.terrain_depths.sweep_depths`): a point
whose patch clearly matches at another height (a rock the 0.4 m terrain grid does not see) moves
there; the rest stay on the terrain_grid. ``refine=None`` keeps every point where tracking put
it.

**The ground frame.** Heights are measured in the ground frame of the first keyframe's
smoothed plane (frame 0's ground as tracking measured it: init.yaml's plane, or the tilt the
first frames corrected it to, smoothed): origin at the foot of camera 0 on the plane,
``forward`` camera 0's optical axis projected onto it, ``right = normal x forward``,
``up = -normal`` (heights above the plane, m), the axes of ``trajectory.png``.
:meth:`TerrainMap.height_grid` bins the points into square cells of the driven strip: a
cell's height is the mean of its points'. :func:`heights_off_best_plane` measures the same
cells from the best-fit plane of the mapped points instead (the relief alone, as
heightmap.png draws it).

Pure: no I/O (the files are written by :mod:`monovo_cli.io.terrain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.mapping.smoothing import SmoothedDrive
from monovo_cli.mapping.terrain_depths import sweep_depths

POINTS_PER_KEYFRAME = 10000  # at most this many of a keyframe's points (every k-th) are kept
CELL = 0.05  # m, default cell of the height grid


def ground_frame(plane: Plane) -> np.ndarray:
    """``ground_from_world`` (4x4): the ground frame of ``plane`` (init.yaml's, camera 0)."""
    n = plane.normal
    z = np.array([0.0, 0.0, 1.0])
    forward = z - (z @ n) * n
    if np.linalg.norm(forward) < 1e-9:  # looking straight down: image up
        y = np.array([0.0, -1.0, 0.0])
        forward = y - (y @ n) * n
    forward /= np.linalg.norm(forward)
    right = np.cross(n, forward)
    R = np.stack([right, forward, -n])  # rows: the ground axes in world coordinates
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ (plane.distance * n)
    return T


@dataclass(frozen=True)
class HeightGrid:
    """Heights of the driven strip: ``height`` (H, W) m (NaN where no point fell), ``count``
    (H, W) points per cell; cell ``[j, i]`` covers right ``x0 + i * cell`` ..  ``+ cell`` and
    forward ``y0 + j * cell`` .. ``+ cell`` (m, ground frame)."""

    x0: float
    y0: float
    cell: float
    height: np.ndarray
    count: np.ndarray


def heights_off_best_plane(grid: HeightGrid) -> HeightGrid:
    """``grid`` with each cell's height taken from the best-fit plane of the mapped points
    instead of the ground frame's plane: the least-squares plane ``h = a * right +
    b * forward + c`` through the cells' centres and heights, each cell weighted by its
    point count (the points' own least-squares plane, up to their spread within a cell).

    Frame 0's local ground is tilted against the terrain as a whole wherever frame 0 stands
    on a slope or a swell; measured from it, rolling terrain shows as a ramp. Measured from
    the best-fit plane, the heights are the relief alone (m, NaN cells stay NaN). A grid
    with fewer than three filled cells, or whose cells lie on one line, is returned with
    its mean height removed only.
    """
    ok = grid.count > 0
    if not ok.any():
        return grid
    j, i = np.nonzero(ok)
    x = grid.x0 + (i + 0.5) * grid.cell
    y = grid.y0 + (j + 0.5) * grid.cell
    h, w = grid.height[ok], np.sqrt(grid.count[ok].astype(float))
    A = np.stack([x, y, np.ones_like(x)], axis=1)
    if len(h) >= 3 and np.linalg.matrix_rank(A) == 3:
        coef = np.linalg.lstsq(A * w[:, None], h * w, rcond=None)[0]
    else:
        coef = np.array([0.0, 0.0, np.average(h, weights=w * w)])
    jj, ii = np.indices(grid.height.shape)
    plane = coef[0] * (grid.x0 + (ii + 0.5) * grid.cell) + \
        coef[1] * (grid.y0 + (jj + 0.5) * grid.cell) + coef[2]
    return HeightGrid(grid.x0, grid.y0, grid.cell, grid.height - plane, grid.count)


@dataclass(frozen=True)
class _Chunk:
    """A keyframe's kept points: ``X`` (N, 3) in its camera, ``intensity`` (N,), its pose,
    its plane (its camera) and the link of that plane to the previous keyframe's."""

    X: np.ndarray
    intensity: np.ndarray
    world_from_key: np.ndarray
    plane: Plane
    link: PlaneLink | None
    samples: np.ndarray | None = None  # (none kept: hindsight scales its motions alone)


class TerrainMap:
    """The keyframes' observation points in the world frame (module docstring).

    ``plane``: init.yaml's ground in camera 0 (the ground frame until a keyframe comes); at
    most ``points_per_keyframe`` of a keyframe's finest points are kept (every k-th);
    ``refine``: ``"sweep"`` (:func:`~monovo_cli.mapping.terrain_depths.sweep_depths`) or None.
    Feed it with :meth:`add` per keyframe and :meth:`finish` with the last frame; the
    queries place the points on the keyframe planes and poses of a
    :class:`~monovo_cli.mapping.smoothing.SmoothedDrive` when given one, else as tracked.
    """

    def __init__(self, plane: Plane, points_per_keyframe: int = POINTS_PER_KEYFRAME, *,
                 refine: str | None = "sweep") -> None:
        self.plane0 = plane  # (init.yaml's: the ground frame until a keyframe comes)
        self.points_per_keyframe = int(points_per_keyframe)
        if refine not in ("sweep", None):
            raise ValueError(f"refine: expected 'sweep' or None, got {refine!r}")
        self.refine = refine
        self._chunks: dict[int, _Chunk] = {}
        self._last: Keyframe | None = None
        self._last_image: np.ndarray | None = None
        self.refined = 0  # points whose depth the images updated

    @property
    def keyframes(self) -> list[tuple[int, _Chunk]]:
        """``(frame index, keyframe record)`` of every keyframe added, oldest first: what
        :func:`~monovo_cli.mapping.smoothing.smooth_drive` takes as its ``keys``."""
        return [(k, self._chunks[k]) for k in sorted(self._chunks)]

    def ground_from_world(self, drive: SmoothedDrive | None = None) -> np.ndarray:
        """4x4: the ground frame (module docstring) of the first keyframe's plane, as
        ``drive`` smoothed it (None: as tracked)."""
        if not self._chunks:
            return ground_frame(self.plane0)
        _, plane, pose = self._placed(drive)[0]
        return ground_frame(plane.in_frame(pose))

    def add(self, key: Keyframe, image: np.ndarray | None = None) -> None:
        """A keyframe's finest-level points; replaces an earlier keyframe of the same index.
        ``image`` (H, W) float32: the keyframe's own image, against which the previous
        keyframe's depths are refined (at the new keyframe's pose) when ``key`` was anchored
        by a re-anchor (it has a plane link), not by a re-initialisation, whose pose was
        bridged by the prediction."""
        last = self._last
        if last is not None and last.index != key.index and image is not None and \
                key.link is not None:  # (not at a re-initialisation's bridged pose)
            self._refine(last, image, se3_inv(key.world_from_key) @ last.world_from_key)
        self._store(key, key.levels[0].points.X[::self._step(key)])
        if last is None or last.index != key.index:  # (a rebuilt keyframe keeps its image)
            self._last_image = image
        self._last = key

    def finish(self, image: np.ndarray | None, world_from_cam: np.ndarray) -> None:
        """The last frame (``image``, pose ``world_from_cam``; None: no image, or a lost frame
        whose pose is only predicted): refine the last keyframe's depths against it."""
        last = self._last
        if last is not None and image is not None:
            self._refine(last, image, se3_inv(world_from_cam) @ last.world_from_key)

    def _step(self, key: Keyframe) -> int:
        return max(1, -(-len(key.levels[0].points) // self.points_per_keyframe))

    def _store(self, key: Keyframe, X: np.ndarray) -> None:
        """``X`` (N, 3): the subsampled points of ``key`` in its camera."""
        pts = key.levels[0].points
        ok = np.all(np.isfinite(X), axis=1)
        self._chunks[key.index] = _Chunk(
            X[ok], pts.intensity[::self._step(key)][ok].astype(np.float32),
            np.array(key.world_from_key), key.plane, key.link)

    def _placed(self, drive: SmoothedDrive | None) -> list[tuple[_Chunk, Plane, np.ndarray]]:
        """Each keyframe's chunk, oldest first, with its plane (its camera) and its pose
        ``world_from_key``: as ``drive`` smoothed them in hindsight (None: as tracked)."""
        chunks = self.keyframes
        if drive is None:
            return [(c, c.plane, c.world_from_key) for _, c in chunks]
        return [(c, *drive.keyframe(k)) for k, c in chunks]

    def _refine(self, key: Keyframe, image: np.ndarray, cur_from_key: np.ndarray) -> None:
        pts = key.levels[0].points
        if self.refine is None or pts.camera.has_distortion or self._last_image is None or \
                float(np.linalg.norm(cur_from_key[:3, 3])) < 1e-3 * key.plane.distance:
            return  # (no baseline: the images cannot tell depths apart)
        X, moved = sweep_depths(pts.camera, key.plane, pts.X[::self._step(key)],
                                self._last_image, image, cur_from_key)
        self._store(key, X)
        self.refined += int(np.count_nonzero(moved))

    def __len__(self) -> int:
        return sum(len(c.X) for c in self._chunks.values())

    def points(self, drive: SmoothedDrive | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(X (N, 3) world frame m, intensity (N,) grey levels)`` of all keyframes, in order:
        each keyframe's points moved along their rays from its plane to its plane as
        ``drive`` smoothed it (keeping their heights off it), then into the world frame with
        its smoothed pose (``drive`` None: the planes and poses as tracked)."""
        if not self._chunks:
            return np.zeros((0, 3)), np.zeros(0, np.float32)
        out = []
        for c, new, pose in self._placed(drive):
            X = c.X
            if new is not c.plane:
                h = c.plane.distance - X @ c.plane.normal  # heights off the plane
                X = X * ((new.distance - h) / (X @ new.normal))[:, None]
            out.append(X @ pose[:3, :3].T + pose[:3, 3])
        return (np.concatenate(out),
                np.concatenate([self._chunks[k].intensity for k in sorted(self._chunks)]))

    def ground_points(self, drive: SmoothedDrive | None = None) -> np.ndarray:
        """The points (N, 3) in the ground frame: right, forward, height (m) (``drive`` as
        for :meth:`points`)."""
        X, _ = self.points(drive)
        G = self.ground_from_world(drive)
        return X @ G[:3, :3].T + G[:3, 3]

    def height_grid(self, cell: float = CELL, drive: SmoothedDrive | None = None) -> HeightGrid:
        """The mean height per ``cell`` x ``cell`` m cell over the points' extent (``drive``
        as for :meth:`points`)."""
        P = self.ground_points(drive)
        if not len(P):
            return HeightGrid(0.0, 0.0, cell, np.full((0, 0), np.nan), np.zeros((0, 0), int))
        x0 = np.floor(P[:, 0].min() / cell) * cell
        y0 = np.floor(P[:, 1].min() / cell) * cell
        i = np.floor((P[:, 0] - x0) / cell).astype(np.int64)
        j = np.floor((P[:, 1] - y0) / cell).astype(np.int64)
        w, h = int(i.max()) + 1, int(j.max()) + 1
        flat = j * w + i
        count = np.bincount(flat, minlength=w * h)
        total = np.bincount(flat, weights=P[:, 2], minlength=w * h)
        with np.errstate(invalid="ignore", divide="ignore"):
            height = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        return HeightGrid(float(x0), float(y0), float(cell), height.reshape(h, w),
                          count.reshape(h, w))
