"""``monovo overlay --terrain``: the glued triangle draped over a height map (issue 14.4).

The height map is built from the TRUE terrain of a short ``synth --terrain rolling`` drive
(terrain.npz), in the ground frame of init.yaml's plane as ``track --terrain-out`` writes it,
and goes through heightmap.csv (its rounding included). The draped triangle's vertices,
projected with the true poses, must land where the true terrain points under them project
(within 0.1 px); the plane triangle's land several pixels away, so the check fails for a
drawing that ignores the terrain.
"""

from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.errors import InputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.terrain import heightmap_csv_text, read_heightmap
from monovo_cli.mapping.terrain_map import HeightGrid, ground_frame
from monovo_cli.synth.terrain import load_terrain
from monovo_cli.synth.write import synthesize
from monovo_cli.viz.drape import (
    DrapedOverlayRenderer,
    clip_segments,
    grid_heights,
    subdivide_triangle,
    subdivision_lines,
)
from monovo_cli.viz.overlay import (
    OverlayRenderer,
    default_triangle_pixels,
    project_polygon,
    project_vertices,
    triangle_on_ground,
)

FRAMES = 8
CELL = 0.05


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    root = tmp_path_factory.mktemp("drape")
    synthesize(root / "seq", preset="drive", frames=FRAMES, size=(160, 160), seed=3,
               terrain="rolling")
    return root


def true_heights(seq: Path, ground_from_world: np.ndarray, right: np.ndarray,
                 forward: np.ndarray) -> np.ndarray:
    """Heights (N,) m above the ground frame's plane, along its up, where the line through
    ground point (right, forward) meets the true terrain (G frame, z up)."""
    terrain = load_terrain(seq / "terrain.npz")
    with np.load(seq / "terrain.npz") as f:
        g_from_world = f["g_from_cam"][0]
    world_from_ground = se3_inv(ground_from_world)
    T = g_from_world @ world_from_ground
    base = np.stack([right, forward, np.zeros_like(right)], 1) @ T[:3, :3].T + T[:3, 3]
    up = T[:3, 2]  # the ground frame's up in G
    h = np.zeros(len(right))
    for _ in range(30):  # the up is within a few degrees of G's z: a contraction
        P = base + h[:, None] * up
        h += (terrain.height(P[:, 0], P[:, 1]) - P[:, 2]) / up[2]
    return h


def write_true_heightmap(seq: Path, path: Path, *, holes=None) -> np.ndarray:
    """heightmap.csv of the true terrain over the first triangle's surroundings, ground frame
    of init.yaml's plane; ``holes(right, forward) -> bool`` cells left empty. Returns
    ``ground_from_world``."""
    cfg = load_init(seq / "init.yaml")
    G = ground_frame(cfg.plane)
    tri = triangle_on_ground(cfg.camera, cfg.plane, None, cfg.region)
    g = tri @ G[:3, :3].T + G[:3, 3]
    x0 = np.floor(g[:, 0].min() / CELL) * CELL - 0.5
    y0 = np.floor(g[:, 1].min() / CELL) * CELL - 0.5
    w = int(np.ceil((g[:, 0].max() + 0.5 - x0) / CELL))
    h = int(np.ceil((g[:, 1].max() + 0.5 - y0) / CELL))
    right, forward = np.meshgrid(x0 + (np.arange(w) + 0.5) * CELL, y0 + (np.arange(h) + 0.5) * CELL)
    height = true_heights(seq, G, right.ravel(), forward.ravel()).reshape(h, w)
    if holes is not None:
        height[holes(right, forward)] = np.nan
    grid = HeightGrid(float(x0), float(y0), CELL, height, np.where(np.isfinite(height), 3, 0))
    path.write_text(heightmap_csv_text(grid, G))
    return G


def _renderers(seq: Path, heightmap: Path):
    cfg = load_init(seq / "init.yaml")
    tri = triangle_on_ground(cfg.camera, cfg.plane, None, cfg.region)
    grid, G = read_heightmap(heightmap)
    draped = DrapedOverlayRenderer(cfg.camera, cfg.plane, tri, grid=grid, ground_from_world=G,
                                   region=cfg.region)
    return cfg, tri, draped


