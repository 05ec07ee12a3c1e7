"""Tests of the synthetic-sequence generator (monovo_cli.synth).

The renders are checked against the geometry they claim: the plane homography against
PinholeCamera.project, a linear ramp texture against the exact ray/plane intersection
(pixel-centre and supersampling conventions to 0.01 px), and rendered frames against
their own ground truth files (photometric consistency, sub-pixel vertex of the SSD).
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from monovo_cli import synth  # the package: its public names
from monovo_cli.errors import InputError, MonovoError, OutputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, pose_from_vectors, se3_inv, so3_exp
from monovo_cli.io.formats import read_motion_csv, read_tum

SMALL = (128, 96)


# ----------------------------------------------------------------------------- helpers


def load_sequence(seq: Path):
    init = yaml.safe_load((seq / "init.yaml").read_text())
    c = init["camera"]
    cam = PinholeCamera(c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"])
    frames = sorted((seq / "frames").glob("*.png"))
    assert frames, f"no frames in {seq}"
    images = [cv2.imread(str(f), cv2.IMREAD_UNCHANGED) for f in frames]
    n0 = np.array(init["ground"]["normal"], dtype=float)
    d0 = float(init["ground"]["distance"])
    return cam, images, n0, d0


def plane_in_frame(n0: np.ndarray, d0: float, T_0_k: np.ndarray) -> tuple[np.ndarray, float]:
    """The plane {n0 . X0 = d0} in camera k: X0 = R Xk + t -> (R^T n0) . Xk = d0 - n0 . t."""
    R, t = T_0_k[:3, :3], T_0_k[:3, 3]
    return R.T @ n0, float(d0 - n0 @ t)


def warp_points(cam: PinholeCamera, n: np.ndarray, d: float, T_a_b: np.ndarray, margin: int):
    """Pixels p of frame a (interior), and where their ground point appears in frame b."""
    x, y = np.meshgrid(np.arange(margin, cam.width - margin),
                       np.arange(margin, cam.height - margin))
    uv = np.stack([x.ravel(), y.ravel()], axis=1).astype(float)
    rays = cam.rays(uv)
    X_a = rays * (d / (rays @ n))[:, None]
    T_b_a = se3_inv(T_a_b)
    X_b = X_a @ T_b_a[:3, :3].T + T_b_a[:3, 3]
    p_b = cam.project(X_b)
    inside = ((p_b[:, 0] >= margin) & (p_b[:, 0] <= cam.width - 1 - margin)
              & (p_b[:, 1] >= margin) & (p_b[:, 1] <= cam.height - 1 - margin))
    return uv[inside].astype(int), p_b[inside]


def sample(img: np.ndarray, p: np.ndarray, interpolation=cv2.INTER_LINEAR) -> np.ndarray:
    mx = p[:, 0].astype(np.float32).reshape(-1, 1)
    my = p[:, 1].astype(np.float32).reshape(-1, 1)
    return cv2.remap(img.astype(np.float32), mx, my, interpolation).ravel()


def photometric_error(cam, img_a, img_b, n, d, T_a_b, margin=4):
    """Mean |I_b(p') - I_a(p)| over textured interior pixels p of frame a (bilinear I_b)."""
    p, q = warp_points(cam, n, d, T_a_b, margin)
    a = img_a.astype(np.float32)
    grad = np.hypot(cv2.Sobel(a, cv2.CV_32F, 1, 0), cv2.Sobel(a, cv2.CV_32F, 0, 1)) / 8.0
    textured = grad[p[:, 1], p[:, 0]] > 2.0
    assert textured.sum() > 1000
    diff = sample(img_b, q[textured]) - a[p[textured, 1], p[textured, 0]]
    return float(np.mean(np.abs(diff)))


def ssd_vertex(cam, img_a, img_b, n, d, T_a_b, margin=5, h=0.1):
    """Sub-pixel offset (dx, dy) of frame b that minimises the SSD against frame a, from a
    parabola through the SSD at -h, 0, +h px (bicubic sampling of frame b)."""
    p, q = warp_points(cam, n, d, T_a_b, margin)
    va = img_a.astype(np.float32)[p[:, 1], p[:, 0]]
    out = []
    for axis in (0, 1):
        e = []
        for k in (-1, 0, 1):
            off = np.zeros(2)
            off[axis] = k * h
            e.append(float(np.mean((sample(img_b, q + off, cv2.INTER_CUBIC) - va) ** 2)))
        out.append(h * (e[0] - e[2]) / (2.0 * (e[0] - 2.0 * e[1] + e[2])))
    return np.array(out)


@pytest.fixture(scope="module")
def pairs_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("synth") / "pairs"
    s = synth.synthesize(out, preset="pairs", frames=3, size=SMALL, noise_var=0.0, seed=3)
    assert (s.sequences, s.frames_per_sequence) == (3, 2)
    return out


@pytest.fixture(scope="module")
def drive_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("synth") / "drive"
    s = synth.synthesize(out, preset="drive", frames=8, size=SMALL, noise_var=0.0, seed=5)
    assert (s.sequences, s.frames_per_sequence) == (1, 8)
    return out


# ----------------------------------------------------------------------------- geometry


def test_plane_homography_matches_projection():
    rng = np.random.default_rng(0)
    cam = synth.default_camera(688, 544)
    for _ in range(20):
        R = so3_exp(rng.uniform(-np.pi, np.pi, 3))
        # Camera above the plane, looking down-ish: make the optical axis point down.
        if R[2, 2] > 0:
            R = R @ np.diag([1.0, -1.0, -1.0])
        g = make_pose(R, np.array([rng.uniform(-50, 50), rng.uniform(-50, 50),
                                   rng.uniform(0.5, 100)]))
        H = synth.plane_homography(cam, g)
        # Ground points in front of the camera: along random rays that hit the plane.
        n, d = synth.ground_in_camera(g)
        rays = rng.normal(size=(400, 3))
        rays = rays[(rays @ n > 0.05) & (rays[:, 2] > 0.05)]
        assert len(rays) > 10
        X_c = rays * (d / (rays @ n))[:, None]
        X_g = X_c @ g[:3, :3].T + g[:3, 3]
        assert np.allclose(X_g[:, 2], 0.0, atol=1e-9 * max(1.0, d))
        h = np.column_stack([X_g[:, 0], X_g[:, 1], np.ones(len(X_g))]) @ H.T
        np.testing.assert_array_less(0.0, h[:, 2])  # third coordinate is the depth
        np.testing.assert_allclose(h[:, :2] / h[:, 2:], cam.project(X_c), rtol=0, atol=1e-9)
        np.testing.assert_allclose(h[:, 2], X_c[:, 2], rtol=1e-9)


def test_ground_in_camera_is_unit_normal_towards_plane():
    g = make_pose(synth.body_from_camera(math.radians(45.0)), np.array([3.0, -2.0, 1.5]))
    n, d = synth.ground_in_camera(g)
    np.testing.assert_allclose(n, [0.0, math.cos(math.pi / 4), math.sin(math.pi / 4)],
                               atol=1e-15)
    assert d == 1.5
    # The optical axis makes 45 deg with the horizontal: the centre ray dips 45 deg.
    cam = synth.default_camera(64, 64)
    dip = synth.ray_depression(cam, g, np.array([cam.cx]), np.array([cam.cy]))
    assert dip[0] == pytest.approx(math.radians(45.0), abs=1e-12)


def test_supersample_pixel_centres():
    for s in (1, 2, 3, 4):
        S = synth.supersample_matrix(s)
        i = np.arange(3 * s, dtype=float)
        orig = (i + 0.5) / s - 0.5
        back = S[0, 0] * orig + S[0, 2]
        np.testing.assert_allclose(back, i, atol=1e-12)


@pytest.mark.parametrize("s", [1, 3, 4])
def test_render_of_ramp_is_exact_ray_plane_intersection(s):
    """A linear ramp texture (value = texel coordinate) must render, at every pixel, the
    texel coordinate where the ray through the pixel centre meets the plane: this pins the
    pixel-centre, supersampling and mip-level alignment conventions to 0.01 texel (~px)."""
    size = 1024
    ramp_u = np.tile(np.arange(size, dtype=np.float32), (size, 1))
    cam = synth.default_camera(96, 72)
    # Oblique view (optical axis 25 deg off the normal), 40 m up, texels ~1 px near.
    R = synth.body_from_camera(math.radians(65.0)) @ so3_exp(np.radians([2.0, -3.0, 0.0]))
    g = make_pose(R, np.array([0.0, 0.0, 40.0]))
    m = 40.0 / cam.fx
    # Put the view in the middle of the ramp (far from its wrap-around seams).
    g[:2, 3] = [500.0 * m, 500.0 * m]
    for ramp, axis in ((ramp_u, 0), (np.ascontiguousarray(ramp_u.T), 1)):
        tex = synth.GroundTexture(ramp, m)
        img = synth.render_ground(cam, g, tex, supersample=s)
        Q = np.linalg.inv(synth.plane_homography(cam, g) @ tex.plane_from_texel(0))
        x, y = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
        nrm = Q[2, 0] * x + Q[2, 1] * y + Q[2, 2]
        want = (Q[axis, 0] * x + Q[axis, 1] * y + Q[axis, 2]) / nrm
        assert 100 < want.min() and want.max() < 900
        np.testing.assert_allclose(img, want, rtol=0, atol=0.01)


def test_mip_levels_are_aligned_and_periodic():
    n = 256
    i = np.arange(n)
    wave = np.cos(2 * np.pi * 3 * i / n)[None, :] * np.cos(2 * np.pi * 2 * i / n)[:, None]
    tex = synth.GroundTexture(100.0 * wave, 1.0)
    assert [lv.shape[0] for lv in tex.levels] == [256, 128, 64, 32, 16, 8]
    for level in (1, 2, 3):
        j = np.arange(n >> level) * (1 << level)
        want = 100.0 * np.cos(2 * np.pi * 3 * j / n)[None, :] * np.cos(2 * np.pi * 2 * j / n)[:, None]
        # pyrDown's Gaussian attenuates even these low frequencies a little (~8 % by
        # level 3), but must not shift them: after fitting the gain, what remains is far
        # below the ~7 grey levels that a shift of one level-0 texel would leave.
        got = tex.levels[level]
        gain = float(np.sum(got * want) / np.sum(want * want))
        assert 0.85 < gain <= 1.0
        np.testing.assert_allclose(got, gain * want, atol=0.3)


def test_procedural_texture_is_mars_like_and_seamless():
    tex = synth.procedural_texture(1024, seed=7)
    assert tex.shape == (1024, 1024) and tex.dtype == np.float32
    assert 110 < tex.mean() < 130 and 40 < tex.std() < 50
    interior = np.mean(np.abs(np.diff(tex, axis=1)))
    seam = np.mean(np.abs(tex[:, 0] - tex[:, -1]))
    seam_y = np.mean(np.abs(tex[0, :] - tex[-1, :]))
    assert seam < 1.5 * interior and seam_y < 1.5 * interior
    assert np.array_equal(tex, synth.procedural_texture(1024, seed=7))
    assert not np.array_equal(tex, synth.procedural_texture(1024, seed=8))


# ----------------------------------------------------------------------------- pairs


def test_pair_frames_agree_with_ground_truth(pairs_dir):
    for i in range(3):
        seq = pairs_dir / f"pair_{i:04d}"
        cam, (f0, f1), n0, d0 = load_sequence(seq)
        assert f0.dtype == np.uint8 and f0.shape == (SMALL[1], SMALL[0])
        _, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
        T01 = motions[0]
        # True motion: the residual is only interpolation (bilinear on texture with detail
        # down to ~1 px) plus uint8 rounding and the slightly different pixel footprints of
        # the two views -- measured ~1.4-2.1 grey levels, texture std ~45. A 3 m error in x
        # (~3 px) brings it near 20; even 0.3 m (~0.3 px) doubles it.
        good = photometric_error(cam, f0, f1, n0, d0, T01)
        bad = photometric_error(cam, f0, f1, n0, d0,
                                T01 @ pose_from_vectors(np.array([3.0, 0, 0]), np.zeros(3)))
        bad_rot = photometric_error(cam, f0, f1, n0, d0,
                                    T01 @ pose_from_vectors(np.zeros(3), np.radians([0, 0, 2.0])))
        assert good < 3.0
        assert bad > 5.0 * good and bad_rot > 5.0 * good
        # Sub-pixel: the SSD is smallest at zero offset to better than 0.02 px.
        np.testing.assert_array_less(np.abs(ssd_vertex(cam, f0, f1, n0, d0, T01)), 0.02)


def test_pair_geometry_and_region(pairs_dir):
    total = 0.0
    for i in range(3):
        seq = pairs_dir / f"pair_{i:04d}"
        init = yaml.safe_load((seq / "init.yaml").read_text())
        n = np.array(init["ground"]["normal"])
        assert init["ground"]["distance"] == pytest.approx(100.0)
        tilt = math.degrees(math.acos(n[2]))  # optical axis vs normal
        assert 25.0 - 7.1 <= tilt <= 25.0 + 7.1
        assert init["ground"]["region"] == [0, 0, SMALL[0], SMALL[1]]
        _, motions, _ = read_motion_csv(seq / "groundtruth_motion.csv")
        t = motions[0][:3, 3]
        assert np.all(np.abs(t) <= 10.0)
        rot = np.degrees(np.linalg.norm(cv2.Rodrigues(motions[0][:3, :3])[0]))
        assert rot <= 5.0 * math.sqrt(3) + 1e-9
        total += float(np.linalg.norm(t))
    meta = yaml.safe_load((pairs_dir / "synth.yaml").read_text())
    assert meta["preset"] == "pairs" and meta["frames"] == 3 and meta["size"] == list(SMALL)
    assert not (pairs_dir / "pair_0003").exists()


def test_pairs_summary_distance(tmp_path):
    s = synth.synthesize(tmp_path / "p", preset="pairs", frames=2, size=(64, 48), seed=1)
    total = 0.0
    for i in range(2):
        _, motions, _ = read_motion_csv(tmp_path / "p" / f"pair_{i:04d}" / "groundtruth_motion.csv")
        total += float(np.linalg.norm(motions[0][:3, 3]))
    assert s.distance_m == pytest.approx(total, rel=1e-12)
    assert s.out_dir == tmp_path / "p"


# ----------------------------------------------------------------------------- drive


def test_drive_ground_truth_files_round_trip(drive_dir):
    ts, traj = read_tum(drive_dir / "groundtruth.tum")
    frames, motions, status = read_motion_csv(drive_dir / "groundtruth_motion.csv")
    assert list(ts) == [float(k) for k in range(8)]
    assert list(frames) == list(range(1, 8)) and status == ["ok"] * 7
    np.testing.assert_allclose(traj[0], np.eye(4), atol=0)
    chained = np.eye(4)
    for k in range(1, 8):
        chained = chained @ motions[k - 1]
        np.testing.assert_allclose(chained, traj[k], rtol=0, atol=1e-9)
    header = (drive_dir / "groundtruth_motion.csv").read_text().splitlines()[0]
    assert header == "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status"
    # A rover: ~5 cm/frame (+-30 %), turning < 1 deg/frame, small wobble.
    steps = np.linalg.norm(motions[:, :3, 3], axis=1)
    assert np.all((0.035 - 0.01 < steps) & (steps < 0.065 + 0.01))
    angles = [np.degrees(np.linalg.norm(cv2.Rodrigues(T[:3, :3])[0])) for T in motions]
    assert max(angles) < 2.0


def test_drive_frames_agree_with_ground_truth(drive_dir):
    cam, images, n0, d0 = load_sequence(drive_dir)
    _, traj = read_tum(drive_dir / "groundtruth.tum")
    _, motions, _ = read_motion_csv(drive_dir / "groundtruth_motion.csv")
    for k in (1, 4, 7):
        n, d = plane_in_frame(n0, d0, traj[k - 1])
        assert np.linalg.norm(n) == pytest.approx(1.0)
        assert abs(d - 1.5) < 0.05  # mast height with its +-2 cm wobble
        T = motions[k - 1]
        good = photometric_error(cam, images[k - 1], images[k], n, d, T)
        bad = photometric_error(cam, images[k - 1], images[k], n, d,
                                T @ pose_from_vectors(np.array([0, 0.02, 0]), np.zeros(3)))
        assert good < 3.0 and bad > 4.0 * good
        np.testing.assert_array_less(np.abs(ssd_vertex(cam, images[k - 1], images[k], n, d, T)),
                                     0.02)


def test_drive_init_yaml(drive_dir):
    text = (drive_dir / "init.yaml").read_text()
    assert "!!" not in text  # plain YAML types only
    init = yaml.safe_load(text)
    assert list(init) == ["camera", "ground"]
    cam = init["camera"]
    assert list(cam) == ["width", "height", "fx", "fy", "cx", "cy", "distortion"]
    assert cam["distortion"] == [0.0] * 5  # written by io.config.dump_init: no lens distortion
    assert (cam["width"], cam["height"]) == SMALL
    assert all(isinstance(cam[k], int) for k in ("width", "height"))
    assert all(isinstance(cam[k], float) for k in ("fx", "fy", "cx", "cy"))
    assert cam["fx"] == cam["fy"] == pytest.approx(0.87 * SMALL[0])
    assert (cam["cx"], cam["cy"]) == ((SMALL[0] - 1) / 2, (SMALL[1] - 1) / 2)
    g = init["ground"]
    assert list(g) == ["normal", "distance", "region"]
    n = np.array(g["normal"])
    assert all(isinstance(v, float) for v in g["normal"])
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    # Frame 0 is the nominal mast pose: 1.5 m, pitched 45 deg down, no roll.
    np.testing.assert_allclose(n, [0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-12)
    assert g["distance"] == pytest.approx(1.5, abs=1e-12)
    assert g["region"] == [0, 0, SMALL[0], SMALL[1]]
    assert all(isinstance(v, int) for v in g["region"])
    meta = yaml.safe_load((drive_dir / "synth.yaml").read_text())
    assert meta["preset"] == "drive" and meta["seed"] == 5 and meta["noise_var"] == 0.0
    assert meta["size"] == list(SMALL) and meta["frames"] == 8


def test_drive_with_horizon_has_sky_and_cropped_region(tmp_path):
    # A tall, narrow image: the top rows look above the horizon.
    synth.synthesize(tmp_path / "d", preset="drive", frames=2, size=(48, 160), noise_var=0.0)
    init = yaml.safe_load((tmp_path / "d" / "init.yaml").read_text())
    x0, y0, x1, y1 = init["ground"]["region"]
    assert (x0, x1, y1) == (0, 48, 160) and 0 < y0 < 160
    img = cv2.imread(str(tmp_path / "d" / "frames" / "frame_000000.png"), cv2.IMREAD_UNCHANGED)
    assert np.all(img[0] == round(synth.SKY_VALUE))
    assert img[y0:].std() > 20  # textured ground below
    cam = synth.default_camera(48, 160)
    g = make_pose(synth.body_from_camera(math.radians(45.0)), np.array([0, 0, 1.5]))
    dip = synth.ray_depression(cam, g, np.arange(48.0), np.full(48, float(y0)))
    assert np.all(dip >= math.radians(synth.REGION_MIN_DEPRESSION_DEG))
    dip_above = synth.ray_depression(cam, g, np.arange(48.0), np.full(48, y0 - 1.0))
    assert np.any(dip_above < math.radians(synth.REGION_MIN_DEPRESSION_DEG))


def test_drive_noise_and_exposure(tmp_path):
    s = synth.synthesize(tmp_path / "e", preset="drive", frames=6, size=(64, 48),
                         noise_var=25.0, exposure=True, seed=2)
    assert s.distance_m == pytest.approx(
        sum(np.linalg.norm(T[:3, 3])
            for T in read_motion_csv(tmp_path / "e" / "groundtruth_motion.csv")[1]), rel=1e-9)
    rows = (tmp_path / "e" / "photometric.csv").read_text().splitlines()
    assert rows[0] == "frame,gain,bias" and len(rows) == 7
    vals = np.array([[float(v) for v in r.split(",")] for r in rows[1:]])
    assert list(vals[:, 0]) == list(range(6))
    assert np.all((0.8 <= vals[:, 1]) & (vals[:, 1] <= 1.2))
    assert np.all(np.abs(vals[:, 2]) <= 15.0)
    assert yaml.safe_load((tmp_path / "e" / "synth.yaml").read_text())["exposure"] is True


def test_noise_has_requested_variance():
    rng = np.random.default_rng(0)
    flat = np.full((200, 200), 100.0, np.float32)
    img = synth.finish_frame(flat, rng, 10.0).astype(float)
    # Rounding adds 1/12 grey level^2.
    assert img.var() == pytest.approx(10.0 + 1.0 / 12.0, rel=0.05)
    assert img.mean() == pytest.approx(100.0, abs=0.05)
    assert np.array_equal(synth.finish_frame(flat, rng, 0.0, gain=1.1, bias=-5.0),
                          np.full((200, 200), 105, np.uint8))


def test_progress_callback(tmp_path):
    calls = []
    synth.synthesize(tmp_path / "d", frames=3, size=(32, 32), progress=lambda i, n: calls.append((i, n)))
    assert calls == [(1, 3), (2, 3), (3, 3)]
    calls.clear()
    synth.synthesize(tmp_path / "p", preset="pairs", frames=2, size=(32, 32),
                     progress=lambda i, n: calls.append((i, n)))
    assert calls == [(1, 2), (2, 2)]


# ----------------------------------------------------------------------------- reproducibility


def _file_bytes(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_same_seed_same_bytes_different_seed_differs(tmp_path):
    kw = dict(preset="drive", frames=3, size=(64, 48))
    synth.synthesize(tmp_path / "a", seed=11, **kw)
    synth.synthesize(tmp_path / "b", seed=11, **kw)
    synth.synthesize(tmp_path / "c", seed=12, **kw)
    a, b, c = (_file_bytes(tmp_path / x) for x in "abc")
    assert "frames/frame_000002.png" in a and len(a) == 7
    assert a == b
    for name in ("frames/frame_000000.png", "frames/frame_000002.png", "groundtruth.tum"):
        assert a[name] != c[name]


def test_user_texture(tmp_path):
    rng = np.random.default_rng(4)
    photo = cv2.GaussianBlur(rng.integers(0, 256, (90, 150, 3)).astype(np.uint8), (0, 0), 1.0)
    path = tmp_path / "photo.jpg"
    assert cv2.imwrite(str(path), photo)
    synth.synthesize(tmp_path / "t", frames=2, size=(64, 48), texture=path, noise_var=0.0)
    img = cv2.imread(str(tmp_path / "t" / "frames" / "frame_000001.png"), cv2.IMREAD_UNCHANGED)
    assert img.ndim == 2 and img.dtype == np.uint8 and img.std() > 3
    meta = yaml.safe_load((tmp_path / "t" / "synth.yaml").read_text())
    assert meta["texture"] == str(path.resolve())
    # Resized to multiples of 32 and mirrored both ways: a seamless 192 x 320 tile.
    tex = synth.load_texture(path)
    assert tex.shape == (192, 320)
    np.testing.assert_array_equal(tex[:, :160], tex[:, 160:][:, ::-1])
    np.testing.assert_array_equal(tex[:96], tex[96:][::-1])


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(preset="moon"), InputError, r"--preset 'moon': unknown preset"),
    (dict(size=(31, 64)), InputError, r"--size 31x64: .*at least|--size 31x64: .*between 32"),
    (dict(size=(64,)), InputError, r"--size"),
    (dict(frames=1), InputError, r"--frames 1: must be a whole number >= 2"),
    (dict(preset="pairs", frames=0), InputError, r"--frames 0"),
    (dict(frames=2.5), InputError, r"--frames 2.5: must be a whole number"),
    (dict(noise_var=-1.0), InputError, r"--noise-var -1.0: must be a number >= 0"),
    (dict(noise_var=float("nan")), InputError, r"--noise-var nan"),
    (dict(seed=-3), InputError, r"--seed -3"),
    (dict(max_rotation_deg=-1.0), InputError, r"max_rotation_deg"),
    (dict(preset="pairs", max_translation=-1.0), InputError, r"max_translation"),
])
def test_bad_arguments(tmp_path, kwargs, error, match):
    with pytest.raises(error, match=match) as info:
        synth.synthesize(tmp_path / "out", **kwargs)
    assert isinstance(info.value, MonovoError)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()  # nothing written on bad arguments


