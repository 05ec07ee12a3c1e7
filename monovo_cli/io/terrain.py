"""The terrain products of ``monovo track --terrain``: ``terrain.ply`` and ``heightmap.csv``.

``terrain.ply``: binary little-endian PLY, one vertex per observation point of the keyframes
in the world frame (camera 0's, m): ``float x, y, z``, ``float intensity`` (grey levels of
the keyframe image) and ``uchar red, green, blue`` (the same grey, for viewers that show
colours). ``heightmap.csv``: one row per non-empty cell of the height grid, header
``right_m,forward_m,height_m,points,x_m,y_m,z_m``: the cell's centre in the ground frame
(:mod:`monovo_cli.core.terrain_map`), the mean height of its points above that plane, their
count, and the cell's centre at that height in the world frame (camera 0's). Both are
written atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.core.terrain_map import HeightGrid
from monovo_cli.io.atomic import atomic_write_bytes, atomic_write_text

HEIGHTMAP_HEADER = "right_m,forward_m,height_m,points,x_m,y_m,z_m"


def ply_bytes(X: np.ndarray, intensity: np.ndarray) -> bytes:
    """The PLY file (module docstring) of points ``X`` (N, 3) and ``intensity`` (N,)."""
    n = len(X)
    header = ("ply\nformat binary_little_endian 1.0\ncomment monovo terrain: observation points "
              "of the keyframes, world frame (camera 0), metres\n"
              f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float intensity\nproperty uchar red\nproperty uchar green\n"
              "property uchar blue\nend_header\n")
    rec = np.zeros(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "<f4"),
                             ("r", "u1"), ("g", "u1"), ("b", "u1")])
    rec["x"], rec["y"], rec["z"] = X[:, 0], X[:, 1], X[:, 2]
    rec["i"] = intensity
    grey = np.clip(np.rint(intensity), 0, 255).astype(np.uint8)
    rec["r"] = rec["g"] = rec["b"] = grey
    return header.encode("ascii") + rec.tobytes()


def read_ply(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``(X (N, 3), intensity (N,))`` of a ``terrain.ply`` written by :func:`write_ply`."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    n = int(next(line.split()[2] for line in data[:end].decode("ascii").splitlines()
                 if line.startswith("element vertex")))
    rec = np.frombuffer(data[end:], dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "<f4"),
                                           ("r", "u1"), ("g", "u1"), ("b", "u1")], count=n)
    return np.stack([rec["x"], rec["y"], rec["z"]], 1).astype(np.float64), rec["i"].copy()


def write_ply(path: Path, X: np.ndarray, intensity: np.ndarray) -> None:
    atomic_write_bytes(Path(path), ply_bytes(X, intensity))


def heightmap_csv_text(grid: HeightGrid, ground_from_world: np.ndarray) -> str:
    """``heightmap.csv`` (module docstring) of ``grid``, whose ground frame is
    ``ground_from_world`` (4x4)."""
    j, i = np.nonzero(grid.count > 0)
    G = np.column_stack([grid.x0 + (i + 0.5) * grid.cell, grid.y0 + (j + 0.5) * grid.cell,
                         grid.height[j, i]])
    R, t = ground_from_world[:3, :3], ground_from_world[:3, 3]
    W = (G - t) @ R  # world = R^T (ground - t)
    rows = [HEIGHTMAP_HEADER]
    for (gx, gy, gz), n, (x, y, z) in zip(G, grid.count[j, i], W):
        rows.append(f"{gx:.4f},{gy:.4f},{gz:.5f},{int(n)},{x:.5f},{y:.5f},{z:.5f}")
    return "\n".join(rows) + "\n"


def write_heightmap_csv(path: Path, grid: HeightGrid, ground_from_world: np.ndarray) -> None:
    atomic_write_text(Path(path), heightmap_csv_text(grid, ground_from_world))
