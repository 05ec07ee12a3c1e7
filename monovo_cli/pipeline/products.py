"""What ``monovo track`` writes at the end of a run, from the poses and the keyframes:
``trajectory.png`` and the terrain products (terrain.ply, heightmap.csv, heightmap.png)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.geometry.trajectory import path_length
from monovo_cli.core.status import FrameStatus
from monovo_cli.mapping.terrain_map import TerrainMap
from monovo_cli.geometry.plane import Plane


def write_terrain(out_dir: Path, terrain: TerrainMap, world_from_cam: np.ndarray) -> None:
    """``terrain.ply``, ``heightmap.csv`` and ``heightmap.png`` (the camera path drawn over
    the heights) of ``terrain`` into ``out_dir`` (:mod:`monovo_cli.io.terrain`)."""
    from monovo_cli.io.terrain import write_heightmap_csv, write_ply
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.viz.heightmap import plot_height_map

    X, intensity = terrain.points()
    write_ply(out_dir / "terrain.ply", X, intensity)
    grid = terrain.height_grid()
    G = terrain.ground_from_world
    write_heightmap_csv(out_dir / "heightmap.csv", grid, G)
    path = world_from_cam[:, :3, 3] @ G[:3, :3].T + G[:3, 3]
    title = f"{out_dir.name}: heights above frame 0's ground, {len(X)} points"
    write_png_atomic(out_dir / "heightmap.png", plot_height_map(grid, path=path[:, :2], title=title))


def write_trajectory_plot(out_dir: Path, plane: Plane, index: list[int], poses: np.ndarray,
                           groundtruth: np.ndarray | None) -> None:
    """``trajectory.png`` of the frames ``index`` at ``poses`` (N, 4, 4) in ``out_dir``
    (atomically), statuses read back from motion.csv.

    The ground truth is drawn from its first pose, which is put at camera 0.
    """
    from monovo_cli.geometry.lie import se3_inv
    from monovo_cli.io.formats import read_motion_stats
    from monovo_cli.io.video import write_png_atomic
    from monovo_cli.viz.plots import plot_trajectory

    stats = read_motion_stats(out_dir / "motion.csv")
    statuses = [stats.get(k, (FrameStatus.OK, 0.0))[0] for k in index]
    gt = None
    if groundtruth is not None:
        gt = se3_inv(groundtruth[0]) @ groundtruth
    dist = path_length(poses)
    title = f"{out_dir.name}: {len(poses)} frames, path {dist:.2f} m"
    write_png_atomic(out_dir / "trajectory.png",
                     plot_trajectory(poses, plane, statuses=statuses, groundtruth=gt,
                                     title=title))