def test_bad_texture(tmp_path):
    missing = tmp_path / "nope.png"
    with pytest.raises(InputError, match=r"nope\.png: cannot read texture"):
        synth.synthesize(tmp_path / "o1", frames=2, size=(32, 32), texture=missing)
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"this is not an image")
    with pytest.raises(InputError, match=r"junk\.png: cannot read texture"):
        synth.synthesize(tmp_path / "o2", frames=2, size=(32, 32), texture=junk)
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.zeros((8, 8), np.uint8))
    with pytest.raises(InputError, match=r"tiny\.png: texture is 8x8 px"):
        synth.synthesize(tmp_path / "o3", frames=2, size=(32, 32), texture=tiny)


def test_refuses_non_empty_or_non_directory_output(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    with pytest.raises(OutputError, match=r"out: already exists and is not empty"):
        synth.synthesize(out, frames=2, size=(32, 32))
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(OutputError, match=r"file: exists and is not a directory"):
        synth.synthesize(afile, frames=2, size=(32, 32))
    empty = tmp_path / "empty"
    empty.mkdir()
    s = synth.synthesize(empty, frames=2, size=(32, 32))  # an empty directory is fine
    assert (empty / "init.yaml").is_file() and s.frames_per_sequence == 2


def test_clean_frame0_removes_only_frame0_noise(tmp_path):
    """--clean-frame0: frame 0 equals the noise-free render; frame 1 keeps the very noise it
    has without the flag (the same seed draws the same noise)."""

    kw = dict(preset="pairs", frames=2, size=SMALL, noise_var=25.0, seed=4)
    synth.synthesize(tmp_path / "noisy", **kw)
    synth.synthesize(tmp_path / "clean", clean_frame0=True, **kw)
    synth.synthesize(tmp_path / "none", **{**kw, "noise_var": 0.0})

    def frame(root, pair, k):
        return cv2.imread(str(tmp_path / root / f"pair_{pair:04d}" / "frames" / f"frame_{k:06d}.png"),
                          cv2.IMREAD_GRAYSCALE).astype(float)

    for pair in range(2):
        assert np.array_equal(frame("clean", pair, 0), frame("none", pair, 0))
        assert np.array_equal(frame("clean", pair, 1), frame("noisy", pair, 1))
        noise = frame("noisy", pair, 0) - frame("none", pair, 0)
        assert 15.0 < noise.var() < 35.0
