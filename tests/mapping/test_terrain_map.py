"""The terrain products: the keyframes' points in the world frame, the height grid, the files."""

import math
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.geometry.lie import make_pose, so3_exp
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.terrain import HEIGHTMAP_HEADER, heightmap_csv_text, ply_bytes, read_ply
from monovo_cli.mapping.smoothing import smoothed_keyframes
from monovo_cli.mapping.terrain_map import TerrainMap, ground_frame

N0 = np.array([0.0, math.cos(math.radians(40)), math.sin(math.radians(40))])


class _Points:
    """A keyframe level's points, as much of them as TerrainMap reads."""

    def __init__(self, X, intensity=None):
        self.X = np.asarray(X, float)
        self.intensity = np.full(len(X), 100.0, np.float32) if intensity is None \
            else np.asarray(intensity, np.float32)

    def __len__(self):
        return len(self.X)


def fake_key(index, X, world_from_key=None, plane=None):
    """What TerrainMap reads of a keyframe: its index, pose, plane, plane link (None) and
    level-0 points."""
    return SimpleNamespace(index=index, levels=(SimpleNamespace(points=_Points(X)),),
                           world_from_key=np.eye(4) if world_from_key is None else world_from_key,
                           plane=plane or Plane(N0, 1.5), link=None)


def test_ground_frame_axes():
    G = ground_frame(Plane(N0, 1.5))
    # the foot of camera 0 on the plane is the origin; camera 0 is 1.5 m above it
    assert np.allclose(G[:3, :3] @ (1.5 * N0) + G[:3, 3], 0.0)
    assert np.allclose(G[:3, 3], [0.0, 0.0, 1.5])
    # forward is camera 0's optical axis projected onto the plane; right-handed, z up
    fwd = np.array([0.0, 0.0, 1.0]) - N0[2] * N0
    assert np.allclose(G[1, :3], fwd / np.linalg.norm(fwd))
    assert np.allclose(G[2, :3], -N0) and np.isclose(np.linalg.det(G[:3, :3]), 1.0)


def test_points_on_the_planes_have_zero_height_and_a_rebuilt_keyframe_replaces_its_points():
    plane = Plane(N0, 1.5)
    rays = np.column_stack([np.linspace(-0.5, 0.5, 50), np.linspace(0.1, 0.6, 50), np.ones(50)])
    tmap = TerrainMap(plane)
    tmap.add(fake_key(0, plane.intersect(rays)))
    # keyframe 3, 2 m along the ground and turned 30 deg about the ground normal: its plane
    # in its camera is the same ground
    world_from_key = make_pose(so3_exp(-N0 * math.radians(30)), 2.0 * np.cross(N0, [1.0, 0, 0]))
    key_plane = plane.in_frame(np.linalg.inv(world_from_key))
    tmap.add(fake_key(3, key_plane.intersect(rays), world_from_key, key_plane))
    assert len(tmap) == 100
    assert np.abs(tmap.ground_points()[:, 2]).max() < 1e-12
    # keyframe 0 rebuilt on a plane 1 cm lower: its points are replaced, the frame follows it
    lower = Plane(N0, 1.51)
    tmap.add(fake_key(0, lower.intersect(rays), plane=lower))
    assert len(tmap) == 100
    h = tmap.ground_points()[:, 2]
    assert np.allclose(h[:50], 0.0, atol=1e-12) and np.allclose(h[50:], 0.01, atol=1e-12)