def test_draped_vertices_land_on_the_true_terrain_and_plane_ones_do_not(drive):
    seq = drive / "seq"
    G = write_true_heightmap(seq, drive / "true.csv")
    cfg, tri, draped = _renderers(seq, drive / "true.csv")
    V_draped, on = draped.mesh()
    assert on.all()  # the map covers the whole triangle
    V_plane, _ = subdivide_triangle(tri, draped.steps)
    g = V_plane @ G[:3, :3].T + G[:3, 3]
    assert np.abs(g[:, 2]).max() < 1e-9  # the plane triangle lies on the map's ground plane
    h_true = true_heights(seq, G, g[:, 0], g[:, 1])
    truth = (np.column_stack([g[:, :2], h_true]) - G[:3, 3]) @ G[:3, :3]
    _, poses = read_tum(seq / "groundtruth.tum")
    err_draped, err_plane = [], []
    for T in poses:
        uv_true, seen = project_vertices(cfg.camera, truth, T)
        uv_d, _ = project_vertices(cfg.camera, V_draped, T)
        uv_p, _ = project_vertices(cfg.camera, V_plane, T)
        err_draped.append(np.linalg.norm(uv_d - uv_true, axis=1)[seen])
        err_plane.append(np.linalg.norm(uv_p - uv_true, axis=1)[seen])
    err_draped, err_plane = np.concatenate(err_draped), np.concatenate(err_plane)
    assert len(err_draped) > 0.5 * FRAMES * len(V_plane)
    print(f"draped: max {err_draped.max():.3f} px, median {np.median(err_draped):.3f} px; "
          f"plane: max {err_plane.max():.2f} px, median {np.median(err_plane):.2f} px")
    assert err_draped.max() < 0.1  # measured 0.003 px: the map's interpolation and rounding
    # the plane-only triangle is off by up to ~3 px (160x160 px, +-5 cm swell, 1.5 m camera)
    assert np.percentile(err_plane, 75) > 1.0 and err_plane.max() > 2.0


def test_corners_stay_at_their_pixels_on_the_terrain(drive):
    """The corners slide along the rays of the pixels they were placed at onto the map: the
    first triangle's in frame 0, a new triangle's in its frame."""
    seq = drive / "seq"
    G = write_true_heightmap(seq, drive / "true.csv")
    cfg = load_init(seq / "init.yaml")
    pixels = default_triangle_pixels(cfg.region)
    tri = triangle_on_ground(cfg.camera, cfg.plane, pixels)
    grid, G = read_heightmap(drive / "true.csv")
    r = DrapedOverlayRenderer(cfg.camera, cfg.plane, tri, grid=grid, ground_from_world=G,
                              region=cfg.region, pixels=pixels, seen_from=np.eye(4))
    _, poses = read_tum(seq / "groundtruth.tum")
    for k, T in ((0, np.eye(4)), (5, poses[5])):
        if k:
            assert r.advance(T, "reanchored")
        uv, seen = project_vertices(cfg.camera, r.triangle, T)
        assert seen.all()
        np.testing.assert_allclose(uv, pixels, atol=1e-3)
        g = r.triangle @ G[:3, :3].T + G[:3, 3]
        np.testing.assert_allclose(g[:, 2], true_heights(seq, G, g[:, 0], g[:, 1]), atol=2e-4)
        assert np.abs(g[:, 2]).max() > 0.005  # not the plane's corners
        V, on = r.mesh()
        # the draped mesh keeps them: vertices 0, steps and -1 are the corners A, C and B
        np.testing.assert_allclose(V[[0, r.steps, -1]], r.triangle[[0, 2, 1]], atol=1e-9)
        assert on.all()


def test_where_the_map_has_no_data_the_triangle_stays_on_the_plane(drive):
    seq = drive / "seq"
    cfg = load_init(seq / "init.yaml")
    G = ground_frame(cfg.plane)
    tri = triangle_on_ground(cfg.camera, cfg.plane, None, cfg.region)
    cut = float(np.median(tri @ G[1, :3] + G[1, 3]))  # forward of the middle vertex
    write_true_heightmap(seq, drive / "holes.csv", holes=lambda r, f: f > cut)
    _, _, draped = _renderers(seq, drive / "holes.csv")
    V_draped, on = draped.mesh()
    V_plane, _ = subdivide_triangle(tri, draped.steps)
    forward = V_plane @ G[1, :3] + G[1, 3]
    assert on[forward < cut - CELL].all() and not on[forward > cut + CELL].any()
    np.testing.assert_array_equal(V_draped[~on], V_plane[~on])
    lift = np.linalg.norm(V_draped - V_plane, axis=1)
    assert lift[on].max() > 0.01  # the rolling ground is centimetres off the plane


def flat_renderer(cam, plane, tri, **kwargs):
    """A draped renderer over a zero height map covering +-20 m: the plane triangle again."""
    grid = HeightGrid(-20.0, -20.0, 0.5, np.zeros((80, 80)), np.ones((80, 80), int))
    return DrapedOverlayRenderer(cam, plane, tri, grid=grid,
                                 ground_from_world=ground_frame(plane), **kwargs)


