"""What ``monovo track`` writes at the end of a run, from the run in memory:
``trajectory.png`` and the terrain products (terrain.ply, heightmap.csv, heightmap.png)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.core.run import TrackRun
from monovo_cli.geometry.plane import Plane
from monovo_cli.mapping.smoothing import SmoothedDrive
from monovo_cli.mapping.terrain_map import TerrainMap


def sequence_name(source: Path) -> str:
    """The name a sequence goes by in the plots' titles: its folder's name (the folder
    holding ``frames/`` when its frames are there), or its video's or bag's file name.
    ``source``: where its frames are read (``FrameSource.dir``)."""
    from monovo_cli.io.sources import FRAMES_SUBDIR

    path = Path(source).resolve()
    return path.parent.name if path.name == FRAMES_SUBDIR else path.name


def write_terrain(out_dir: Path, terrain: TerrainMap, world_from_cam: np.ndarray,
                  drive: SmoothedDrive | None, name: str) -> bytes:
    """``terrain.ply``, ``heightmap.csv`` and ``heightmap.png`` (the camera path
    ``world_from_cam`` (N, 4, 4) drawn over the heights) of ``terrain`` into ``out_dir``
    (:mod:`monovo_cli.io.terrain`), its keyframes placed as ``drive`` smoothed them (None: as
    tracked). heightmap.csv holds the heights above frame 0's ground (the ground frame of
    :mod:`monovo_cli.mapping.terrain_map`, which ``overlay --terrain`` reads back);
    heightmap.png draws them above the best-fit plane of the mapped points
    (:func:`~monovo_cli.mapping.terrain_map.heights_off_best_plane`), the relief without
    frame 0's local tilt. ``name``: the sequence's, for the title. Returns heightmap.png's bytes."""
    from monovo_cli.io.terrain import write_heightmap_csv, write_ply
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.mapping.terrain_map import heights_off_best_plane
    from monovo_cli.viz.heightmap import plot_height_map

    X, intensity = terrain.points(drive)
    write_ply(out_dir / "terrain.ply", X, intensity)
    grid = terrain.height_grid(drive=drive)
    G = terrain.ground_from_world(drive)
    write_heightmap_csv(out_dir / "heightmap.csv", grid, G)
    path = world_from_cam[:, :3, 3] @ G[:3, :3].T + G[:3, 3]
    title = f"{name}: heights above the best-fit plane of the {len(X)} points"
    return write_png_atomic(out_dir / "heightmap.png",
                            plot_height_map(heights_off_best_plane(grid), path=path[:, :2],
                                            title=title))


def write_trajectory_plot(out_dir: Path, plane: Plane, run: TrackRun,
                          groundtruth: np.ndarray | None, name: str) -> bytes:
    """``trajectory.png`` of ``run``'s trajectory, coloured by status, in ``out_dir``
    (atomically); ``groundtruth`` (M, 4, 4) is drawn from its first pose, put at camera 0;
    ``name``: the sequence's, for the title. Returns the PNG's bytes."""
    from monovo_cli.geometry.lie import se3_inv
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.viz.plots import plot_trajectory

    gt = None
    if groundtruth is not None:
        gt = se3_inv(groundtruth[0]) @ groundtruth
    title = f"{name}: {run.frames} frames, path {run.path_length:.2f} m"
    return write_png_atomic(out_dir / "trajectory.png",
                            plot_trajectory(run.trajectory, plane, statuses=list(run.status),
                                            groundtruth=gt, title=title))