def test_smoothing_puts_a_keyframe_on_the_plane_its_successors_found():
    """Keyframe 0 was anchored on a plane 4 cm too far (init.yaml's distance, a camera at a
    crest); keyframe 1's MAP moved the carried distance 3 cm closer and keyframe 2's 2 cm
    more. With smoother gains of 1 and 0.5 (PlaneTracker.successor's), delta_1 = 0.5 * -0.02
    and delta_0 = 1 * (-0.03 + delta_1) = -0.04: keyframe 0's points land on the plane at
    1.50 m, a point 10 cm off its plane (terrain grid) keeps its height, and the ground frame is
    that plane; without smoothing nothing moves, and the last keyframe never does."""
    from monovo_cli.core.plane.belief import PlaneLink, smoothed_corrections

    far = Plane(N0, 1.54)
    rays = np.column_stack([np.linspace(-0.5, 0.5, 40), np.linspace(0.1, 0.6, 40), np.ones(40)])
    X0 = far.intersect(rays)
    X0[:5] *= ((far.distance - 0.1) / (X0[:5] @ N0))[:, None]  # 10 cm above the plane
    links = [None, PlaneLink(np.eye(3), np.array([-0.03, 0.0, 0.0])),
             PlaneLink(0.5 * np.eye(3), np.array([-0.02, 0.0, 0.0]))]
    assert [d[0] for d in smoothed_corrections(links)] == pytest.approx([-0.04, -0.01, 0.0])
    assert smoothed_corrections([None, None, links[2]])[0] == pytest.approx(np.zeros(3))
    for smooth, want in ((True, 1.50), (False, 1.54)):
        tmap = TerrainMap(far)
        for k, link in enumerate(links):
            key = fake_key(k, X0 if k == 0 else Plane(N0, 1.5).intersect(rays))
            key.link = link
            key.plane = far if k == 0 else Plane(N0, 1.5)
            tmap.add(key)
        drive = smoothed_keyframes(tmap.keyframes) if smooth else None
        X, _ = tmap.points(drive)
        assert X[5:40] @ N0 == pytest.approx(np.full(35, want), abs=1e-12)
        assert X[:5] @ N0 == pytest.approx(np.full(5, want - 0.1), abs=1e-12)
        assert X[80:] @ N0 == pytest.approx(np.full(40, 1.5), abs=1e-12)  # the last keyframe
        assert tmap.ground_points(drive)[5:40, 2] == pytest.approx(np.zeros(35), abs=1e-12)


def test_a_keyframe_is_refined_against_its_successor_only_after_a_re_anchor(monkeypatch):
    """The sweep runs when a re-anchored keyframe (one with a plane link) follows, not when
    a re-initialised one does (its pose was bridged by the prediction), nor against a lost
    last frame (finish(None, ...))."""
    import monovo_cli.mapping.terrain_map as tm
    from monovo_cli.core.plane.belief import PlaneLink

    calls = []
    monkeypatch.setattr(tm, "sweep_depths", lambda cam, plane, X, *a, **k: (calls.append(len(X)) or X,
                                                                            np.zeros(len(X), bool)))
    plane = Plane(N0, 1.5)
    rays = np.column_stack([np.linspace(-0.5, 0.5, 20), np.linspace(0.1, 0.6, 20), np.ones(20)])
    img = np.zeros((8, 8), np.float32)

    def key(index, link):
        k = fake_key(index, plane.intersect(rays), make_pose(np.eye(3), [0.0, 0.0, 0.1 * index]))
        k.levels[0].points.camera = SimpleNamespace(has_distortion=False)
        k.link = link
        return k

    tmap = TerrainMap(plane)
    tmap.add(key(0, None), img)
    tmap.add(key(5, None), img)  # re-initialised: no refinement of keyframe 0
    assert calls == []
    tmap.add(key(9, PlaneLink(np.eye(3), np.zeros(3))), img)  # re-anchored: keyframe 5 refined
    assert calls == [20]
    tmap.finish(None, make_pose(np.eye(3), [0.0, 0.0, 1.5]))
    assert calls == [20]
    tmap.finish(img, make_pose(np.eye(3), [0.0, 0.0, 1.5]))
    assert calls == [20, 20]


def test_refine_is_the_sweep_or_nothing():
    for refine in ("sweep", None):
        assert TerrainMap(Plane(N0, 1.5), refine=refine).refine == refine
    with pytest.raises(ValueError, match="refine"):
        TerrainMap(Plane(N0, 1.5), refine="newton")  # the per-point refinement is gone


def test_height_grid_by_hand():
    # looking straight down from 2 m (normal = optical axis): ground frame right = x,
    # forward = -y (image up), height = 2 - z
    tmap = TerrainMap(Plane([0.0, 0.0, 1.0], 2.0))
    X = np.array([[0.01, -0.01, 2.0], [0.02, -0.02, 1.9],        # cell (0, 0): heights 0, 0.1
                  [0.07, -0.01, 1.8],                           # cell (1, 0): 0.2
                  [0.01, -0.12, 2.05]])                         # cell (0, 2): -0.05
    tmap.add(fake_key(0, X, plane=Plane([0.0, 0.0, 1.0], 2.0)))
    g = tmap.height_grid(cell=0.05)
    assert (g.x0, g.y0, g.cell) == (0.0, 0.0, 0.05)
    assert g.height.shape == (3, 2)
    assert g.height[0, 0] == pytest.approx(0.05) and g.count[0, 0] == 2
    assert g.height[0, 1] == pytest.approx(0.2)
    assert g.height[2, 0] == pytest.approx(-0.05)
    assert np.isnan(g.height[1, 0]) and g.count[1, 0] == 0
    # heightmap.csv: the non-empty cells, their centres back in the world frame
    lines = heightmap_csv_text(g, tmap.ground_from_world()).splitlines()
    assert lines[0] == HEIGHTMAP_HEADER and len(lines) == 4
    row = [float(v) for v in lines[1].split(",")]
    assert row[:4] == pytest.approx([0.025, 0.025, 0.05, 2])
    assert row[4:] == pytest.approx([0.025, -0.025, 1.95])  # x, -forward, 2 - height


