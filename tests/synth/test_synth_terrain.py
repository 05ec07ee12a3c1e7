"""Tests of the terrain drives of `monovo synth` (issues 14.2 and 13.6).

The ray caster is checked against the planar renderer on flat ground, against an analytic
swell (a hit lies on the surface and is the first crossing along its ray), and for
occlusion by a rock; the written drives against their own ground truth and nominal plane;
the MER preset's steps and turns; determinism by seed; the gravel texture.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import yaml

from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import make_pose, se3_inv
from monovo_cli.io.formats import read_motion_csv, read_tum
from monovo_cli.synth.gravel import gravel_texture
from monovo_cli.synth.motion import (
    BOB_HEIGHT,
    BOB_TILT_DEG,
    MER_ARC_DEG,
    MER_STEP,
    MER_TURN_DEG,
    bobbing,
    body_from_camera,
    body_on_ground,
    mer_path,
)
from monovo_cli.synth.raycast import TerrainRenderer
from monovo_cli.synth.render import GroundRenderer, default_camera, ground_in_camera
from monovo_cli.synth.rover import rover_mount, rover_scene
from monovo_cli.synth.terrain import Rocks, Terrain, load_terrain, make_terrain
from monovo_cli.synth.texture import GroundTexture, procedural_texture
from monovo_cli.synth.write import synthesize

SIZE = (96, 80)


def camera_pose(pitch_deg=40.0, xy=(0.3, -0.2), height=1.5, yaw=0.4):
    c, s = math.cos(yaw), math.sin(yaw)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return make_pose(Rz @ body_from_camera(math.radians(pitch_deg)), np.array([*xy, height]))


@pytest.fixture(scope="module")
def texture():
    return GroundTexture(procedural_texture(512, 7), 0.01)


def flat() -> Terrain:
    return Terrain("flat", (0.0, 0.0), np.zeros((64, 64), np.float32), 0.04, Rocks.none())


# ----------------------------------------------------------------------------- the ray caster


@pytest.mark.parametrize("s", [1, 2])
def test_ray_caster_matches_planar_renderer_on_flat_ground(texture, s):
    cam = default_camera(*SIZE)
    g = camera_pose()
    planar = GroundRenderer(cam, texture, supersample=s).render(g)
    cast = TerrainRenderer(cam, texture, flat(), supersample=s, sun_azimuth=1.0).render(g)
    diff = np.abs(cast - planar)
    assert planar.std() > 20.0  # a textured image, not a blank one
    assert diff.mean() < 0.02 and diff.max() < 1.0  # grey levels


def test_hit_lies_on_an_analytic_swell_and_is_the_first_crossing(texture):
    """A steep swell z = A sin(2 pi x / L) (+-10 cm, slopes up to 26 deg; grid sampled, its
    bilinear interpolant is within 0.03 mm of the sine) on a tilted plane: hits lie on it
    within 1 mm, and no part of a ray before its hit is below it (rays graze the crests)."""
    A, L, h, n = 0.1, 1.28, 0.01, 512
    x = np.arange(n) * h
    swell = np.tile((A * np.sin(2 * np.pi * x / L)).astype(np.float32), (n, 1))
    terrain = Terrain("rolling", (0.02, -0.03), swell, h, Rocks.none())
    cam = default_camera(*SIZE)
    g = camera_pose(pitch_deg=35.0)  # the top rows see ground ~9 m away, grazing the crests
    r = TerrainRenderer(cam, texture, terrain)
    px, py = np.meshgrid(np.arange(0, SIZE[0], 3.0), np.arange(0, SIZE[1], 3.0))
    hits = r.cast(g, px.ravel(), py.ravel())
    assert np.all(np.isfinite(hits.t))

    def surface(p):
        return 0.02 * p[..., 0] - 0.03 * p[..., 1] + A * np.sin(2 * np.pi * p[..., 0] / L)

    assert np.max(np.abs(hits.point[:, 2] - surface(hits.point))) < 1e-3
    assert np.max(np.abs(hits.point[:, 2] - terrain.height(hits.point[:, 0], hits.point[:, 1]))) < 1e-3
    # The hit projects back to its pixel.
    cam_pts = (hits.point - g[:3, 3]) @ g[:3, :3]
    back = cam.project(cam_pts)
    assert np.max(np.abs(back - np.column_stack([px.ravel(), py.ravel()]))) < 1e-3
    # First crossing: the ray is above the surface (less 1 mm) everywhere before the hit.
    frac = np.linspace(0.0, 1.0, 400, endpoint=False)[None, :, None]
    before = g[:3, 3] + frac * (hits.point - g[:3, 3])[:, None, :]
    assert np.min(before[..., 2] - surface(before)) > -1e-3


def test_a_rock_occludes_the_ground_behind_it(texture):
    """A 20 cm rock 3 m ahead: the ray to a ground point just behind it meets the rock."""
    rock = Rocks(centre=np.array([[3.0, 0.0, -0.05]]), axes=np.array([[0.3, 0.25, 0.25]]),
                 angle=np.array([0.3]), albedo=np.array([0.5]))
    terrain = Terrain("rocks", (0.0, 0.0), np.zeros((64, 64), np.float32), 0.04, rock)
    cam = default_camera(*SIZE)
    g = make_pose(body_from_camera(math.radians(30.0)), np.array([0.0, 0.0, 1.5]))
    r = TerrainRenderer(cam, texture, terrain, sun_azimuth=2.0)
    # The ground point behind the rock's top, on the line from the camera over it.
    top = np.array([3.0, 0.0, 0.2])
    o = g[:3, 3]
    behind = o + (top - o) * (o[2] / (o[2] - top[2])) * 0.999
    assert behind[0] > 3.3  # beyond the rock's footprint
    p = cam.project(((behind - o) @ g[:3, :3])[None, :])[0]
    hits = r.cast(g, [p[0]], [p[1]])
    assert hits.rock[0] == 0
    assert hits.t[0] < 0.95 * float((behind - o) @ g[:3, 2])  # nearer than the ground point
    q = hits.point[0] - rock.centre[0]
    c, s = math.cos(0.3), math.sin(0.3)
    unit = np.array([c * q[0] + s * q[1], -s * q[0] + c * q[1], q[2]]) / rock.axes[0]
    assert abs(np.linalg.norm(unit) - 1.0) < 1e-6  # on the ellipsoid
    assert hits.point[0, 2] > 0.1
    assert abs(hits.point[0, 2] - terrain.height(hits.point[0, 0], hits.point[0, 1])) < 1e-3
    # A pixel well beside the rock sees the ground.
    side = cam.project(((np.array([3.0, 1.5, 0.0]) - o) @ g[:3, :3])[None, :])[0]
    hits = r.cast(g, [side[0]], [side[1]])
    assert hits.rock[0] == -1 and abs(hits.point[0, 2]) < 1e-6
    # The rendered image shows the rock: rows through it differ from the bare ground.
    img = r.render(g)
    bare = TerrainRenderer(cam, texture, flat(), sun_azimuth=2.0).render(g)
    assert np.abs(img - bare)[int(p[1]), int(p[0])] > 0.0
    assert np.mean(np.abs(img - bare) > 1.0) > 0.005


def test_rocks_terrain_has_rocks_sunk_into_the_ground():
    t = make_terrain("rocks", np.random.default_rng(2), (-5.0, -5.0, 5.0, 5.0))
    assert 40 < len(t.rocks) < 120  # 0.8 per m^2 over 100 m^2
    visible = t.rocks.centre[:, 2] + t.rocks.axes[:, 2]
    assert visible.min() >= 0.03 - 1e-9 and visible.max() <= 0.20 + 1e-9
    assert np.all(t.rocks.centre[:, 2] < 0)
    assert t.height(t.rocks.centre[:, 0], t.rocks.centre[:, 1]) == pytest.approx(visible)


# ----------------------------------------------------------------------------- motion


def test_mer_path_steps_and_turns_in_range():
    path, turning = mer_path(120, np.random.default_rng(4))
    step = np.hypot(*np.diff(path[:, :2], axis=0).T)
    turn = np.degrees(np.abs(np.diff(path[:, 2])))
    assert turning[1:].sum() > 10 and (~turning[1:]).sum() > 50
    drive = ~turning[1:]
    assert np.all((step[drive] >= MER_STEP[0]) & (step[drive] <= MER_STEP[1]))
    assert np.all(turn[drive] <= MER_ARC_DEG + 1e-9)
    assert np.all(step[~drive] == 0.0)
    assert np.all((turn[~drive] >= MER_TURN_DEG[0]) & (turn[~drive] <= MER_TURN_DEG[1]))


def test_body_lies_on_a_sloping_plane_and_bobs_from_a_crest():
    slope = (math.tan(math.radians(6.0)) * 0.6, math.tan(math.radians(6.0)) * 0.8)
    path = np.array([[1.0, 2.0, 0.3], [1.5, 2.1, 1.9]])
    for g in body_on_ground(path, lambda x, y: slope[0] * x + slope[1] * y + 0.1):
        normal = np.array([-slope[0], -slope[1], 1.0]) / math.hypot(*slope, 1.0)
        assert g[:3, 2] == pytest.approx(normal, abs=1e-12)
        assert g[2, 3] == pytest.approx(slope[0] * g[0, 3] + slope[1] * g[1, 3] + 0.1, abs=1e-12)
    bob = bobbing(50, np.random.default_rng(1), (15.0, 60.0))
    limits = np.array([BOB_HEIGHT, math.radians(BOB_TILT_DEG), math.radians(BOB_TILT_DEG)])
    assert np.abs(bob[0]) == pytest.approx(limits)  # frame 0 at a crest, not at the mean
    assert np.all(np.abs(bob) <= limits + 1e-12)


def test_frame_0_may_sit_at_a_given_height_of_the_bobbing():
    """``crest``: frame 0's height is the one given, its pitch and roll at their means; the
    bobbing keeps its range (issue 24's case: +1.3 cm of +-2 cm)."""
    limits = np.array([BOB_HEIGHT, math.radians(BOB_TILT_DEG), math.radians(BOB_TILT_DEG)])
    for crest in (0.013, -BOB_HEIGHT, 0.0):
        bob = bobbing(400, np.random.default_rng(5), (15.0, 60.0), crest)
        assert bob[0] == pytest.approx([crest, 0.0, 0.0], abs=1e-15)
        assert np.all(np.abs(bob) <= limits + 1e-12)
        assert np.all(np.abs(bob).max(axis=0) > 0.8 * limits)  # it bobs most of that far


def test_crest_is_frame_0s_distance_off_the_design_mount(synth_drive, tmp_path):
    """On flat ground frame 0's plane in init.yaml is the design mount's moved by the crest
    along its normal, the tilts unchanged; synth.yaml records it; out of range, or without a
    rover, it is refused."""
    seq = synth_drive(terrain="flat", frames=2, size=SIZE, seed=3, noise_var=0.0, crest=0.013)
    init = yaml.safe_load((seq / "init.yaml").read_text())
    n_nom, d_nom = ground_in_camera(rover_mount("drive"))
    assert init["ground"]["distance"] == pytest.approx(d_nom + 0.013, abs=1e-9)
    assert init["ground"]["normal"] == pytest.approx(n_nom, abs=1e-9)
    assert yaml.safe_load((seq / "synth.yaml").read_text())["crest"] == 0.013
    with pytest.raises(InputError, match="--crest"):
        synthesize(tmp_path / "a", preset="drive", terrain="flat", frames=2, size=(64, 64), crest=0.03)
    with pytest.raises(InputError, match="--crest"):
        synthesize(tmp_path / "b", preset="drive", frames=2, size=(64, 64), crest=0.01)


# ----------------------------------------------------------------------------- written drives


@pytest.fixture(scope="module")
def rolling_drive(synth_drive):
    return synth_drive(terrain="rolling", frames=6, size=SIZE, seed=3, noise_var=0.0)


def test_terrain_drive_ground_truth_chains(rolling_drive):
    _, tum = read_tum(rolling_drive / "groundtruth.tum")
    _, rel, _ = read_motion_csv(rolling_drive / "groundtruth_motion.csv")
    assert len(tum) == 6 and len(rel) == 5
    chain = np.eye(4)
    for k in range(1, 6):
        chain = chain @ rel[k - 1]
        assert chain == pytest.approx(tum[k], abs=1e-6)
    steps = np.linalg.norm(np.diff(tum[:, :3, 3], axis=0), axis=1)
    assert np.all(steps > 0.01) and np.all(steps < 0.15)  # ~5 cm per frame


def test_terrain_drive_init_yaml_is_frame_0s_ground(rolling_drive):
    """init.yaml holds frame 0's ground: the wheels' plane at frame 0 seen from the bobbing
    camera (SPEC.md), so the nominal mount's 1.5 m is off by the crest."""
    text = (rolling_drive / "init.yaml").read_text()
    assert "frame 0's" in text.splitlines()[0]
    init = yaml.safe_load(text)
    assert "nominal" not in init["ground"]
    n_nom, d_nom = ground_in_camera(rover_mount("drive"))  # mast 1.5 m, pitched 40 deg
    assert abs(init["ground"]["distance"] - 1.5) > 0.002
    assert math.degrees(math.acos(np.dot(init["ground"]["normal"], n_nom))) > 1.0
    assert init["camera"]["fx"] == pytest.approx(0.87 * SIZE[0])
    params = yaml.safe_load((rolling_drive / "synth.yaml").read_text())
    assert params["terrain"] == "rolling" and params["pitch_deg"] == pytest.approx(40.0)
    assert "init_pose" not in params


def test_terrain_drive_init_yaml_may_be_the_nominal_mount(synth_drive):
    """With init_pose="nominal" init.yaml holds the nominal mount and says so."""
    seq = synth_drive(terrain="rolling", frames=3, size=SIZE, seed=3, noise_var=0.0,
                      init_pose="nominal")
    text = (seq / "init.yaml").read_text()
    assert "nominal" in text.splitlines()[0]
    init = yaml.safe_load(text)
    n, d = ground_in_camera(rover_mount("drive"))
    assert init["ground"]["nominal"] is True
    assert init["ground"]["normal"] == pytest.approx(n, abs=1e-12)
    assert init["ground"]["distance"] == pytest.approx(1.5, abs=1e-12)
    assert yaml.safe_load((seq / "synth.yaml").read_text())["init_pose"] == "nominal"


def test_init_pose_nominal_needs_a_drive(tmp_path):
    with pytest.raises(InputError, match="--init-pose nominal"):
        synthesize(tmp_path / "p", preset="pairs", frames=1, size=(64, 64), init_pose="nominal")
    with pytest.raises(InputError, match="--init-pose 'mean'"):
        synthesize(tmp_path / "q", preset="drive", frames=2, size=(64, 64), init_pose="mean")


def test_terrain_npz_is_the_rendered_surface(rolling_drive, texture):
    terrain = load_terrain(rolling_drive / "terrain.npz")
    assert terrain.kind == "rolling"
    lo, hi = terrain.swell_range()
    assert -0.05 - 1e-6 <= lo < -0.02 and 0.02 < hi <= 0.05 + 1e-6  # +-5 cm
    with np.load(rolling_drive / "terrain.npz") as f:
        heights, origin, step = f["heights"], f["heights_origin"], float(f["heights_spacing"])
    j, i = 17, 23
    assert heights[j, i] == pytest.approx(terrain.height(origin[0] + i * step, origin[1] + j * step),
                                          abs=1e-6)
    # The camera poses in G agree with the ground truth; camera 0 is ~1.5 m over the ground.
    with np.load(rolling_drive / "terrain.npz") as f:
        g = f["g_from_cam"]
    _, tum = read_tum(rolling_drive / "groundtruth.tum")
    for k in range(len(tum)):
        assert se3_inv(g[0]) @ g[k] == pytest.approx(tum[k], abs=1e-6)
    clearance = g[0][2, 3] - terrain.height(g[0][0, 3], g[0][1, 3])
    assert 1.5 - 0.1 < clearance < 1.5 + 0.1  # mast, bobbing (+-2 cm + tilt), swell (+-5 cm)


def test_frame0_is_off_the_nominal_mounting_by_the_bobbing_crest():
    """The camera at frame 0 = body (plane of the wheels) @ bobbing at a crest @ mounting."""
    scene = rover_scene("drive", "slope", 8, motion_rng=np.random.default_rng(1),
                        terrain_rng=np.random.default_rng(2), bob_rng=np.random.default_rng(3),
                        peak_step=0.065, origin=(1.0, 2.0))
    body0 = body_on_ground(scene.path[:1], scene.terrain.base_height)[0]
    off = se3_inv(body0) @ scene.poses[0] @ se3_inv(scene.mount)  # the bobbing
    assert abs(off[2, 3]) == pytest.approx(BOB_HEIGHT, abs=1e-12)
    tilt = math.degrees(math.acos(off[2, 2]))
    assert 2.0 < tilt <= math.hypot(BOB_TILT_DEG, BOB_TILT_DEG) + 1e-9
    # The body itself leans with the 6 deg slope under the wheels.
    assert math.degrees(math.acos(body0[2, 2])) == pytest.approx(6.0, abs=0.5)
    # So the true ground under the camera is not the nominal plane of init.yaml.
    n_true, d_true = ground_in_camera(se3_inv(body0) @ scene.poses[0])  # the wheels' plane
    n_nom, d_nom = ground_in_camera(scene.mount)
    assert d_nom == 1.5 and abs(d_true - d_nom) > 0.002  # (2 cm bob, part undone by the pitch)
    assert math.degrees(math.acos(n_true @ n_nom)) > 2.0


def test_mer_preset_defaults_and_steps(tmp_path):
    out = tmp_path / "mer"
    s = synthesize(out, preset="mer", frames=5, size=(64, 64), seed=1, texture="gravel")
    init = yaml.safe_load((out / "init.yaml").read_text())
    assert init["camera"]["fx"] == pytest.approx(32.0 / math.tan(math.radians(22.5)))
    n, d = ground_in_camera(rover_mount("mer"))  # the nominal mount; init.yaml: frame 0's
    assert d == 1.5 and math.degrees(math.asin(-n[2])) == pytest.approx(-45.0)
    assert abs(init["ground"]["distance"] - 1.5) < 0.05
    assert math.degrees(math.acos(np.dot(init["ground"]["normal"], n))) < 4.0
    params = yaml.safe_load((out / "synth.yaml").read_text())
    assert params["terrain"] == "flat" and params["texture"] == "gravel"
    _, tum = read_tum(out / "groundtruth.tum")
    steps = np.linalg.norm(np.diff(tum[:, :3, 3], axis=0), axis=1)
    assert np.all(steps > 0.05) and np.all(steps < 0.9)  # a drive step or a turn's mast swing
    assert s.distance_m == pytest.approx(steps.sum())


def test_same_seed_same_bytes(tmp_path):
    def run(name, seed):
        out = tmp_path / name
        synthesize(out, terrain="rocks", frames=3, size=(64, 48), seed=seed)
        return [(out / "frames" / f"frame_{k:06d}.png").read_bytes() for k in range(3)] + [
            (out / "terrain.npz").read_bytes(), (out / "groundtruth.tum").read_bytes()]

    a, b, c = run("a", 5), run("b", 5), run("c", 6)
    assert a == b
    assert all(x != y for x, y in zip(a, c))


@pytest.mark.parametrize("kwargs, match", [
    ({"terrain": "hills"}, "unknown terrain"),
    ({"terrain": "flat", "preset": "pairs"}, "only the drive and mer presets"),
    ({"preset": "mer", "max_translation": 0.5}, "steps are fixed"),
])
def test_bad_terrain_arguments(tmp_path, kwargs, match):
    with pytest.raises(InputError, match=match):
        synthesize(tmp_path / "x", frames=2, size=(64, 48), **kwargs)
    assert not (tmp_path / "x").exists()


# ----------------------------------------------------------------------------- gravel


def test_gravel_texture_is_seamless_deterministic_and_unlike_the_procedural_one():
    g = gravel_texture(256, 3, metres_per_texel=0.003)
    assert np.array_equal(g, gravel_texture(256, 3, metres_per_texel=0.003))
    assert not np.array_equal(g, gravel_texture(256, 4, metres_per_texel=0.003))
    assert g.mean() == pytest.approx(120.0, abs=3.0) and g.std() == pytest.approx(40.0, abs=3.0)
    # Seamless: steps across the wrap-around are like steps inside.
    inside = np.abs(np.diff(g, axis=1)).mean()
    seam = np.abs(g[:, 0] - g[:, -1]).mean()
    assert seam < 1.3 * inside
    # Different statistics: gravel has far more of its variance in fine detail.
    def fine_share(img):
        smooth = cv2.GaussianBlur(np.pad(img, 16, mode="wrap"), (0, 0), 3.0)[16:-16, 16:-16]
        return float(np.var(img - smooth) / np.var(img))

    assert fine_share(g) > 0.6 > 0.4 > fine_share(procedural_texture(256, 3))


# ----------------------------------------------------------------------------- the command


def test_cli_terrain_mer_and_gravel(tmp_path):
    from click.testing import CliRunner

    from monovo_cli.cli import main

    r = CliRunner().invoke(main, ["synth", str(tmp_path / "a"), "--terrain", "rocks", "--texture",
                                  "gravel", "--frames", "3", "--size", "64x48", "-q"])
    assert r.exit_code == 0, r.output
    params = yaml.safe_load((tmp_path / "a" / "synth.yaml").read_text())
    assert (params["terrain"], params["texture"], params["preset"]) == ("rocks", "gravel", "drive")
    assert (tmp_path / "a" / "terrain.npz").is_file()
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "b"), "--preset", "mer", "--frames", "2",
                                  "--size", "64x64", "-q"])
    assert r.exit_code == 0, r.output
    assert yaml.safe_load((tmp_path / "b" / "synth.yaml").read_text())["terrain"] == "flat"
    r = CliRunner().invoke(main, ["synth", str(tmp_path / "c"), "--preset", "pairs", "--terrain",
                                  "slope", "--frames", "1"])
    assert r.exit_code == 2 and "only the drive and mer presets" in r.output
    assert "Traceback" not in r.output