def _area(uv):
    x, y = uv[:, 0], uv[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


@pytest.mark.parametrize("offset", [0.0, -1.5, -2.0])  # all in front, tip behind, most behind
def test_facets_are_clipped_like_the_plane_triangle(offset):
    cam = PinholeCamera(160, 120, 100.0, 100.0, 79.5, 59.5)
    plane = Plane(np.array([0.0, 1.0, 0.0]), 1.0)  # ground 1 m below a level camera
    tri = np.array([[0.0, 1.0, 0.5], [1.5, 1.0, 4.0], [-1.5, 1.0, 4.0]]) + [0.0, 0.0, offset]
    r = flat_renderer(cam, plane, tri, region=(0, 60, 160, 120))
    polys = r.image_facets(np.eye(4))
    whole = project_polygon(cam, tri, r.near)
    allpts = np.concatenate(polys)
    assert np.all(np.isfinite(allpts)) and np.abs(allpts).max() < 4 * cam.width
    # a flat map: the facets tile exactly the clipped plane triangle
    assert sum(_area(p) for p in polys) == pytest.approx(_area(whole), rel=1e-9)
    seg = r.image_segments(np.eye(4), r.outline_edges)
    assert np.all(np.isfinite(seg)) and np.abs(seg).max() < 4 * cam.width
    img = r.render(0, np.full((120, 160), 100.0, np.float32), np.eye(4))
    base = OverlayRenderer(cam, plane, tri, region=(0, 60, 160, 120)).render(
        0, np.full((120, 160), 100.0, np.float32), np.eye(4))
    a, b = np.any(img != 100, axis=2), np.any(base != 100, axis=2)
    a[:20, :100] = b[:20, :100] = False  # the text line
    assert b.sum() > 200 and (a & b).sum() / (a | b).sum() > 0.97  # the same pixels, up to the edges' drawing


def test_far_away_triangle_draws_nothing():
    cam = PinholeCamera(160, 120, 100.0, 100.0, 79.5, 59.5)
    plane = Plane(np.array([0.0, 1.0, 0.0]), 1.0)
    tri = np.array([[0.0, 1.0, -2.0], [1.0, 1.0, -4.0], [-1.0, 1.0, -4.0]])  # behind
    r = flat_renderer(cam, plane, tri)
    assert r.image_facets(np.eye(4)) == [] and len(r.image_segments(np.eye(4), r.outline_edges)) == 0
    img = r.render(0, np.full((120, 160), 100.0, np.float32), np.eye(4))
    assert np.all(img[30:] == 100)


def test_subdivision_and_lines():
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    V, faces = subdivide_triangle(tri, 4)
    assert len(V) == 15 and len(faces) == 16
    np.testing.assert_array_equal(V[[0, 4, 14]], tri[[0, 2, 1]])  # the corners, exact
    area = sum(0.5 * abs(np.cross(V[b] - V[a], V[c] - V[a])[2]) for a, b, c in faces)
    assert area == pytest.approx(0.5)
    outline, inner = subdivision_lines(4, 2)
    assert len(outline) == 12  # 3 sides of 4 segments
    assert len(inner) == 3 * 2  # one line (2 segments) parallel to each side, halfway
    ends = V[outline]
    on_side = (np.abs(ends[..., 0]) < 1e-12) | (np.abs(ends[..., 1]) < 1e-12) \
        | (np.abs(ends[..., 0] + ends[..., 1] - 1) < 1e-12)
    assert on_side.all()


def test_clip_segments_against_brute_force():
    rng = np.random.default_rng(5)
    P, Q = rng.uniform(-3, 3, (200, 3)), rng.uniform(-3, 3, (200, 3))
    H = np.array([[0.0, 0.0, 1.0, -0.5], [1.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.5, 1.0]])
    A, B, keep = clip_segments(P, Q, H)
    t = np.linspace(0.0, 1.0, 2001)
    for k in range(len(P)):
        X = P[k] + t[:, None] * (Q[k] - P[k])
        good = np.all(X @ H[:, :3].T + H[:, 3] >= 0, axis=1)
        assert keep[k] == good.any() or abs(np.ptp(t[good]) if good.any() else 0) < 1e-3
        if keep[k] and good.any():
            for end in (A[k], B[k]):
                assert np.all(end @ H[:, :3].T + H[:, 3] >= -1e-9)
            span = np.linalg.norm(B[k] - A[k]) / np.linalg.norm(Q[k] - P[k])
            assert span == pytest.approx(np.ptp(t[good]), abs=1e-3)


def test_grid_heights_bilinear_and_no_data():
    x0, y0, cell = -1.0, 2.0, 0.1
    j, i = np.mgrid[0:10, 0:20]
    r, f = x0 + (i + 0.5) * cell, y0 + (j + 0.5) * cell
    grid = HeightGrid(x0, y0, cell, 0.3 * r - 0.2 * f + 0.05, np.ones_like(r, int))
    rng = np.random.default_rng(1)
    qr, qf = rng.uniform(-0.95, 0.95, 100), rng.uniform(2.05, 2.95, 100)
    np.testing.assert_allclose(grid_heights(grid, qr, qf), 0.3 * qr - 0.2 * qf + 0.05, atol=1e-12)
    assert np.isnan(grid_heights(grid, np.array([5.0, -1.2]), np.array([2.5, 2.5]))).all()


# ----------------------------------------------------------------------------- the file


def _small_map(tmp_path: Path) -> tuple[Path, HeightGrid, np.ndarray]:
    n = np.array([0.1, 0.9, 0.4])
    G = ground_frame(Plane(n / np.linalg.norm(n), 1.3))
    h = np.random.default_rng(2).normal(0.0, 0.03, (6, 5))
    h[2, 3] = h[4, 1] = np.nan
    grid = HeightGrid(-0.15, 0.35, 0.05, h, np.where(np.isfinite(h), 4, 0))
    path = tmp_path / "heightmap.csv"
    path.write_text(heightmap_csv_text(grid, G))
    return path, grid, G


def test_read_heightmap_round_trip(tmp_path):
    path, grid, G = _small_map(tmp_path)
    for where in (path, tmp_path):  # the file, or the --terrain-out directory holding it
        got, G2 = read_heightmap(where)
        assert (got.x0, got.y0, got.cell) == pytest.approx((grid.x0, grid.y0, grid.cell), abs=1e-9)
        np.testing.assert_array_equal(np.isnan(got.height), np.isnan(grid.height))
        np.testing.assert_allclose(got.height, grid.height, atol=6e-6)  # written to 0.01 mm
        np.testing.assert_array_equal(got.count, grid.count)
        np.testing.assert_allclose(G2, G, atol=5e-5)


def _edit(path: Path, fn) -> None:
    lines = path.read_text().splitlines()
    path.write_text("\n".join(fn(lines)) + "\n")


@pytest.mark.parametrize(("edit", "words"), [
    (lambda ls: ["x,y,z"] + ls[1:], ["expected a header starting with right_m"]),
    (lambda ls: ls[:2] + ["0.1,abc,0,1,0,0,0"] + ls[3:], ["line 3", "expected numbers"]),
    (lambda ls: ls[:3], ["2 cells", "at least 3"]),
    (lambda ls: ls + [ls[5]], ["given twice"]),
    (lambda ls: ls[:4] + [ls[4].replace("0.", "0.0", 1)] + ls[5:], ["off the", "grid"]),
    (lambda ls: ls[:1] + [r for r in ls[1:] if r.startswith("-0.1250,")],
     ["on one line"]),
    (lambda ls: ls[:6] + [",".join(ls[6].split(",")[:6] + ["9.0"])] + ls[7:],
     ["not the ground columns", "moved rigidly"]),
])
def test_malformed_heightmaps_are_one_line_errors(tmp_path, edit, words):
    path, _, _ = _small_map(tmp_path)
    _edit(path, edit)
    with pytest.raises(InputError) as exc:
        read_heightmap(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(path))
    for w in words:
        assert w in msg, msg


def test_overlay_cli_terrain(drive, tmp_path):
    seq = drive / "seq"
    terrain_dir = tmp_path / "out"
    terrain_dir.mkdir()
    write_true_heightmap(seq, terrain_dir / "heightmap.csv")
    gt = str(seq / "groundtruth.tum")
    runner = CliRunner()
    r = runner.invoke(main, ["overlay", str(seq), "-t", gt, "-o", str(tmp_path / "plane/")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(main, ["overlay", str(seq), "-t", gt, "-o", str(tmp_path / "draped/"),
                             "--terrain", str(terrain_dir)])
    assert r.exit_code == 0, r.output
    plane = sorted((tmp_path / "plane").glob("*.png"))
    draped = sorted((tmp_path / "draped").glob("*.png"))
    assert len(plane) == len(draped) == FRAMES
    diffs = [np.count_nonzero(np.any(cv2.imread(str(a)) != cv2.imread(str(b)), axis=2))
             for a, b in zip(plane, draped)]
    assert min(diffs) > 100  # the draped triangle (and its grid lines) is drawn elsewhere
    # errors: one line, exit 2, no output
    bad = tmp_path / "bad.csv"
    bad.write_text("right_m,forward_m,height_m,points,x_m,y_m,z_m\n0.025,0.025,nan,1,0,0,0\n")
    for terrain, words in ((tmp_path / "missing.csv", "cannot read height map"),
                           (seq, "no heightmap.csv in this directory"),
                           (seq / "init.yaml", "expected a header"),
                           (bad, "non-finite")):
        out = tmp_path / "x.mp4"
        r = runner.invoke(main, ["overlay", str(seq), "-t", gt, "-o", str(out),
                                 "--terrain", str(terrain)])
        assert r.exit_code == 2, r.output
        assert r.output.startswith("Error: ") and r.output.count("\n") == 1, r.output
        assert words in r.output and "Traceback" not in r.output
        assert not out.exists()