def test_ply_round_trip():
    X = np.array([[0.0, 1.0, 2.0], [-1.5, 0.25, 3.0]])
    data = ply_bytes(X, np.array([12.4, 250.0]))
    header = data[:data.index(b"end_header\n")].decode()
    assert header.startswith("ply\nformat binary_little_endian 1.0\n")
    assert "element vertex 2" in header and "property float intensity" in header
    assert len(data) - len(header) - len("end_header\n") == 2 * (4 * 4 + 3)


def test_track_terrain_out_on_a_plane_drive(tmp_path):
    seq = tmp_path / "s"
    r = CliRunner().invoke(main, ["synth", str(seq), "--frames", "30", "--size", "128x128",
                                  "--seed", "2", "-q"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "--terrain-out", "-q"])
    assert r.exit_code == 0, r.output
    X, intensity = read_ply(out / "terrain.ply")
    assert len(X) > 1000 and np.all((intensity >= 0) & (intensity <= 255))
    # a plane drive with an exact init.yaml: every keyframe's points lie within a few mm of
    # frame 0's ground (the drive's own small wobble of the camera is tracked)
    cells = np.loadtxt(out / "heightmap.csv", delimiter=",", skiprows=1, ndmin=2)
    assert np.sqrt(np.mean(cells[:, 2] ** 2)) < 0.005
    img = cv2.imread(str(out / "heightmap.png"))
    assert img is not None and img.shape[0] > 400
    r = CliRunner().invoke(main, ["track", str(seq), "-o", "-", "--terrain-out"])
    assert r.exit_code == 2 and "--terrain-out" in r.output and "Traceback" not in r.output


def test_depth_sweep_puts_points_the_relief_misplaced_back_on_the_ground():
    """Two views of flat ground 0.4 m apart, exact poses; a fifth of the keyframe's points
    sit 8 cm above the ground (a terrain grid that missed the ground there, as it misses a rock).
    The sweep moves most of them back to within 1 cm and leaves the others where they are
    (measured: 57 % moved, to 0.79 cm RMS; 0.06 % of the others moved). The rest are points
    whose texture runs along their epipolar line: no height is clearly better there."""
    from monovo_cli.core.estimator.ground import select_points
    from monovo_cli.geometry.lie import se3_inv
    from monovo_cli.mapping.terrain_depths import sweep_depths
    from monovo_cli.synth.motion import camera_mount
    from monovo_cli.synth.render import GroundRenderer, default_camera, finish_frame, ground_in_camera
    from monovo_cli.synth.texture import GroundTexture, procedural_texture

    cam = default_camera(256, 256)
    g0 = camera_mount(40.0)
    g1 = make_pose(np.eye(3), np.array([0.4, 0.05, 0.0])) @ g0
    rng = np.random.default_rng(3)
    ren = GroundRenderer(cam, GroundTexture(procedural_texture(512, 2), 1.2 / cam.fx), supersample=2)
    img0, img1 = (finish_frame(ren.render(g), rng, 10.0).astype(np.float32) for g in (g0, g1))
    n, d = ground_in_camera(g0)
    ground = Plane(n, d)
    corners = np.array(ground.intersect(cam.rays(np.array([[0.0, 40], [255, 40], [255, 255], [0, 255]]))))
    X = select_points(img0, cam, ground, corners, level=0, threshold=3.0, max_points=4000).X
    off = rng.random(len(X)) < 0.2
    Xw = X.copy()
    Xw[off] *= ((d - 0.08) / (X[off] @ n))[:, None]  # 8 cm up their rays
    height = lambda P: d - P @ n  # noqa: E731 (above the true ground, m)
    Xs, moved = sweep_depths(cam, ground, Xw, img0, img1, se3_inv(g1) @ g0)
    assert np.allclose(height(Xw[off]), 0.08) and off.sum() > 500
    assert moved[off].mean() > 0.5 and moved[~off].mean() < 0.01
    assert np.sqrt(np.mean(height(Xs[off & moved]) ** 2)) < 0.01
    assert np.array_equal(Xs[~moved], Xw[~moved])
