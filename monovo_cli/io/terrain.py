"""The terrain products of ``monovo track --terrain``: ``terrain.ply`` and ``heightmap.csv``.

``terrain.ply``: binary little-endian PLY, one vertex per observation point of the keyframes
in the world frame (camera 0's, m): ``float x, y, z``, ``float intensity`` (grey levels of
the keyframe image) and ``uchar red, green, blue`` (the same grey, for viewers that show
colours). ``heightmap.csv``: one row per non-empty cell of the height grid, header
``right_m,forward_m,height_m,points,x_m,y_m,z_m``: the cell's centre in the ground frame
(:mod:`monovo_cli.mapping.terrain_map`), the mean height of its points above that plane, their
count, and the cell's centre at that height in the world frame (camera 0's). Both are
written atomically. :func:`read_heightmap` reads ``heightmap.csv`` back (for ``monovo
overlay --terrain``): the grid, and the ground frame recovered from the two sets of columns.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.atomic import atomic_write_bytes, atomic_write_text
from monovo_cli.io.formats import csv_rows, floats
from monovo_cli.mapping.terrain_map import HeightGrid

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
    """Write :func:`ply_bytes` of points ``X`` (N, 3) m and ``intensity`` (N,) to ``path``,
    atomically."""
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
    """Write :func:`heightmap_csv_text` to ``path``, atomically."""
    atomic_write_text(Path(path), heightmap_csv_text(grid, ground_from_world))


HEIGHTMAP_NAME = "heightmap.csv"
FRAME_TOLERANCE = 2e-3  # m: the world and ground columns must agree to this (they are rounded)


def read_heightmap(path: Path) -> tuple[HeightGrid, np.ndarray]:
    """``(grid, ground_from_world (4, 4))`` of a ``heightmap.csv`` (module docstring), or of the
    one in the directory ``path`` (``monovo track -o DIR --terrain-out``).

    The cell size is the smallest spacing of the cells' centres (they lie on a lattice); the
    ground frame is the rigid motion that maps the ``x_m,y_m,z_m`` columns onto the
    ``right_m,forward_m,height_m`` ones (least squares). InputError (one line) when the file
    is missing or unreadable, a row is not numbers, a cell is given twice, the centres are off
    the lattice, the cells are fewer than 3 or on one line, or the two sets of columns do not
    describe the same points.
    """
    path = Path(path)
    if path.is_dir():
        if not (path / HEIGHTMAP_NAME).is_file():
            raise InputError(f"{path}: no {HEIGHTMAP_NAME} in this directory "
                             "(a tracking run writes one with its terrain products)")
        path = path / HEIGHTMAP_NAME
    rows = csv_rows(path, "height map", HEIGHTMAP_HEADER.split(","))
    vals = np.array([floats(r[:7], path, i) for i, r in rows]).reshape(-1, 7)
    if len(vals) < 3:
        raise InputError(f"{path}: {len(vals)} cells; a height map needs at least 3")
    G, W = vals[:, :3], vals[:, 4:7]
    foot = G[:, :2] - G[:, :2].mean(axis=0)
    spacings = [np.diff(np.unique(np.round(v, 6))) for v in G[:, :2].T]
    steps = np.concatenate([d[d > 1e-6] for d in spacings])
    if not len(steps) or np.linalg.svd(foot, compute_uv=False)[-1] < 1e-6:
        raise InputError(f"{path}: the cells lie on one line; expected a height map of an area")
    cell = round(float(steps.min()), 6)  # (the centres are written to 0.1 mm)
    lo = np.round(G[:, :2].min(axis=0) - 0.5 * cell, 6)
    ij = (G[:, :2] - lo) / cell - 0.5
    idx = np.rint(ij).astype(np.int64)
    if np.max(np.abs(ij - idx)) > 0.02:
        k = int(np.argmax(np.max(np.abs(ij - idx), axis=1)))
        raise InputError(f"{path}: line {rows[k][0]}: cell centre ({G[k, 0]:g}, {G[k, 1]:g}) m "
                         f"is off the {cell:g} m grid of the other cells")
    w, h = (int(v) + 1 for v in idx.max(axis=0))
    if w * h > 4e7:
        raise InputError(f"{path}: the cells span {w} x {h} cells of {cell:g} m; too large")
    flat = idx[:, 1] * w + idx[:, 0]
    uniq, first, counts = np.unique(flat, return_index=True, return_counts=True)
    if np.any(counts > 1):
        k = int(np.nonzero(flat == uniq[np.argmax(counts > 1)])[0][1])
        raise InputError(f"{path}: line {rows[k][0]}: cell ({G[k, 0]:g}, {G[k, 1]:g}) m is "
                         "given twice")
    height = np.full(h * w, np.nan)
    count = np.zeros(h * w, np.int64)
    height[flat] = G[:, 2]
    count[flat] = np.rint(vals[:, 3]).astype(np.int64)
    ground_from_world = _rigid_fit(W, G)
    resid = W @ ground_from_world[:3, :3].T + ground_from_world[:3, 3] - G
    if float(np.max(np.linalg.norm(resid, axis=1))) > FRAME_TOLERANCE:
        raise InputError(f"{path}: the world columns (x_m, y_m, z_m) are not the ground columns "
                         "(right_m, forward_m, height_m) moved rigidly; is the file edited?")
    grid = HeightGrid(float(lo[0]), float(lo[1]), cell, height.reshape(h, w),
                      count.reshape(h, w))
    return grid, ground_from_world


def _rigid_fit(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The 4x4 rigid motion ``T`` (rotation, translation) minimising ``sum |T a - b|^2`` over
    the rows of ``A`` and ``B`` (N, 3) (Kabsch)."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    U, _, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = cb - R @ ca
    return T
