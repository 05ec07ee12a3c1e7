"""What ``monovo track`` writes at the end of a run, from the run in memory:
``trajectory.png`` and the terrain products (terrain.ply, heightmap.csv, heightmap.png)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.core.run import TrackRun
from monovo_cli.geometry.plane import Plane
from monovo_cli.mapping.smoothing import SmoothedDrive
from monovo_cli.mapping.terrain_map import TerrainMap


def write_terrain(out_dir: Path, terrain: TerrainMap, world_from_cam: np.ndarray,
                  drive: SmoothedDrive | None) -> bytes:
    """``terrain.ply``, ``heightmap.csv`` and ``heightmap.png`` (the camera path
    ``world_from_cam`` (N, 4, 4) drawn over the heights) of ``terrain`` into ``out_dir``
    (:mod:`monovo_cli.io.terrain`), its keyframes placed as ``drive`` smoothed them (None: as
    tracked). Returns heightmap.png's bytes."""
    from monovo_cli.io.terrain import write_heightmap_csv, write_ply
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.viz.heightmap import plot_height_map

    X, intensity = terrain.points(drive)
    write_ply(out_dir / "terrain.ply", X, intensity)
    grid = terrain.height_grid(drive=drive)
    G = terrain.ground_from_world(drive)
    write_heightmap_csv(out_dir / "heightmap.csv", grid, G)
    path = world_from_cam[:, :3, 3] @ G[:3, :3].T + G[:3, 3]
    title = f"{out_dir.name}: heights above frame 0's ground, {len(X)} points"
    return write_png_atomic(out_dir / "heightmap.png",
                            plot_height_map(grid, path=path[:, :2], title=title))


def write_trajectory_plot(out_dir: Path, plane: Plane, run: TrackRun,
                          groundtruth: np.ndarray | None) -> bytes:
    """``trajectory.png`` of ``run``'s trajectory, coloured by status, in ``out_dir``
    (atomically); ``groundtruth`` (M, 4, 4) is drawn from its first pose, put at camera 0.
    Returns the PNG's bytes."""
    from monovo_cli.geometry.lie import se3_inv
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.viz.plots import plot_trajectory

    gt = None
    if groundtruth is not None:
        gt = se3_inv(groundtruth[0]) @ groundtruth
    title = f"{out_dir.name}: {run.frames} frames, path {run.path_length:.2f} m"
    return write_png_atomic(out_dir / "trajectory.png",
                            plot_trajectory(run.trajectory, plane, statuses=list(run.status),
                                            groundtruth=gt, title=title))
