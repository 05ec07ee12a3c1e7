"""The overlay command's pipeline: a sequence and a trajectory in, the glued-triangle video out.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.sources import FrameSource
from monovo_cli.pipeline.tracking import open_sequence

if TYPE_CHECKING:
    from monovo_cli.geometry.camera import PinholeCamera
    from monovo_cli.geometry.plane import Plane
    from monovo_cli.viz.overlay import OverlayRenderer

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class OverlaySummary:
    """What :func:`overlay_sequence` wrote: ``frames`` rendered to ``out`` (``kind`` mp4, gif
    or png) in ``seconds``, with ``triangles`` triangles placed."""

    frames: int
    out: Path
    kind: str
    seconds: float
    triangles: int = 1


def _trajectory_by_frame(path: Path, frames: FrameSource) -> dict[int, np.ndarray]:
    """``{frame: world_from_cam}`` from a trajectory.csv, or a TUM file matched to the frames'
    timestamps (within 1e-6 s)."""
    from monovo_cli.io.formats import read_trajectory_csv, read_tum

    if path.suffix.lower() == ".tum" or path.suffix.lower() == ".txt":
        ts, poses = read_tum(path)
        pos = np.searchsorted(frames.timestamps, ts)
        out = {}
        for t, p, T in zip(ts, pos, poses):
            hit = [j for j in (p - 1, p) if 0 <= j < len(frames)
                   and abs(frames.timestamps[j] - t) <= 1e-6]
            if not hit:
                raise InputError(f"{path}: timestamp {float(t)!r} matches no frame of {frames.dir} "
                                 "(frame k has timestamp k, or its line in times.txt)")
            out[hit[0]] = T
        return out
    idx, _, poses = read_trajectory_csv(path)
    if idx.max() >= len(frames):
        raise InputError(f"{path}: has frame {int(idx.max())} but {frames.dir} holds only "
                         f"{len(frames)} frames; is it the trajectory of this sequence?")
    return {int(k): T for k, T in zip(idx, poses)}


def _draped_renderer(terrain: Path, camera: PinholeCamera, plane: Plane, tri: np.ndarray,
                     kwargs: dict) -> OverlayRenderer:
    """The renderer draping the triangles over the height map ``terrain``; logs how much of
    the first triangle the map covers."""
    from monovo_cli.io.terrain import read_heightmap
    from monovo_cli.viz.drape import DrapedOverlayRenderer

    grid, ground_from_world = read_heightmap(terrain)
    renderer = DrapedOverlayRenderer(camera, plane, tri, grid=grid,
                                     ground_from_world=ground_from_world, seen_from=np.eye(4),
                                     **kwargs)
    share = float(np.mean(renderer.mesh()[1]))
    if share == 0.0:
        log.warning("%s: the height map covers none of the first triangle; it is drawn on the "
                    "plane until a triangle falls on the mapped strip", terrain)
    else:
        log.info("%s: %.0f %% of the first triangle on the height map (%d x %d cells of %g m)",
                 terrain, 100.0 * share, grid.height.shape[1], grid.height.shape[0], grid.cell)
    return renderer


def overlay_sequence(seq: Path, params: Path | None, trajectory: Path, out: str | Path, *,
                     triangle_px: np.ndarray | None = None, points: bool = False,
                     fps: float = 10.0, scale: float = 1.0, every: int = 1,
                     overwrite: bool = False, topic: str | None = None,
                     terrain: Path | None = None,
                     progress: Callable[[int, int], None] | None = None) -> OverlaySummary:
    """``monovo overlay``: render the glued triangle into every frame of ``seq``.

    ``trajectory`` is a trajectory.csv (or .tum) of the sequence; status and msd come from
    motion.csv beside it when it is there. ``triangle_px`` (3, 2) frame-0 pixels (None: the
    default triangle); a new triangle is placed at the same pixels at every keyframe (status
    ``reanchored`` / ``reinit`` in motion.csv) and when the current one leaves the view
    (:meth:`~monovo_cli.viz.overlay.OverlayRenderer.advance`). Frames 0, ``every``,
    2 ``every``, ... up to the last posed frame are written to ``out`` (.mp4, .gif or a
    directory of PNGs, :mod:`monovo_cli.io.video`), resized by ``scale`` (0 < scale <= 1);
    frames without a pose show no triangle. ``topic`` the image topic of a ROS bag.
    ``terrain``: a ``heightmap.csv`` of ``monovo track --terrain-out`` (or the directory
    holding it): each triangle is then draped over that height map, on the plane where the
    map has no data (:mod:`monovo_cli.viz.drape`).
    """
    from monovo_cli.io.formats import read_motion_stats
    from monovo_cli.io.video import open_sink
    from monovo_cli.viz.overlay import OverlayRenderer, default_triangle_pixels, triangle_on_ground

    if not 0.0 < scale <= 1.0:
        raise InputError(f"--scale: expected 0 < scale <= 1, got {scale:g}")
    if every < 1:
        raise InputError(f"--every: expected a whole number >= 1, got {every}")
    t0 = time.perf_counter()
    opened = open_sequence(seq, params, topic=topic)
    frames, cfg = opened.frames, opened.config
    trajectory = Path(trajectory)
    poses = _trajectory_by_frame(trajectory, frames)
    motion = trajectory.parent / "motion.csv"
    stats = read_motion_stats(motion) if motion.is_file() else {}
    plane, region = cfg.plane, cfg.region
    tri = triangle_on_ground(cfg.camera, plane, triangle_px, region)
    pixels = default_triangle_pixels(region) if triangle_px is None else triangle_px
    kwargs = dict(region=region, points=points, pixels=pixels, scale=scale)
    if terrain is None:
        renderer = OverlayRenderer(cfg.camera, plane, tri, **kwargs)
    else:
        renderer = _draped_renderer(Path(terrain), cfg.camera, plane, tri, kwargs)
    last = max(poses)
    if len(poses) < len(frames):  # e.g. an interrupted run: rendered, but said
        log.warning("%s: poses for %d of the %d frames of %s; frames without one show no "
                    "triangle and the video ends at frame %d", trajectory, len(poses),
                    len(frames), frames.dir, last)
    sink = open_sink(out, fps=fps, overwrite=overwrite)
    try:
        for k in range(last + 1):
            status, msd = stats.get(k, ("start" if k == 0 else None, None))
            if k > 0:
                renderer.advance(poses.get(k), status)
            if k % every == 0:
                frame = frames.read(k)
                sink.write(renderer.render(k, frame.image, poses.get(k), status=status,
                                           msd=msd, last=last))
            if progress is not None:
                progress(k + 1, last + 1)
        sink.close()
    except BaseException:
        sink.abort()
        raise
    return OverlaySummary(sink.frames, sink.path, sink.kind, time.perf_counter() - t0,
                          renderer.triangles)
