"""CAHV / CAHVOR / CAHVORE camera models: projection, rays, conversion to a pinhole, init.yaml.

The Navcam facts are MER's published ones (Maki et al. 2003, JGR 108(E12) 8071): 1024 x 1024
pixels of 12 um behind a 14.67 mm lens, a 45 deg field of view, 0.82 mrad per pixel at the
centre. The CAHVOR vectors below are built from those facts; their radial terms and the
optical axis' tilt are of the size a calibrated Navcam has, not a published calibration.
"""

import math

import cv2
import numpy as np
import pytest
import yaml

from monovo_cli.errors import ConfigError
from monovo_cli.geometry.cahvor import CahvorModel, cahvor_from_pinhole, fit_pinhole
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import so3_exp
from monovo_cli.io.config import load_init
from monovo_cli.io.jpl_camera import MAX_RMS_PX

NAVCAM_PIXELS = 1024
NAVCAM_FOCAL_MM = 14.67
NAVCAM_PIXEL_MM = 0.012
NAVCAM_FOV_DEG = 45.0
NAVCAM_IFOV_MRAD = 0.82


def _rotation(seed: int) -> np.ndarray:
    return so3_exp(np.random.default_rng(seed).normal(size=3))


def navcam(scale: float = 1.0, seed: int = 3) -> CahvorModel:
    """A CAHVOR of a MER-Navcam-like camera, in a rover frame turned and shifted from the
    camera's; ``scale`` resamples the image (0.25: the 256 x 256 Navcam)."""
    f = NAVCAM_FOCAL_MM / NAVCAM_PIXEL_MM * scale
    cx = (515.2 + 0.5) * scale - 0.5  # principal point a few px off the centre
    cy = (508.7 + 0.5) * scale - 0.5
    rover_R_cam = _rotation(seed)
    x, y, z = rover_R_cam.T
    o_cam = so3_exp(np.radians([0.3, -0.2, 0.0])) @ np.array([0.0, 0.0, 1.0])
    return CahvorModel(C=np.array([0.45, -0.3, -1.5]), A=z, H=f * x + cx * z, V=f * y + cy * z,
                       O=rover_R_cam @ o_cam, R=np.array([1e-4, -0.012, 0.006]))


def _points(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-3.0, 3.0, (n, 3))
    X[:, 2] = rng.uniform(1.0, 20.0, n)
    return X


def _to_model(cam_from_model: np.ndarray, X_cam: np.ndarray) -> np.ndarray:
    model_from_cam = np.linalg.inv(cam_from_model)
    return X_cam @ model_from_cam[:3, :3].T + model_from_cam[:3, 3]


# --------------------------------------------------------------------------- the model


def test_cahvor_with_o_along_a_is_opencv_radial_distortion():
    cam = PinholeCamera(640, 480, 520.0, 515.0, 322.5, 236.0, (-0.21, 0.05, 0.0, 0.0, 0.0))
    T = np.eye(4)
    T[:3, :3] = _rotation(1)
    T[:3, 3] = [0.2, -0.4, 1.1]
    m = cahvor_from_pinhole(cam, T)
    X = _points(400, 0)
    np.testing.assert_allclose(m.project(_to_model(T, X)), cam.project(X), atol=1e-9)
    np.testing.assert_allclose(m.cam_from_model, T, atol=1e-12)
    assert (m.hs, m.vs, m.hc, m.vc) == pytest.approx((520.0, 515.0, 322.5, 236.0), abs=1e-9)


@pytest.mark.parametrize("linearity", [1.0, 0.5, 0.0, -0.3])
def test_rays_and_projection_are_inverse(linearity):
    base = navcam()
    m = CahvorModel(C=base.C, A=base.A, H=base.H, V=base.V, O=base.O, R=base.R,
                    E=np.array([0.01, 0.02, -0.005]), linearity=linearity, kind="cahvore")
    uv = np.random.default_rng(2).uniform(0.0, 1023.0, (300, 2))
    origins, d = m.rays(uv)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    for depth in (0.3, 5.0, 100.0):  # the pupil shift makes the depth matter near the lens
        np.testing.assert_allclose(m.project(origins + depth * d), uv, atol=1e-8)
    # the entrance pupil moves along O, and only by the E terms' amount
    shift = (origins - m.C) @ m.O
    np.testing.assert_allclose(origins - m.C, shift[:, None] * m.O, atol=1e-15)
    assert np.all(np.abs(shift) < 0.01)


def test_cahvore_perspective_without_pupil_shift_is_cahvor():
    m = navcam()
    e = CahvorModel(C=m.C, A=m.A, H=m.H, V=m.V, O=m.O, R=m.R, E=np.zeros(3), linearity=1.0,
                    kind="cahvore")
    P = _to_model(m.cam_from_model, _points(300, 4))
    np.testing.assert_allclose(e.project(P), m.project(P), atol=1e-9)


def test_points_behind_the_camera_have_no_pixel():
    m = navcam()
    P = _to_model(m.cam_from_model, np.array([[0.1, 0.2, -3.0], [0.0, 0.0, 2.0]]))
    uv = m.project(P)
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))


@pytest.mark.parametrize("change, match", [
    (dict(A=[0.0, 0.0, 2.0]), "A must be a unit vector"),
    (dict(H=[0.0, 0.0, 500.0]), "H and V must not be parallel to A"),
    (dict(V=[0.0, -1000.0, 512.0]), "left-handed"),
    (dict(O=[1.0, 0.0, 0.0]), "O is 90 deg from A"),
    (dict(R=[0.0, 1.0]), "R must be 3 finite numbers"),
])
def test_impossible_models_are_refused(change, match):
    args = dict(C=[0.0, 0.0, 0.0], A=[0.0, 0.0, 1.0], H=[1000.0, 0.0, 512.0],
                V=[0.0, 1000.0, 512.0], O=[0.0, 0.0, 1.0], R=[0.0, 0.0, 0.0])
    args.update(change)
    with pytest.raises(ValueError, match=match):
        CahvorModel(**{k: np.array(v, dtype=float) for k, v in args.items()})


# --------------------------------------------------------------------------- conversion


def test_radial_cahvor_converts_exactly():
    cam = PinholeCamera(800, 600, 700.0, 698.0, 401.3, 297.9, (-0.3, 0.11, 0.0, 0.0, 0.0))
    fit = fit_pinhole(cahvor_from_pinhole(cam), 800, 600)
    assert fit.rms_px < 1e-9
    assert (fit.camera.fx, fit.camera.fy, fit.camera.cx, fit.camera.cy) == pytest.approx(
        (700.0, 698.0, 401.3, 297.9), abs=1e-7)
    np.testing.assert_allclose(fit.camera.distortion, cam.distortion, atol=1e-9)


def test_navcam_converts_within_0_05_px_and_matches_the_published_facts():
    m = navcam()
    fit = fit_pinhole(m, NAVCAM_PIXELS, NAVCAM_PIXELS)
    assert fit.rms_px <= 0.05 and fit.max_px <= 0.1, (fit.rms_px, fit.max_px)
    cam = fit.camera
    # f = 14.67 mm / 12 um = 1222.5 px; 0.82 mrad per pixel; a 45 deg field of view
    assert cam.fx == pytest.approx(NAVCAM_FOCAL_MM / NAVCAM_PIXEL_MM, rel=1e-3)
    assert cam.fy == pytest.approx(NAVCAM_FOCAL_MM / NAVCAM_PIXEL_MM, rel=1e-3)
    assert 1000.0 / cam.fx == pytest.approx(NAVCAM_IFOV_MRAD, abs=0.005)
    rays = m.rays(np.array([[-0.5, cam.cy], [NAVCAM_PIXELS - 0.5, cam.cy]]))[1]
    fov = math.degrees(math.acos(float(rays[0] @ rays[1])))
    assert fov == pytest.approx(NAVCAM_FOV_DEG, abs=1.0)
    # the conversion's pinhole puts the model's 3-D points where the model does
    X = _points(500, 6)
    X[:, 2] += 2.0
    uv_model = m.project(_to_model(fit.cam_from_model, X))
    inside = np.all((uv_model >= 0) & (uv_model <= NAVCAM_PIXELS - 1), axis=1)
    err = np.linalg.norm(cam.project(X[inside]) - uv_model[inside], axis=1)
    assert inside.sum() > 100 and np.sqrt(np.mean(err ** 2)) <= 0.05


def test_tilted_optical_axis_is_absorbed_by_the_tangential_terms():
    cam = PinholeCamera(1024, 1024, 1222.5, 1222.5, 511.5, 511.5, (-0.05, 0.01, 0.0, 0.0, 0.0))
    fit = fit_pinhole(cahvor_from_pinhole(cam, O_tilt_deg=(0.5, -0.3)), 1024, 1024)
    assert fit.rms_px < 0.01
    k1, k2, p1, p2, _ = fit.camera.distortion
    assert abs(p1) > 1e-5 and abs(p2) > 1e-5  # decentred distortion: tangential terms
    assert k1 == pytest.approx(-0.05, abs=1e-3)


def test_real_cahvore_of_a_pds4_label_converts():
    """The CAHVORE of the PDS4 Imaging dictionary's example label (a Mars 2020 camera on the
    robotic arm; model type 2, fish-eye linearity): its image is sized to put A at the
    centre, as the label's hc, vc say."""
    m = CahvorModel(C=[0.955584, 0.764515, -1.95254], A=[-0.35631, 0.916392, 0.182443],
                    H=[-3229.43, 141.993, 229.563], V=[-168.067, 400.716, 3088.89],
                    O=[-0.357624, 0.915861, 0.182539], R=[1.736e-06, 0.0501396, -0.0171254],
                    E=[-8.0e-09, 1.0e-08, -2.9e-08], linearity=0.0, kind="cahvore")
    w, h = round(2 * m.hc + 1), round(2 * m.vc + 1)
    fit = fit_pinhole(m, w, h)
    assert fit.rms_px < 0.2
    assert fit.camera.fx == pytest.approx(m.hs, rel=1e-3)
    uv = np.random.default_rng(0).uniform(0, [w - 1, h - 1], (200, 2))
    o, d = m.rays(uv)
    np.testing.assert_allclose(m.project(o + 3.0 * d), uv, atol=1e-7)


# --------------------------------------------------------------------------- init.yaml


def _init(tmp_path, camera: dict, ground=None) -> object:
    p = tmp_path / "init.yaml"
    p.write_text(yaml.safe_dump({"camera": camera, "ground": ground or {
        "normal": [0.0, 0.7071068, 0.7071068], "distance": 1.5}}))
    return p


def _cahvor_yaml(m: CahvorModel, size: int = NAVCAM_PIXELS) -> dict:
    return {"model": "cahvor", "width": size, "height": size,
            **{k: [float(v) for v in getattr(m, k)] for k in "CAHVOR"}}


def test_init_yaml_cahvor_becomes_the_fitted_pinhole(tmp_path, caplog):
    m = navcam()
    with caplog.at_level("INFO"):
        cfg = load_init(_init(tmp_path, _cahvor_yaml(m)))
    fit = fit_pinhole(m, NAVCAM_PIXELS, NAVCAM_PIXELS)
    assert cfg.camera == fit.camera
    assert "CAHVOR camera as pinhole" in caplog.text and "RMS" in caplog.text


def test_init_yaml_cahvore(tmp_path):
    m = navcam()
    cam = _cahvor_yaml(m)
    cam.update(model="cahvore", E=[0.0, 0.0, 0.0], linearity=1.0)
    a = load_init(_init(tmp_path, cam)).camera
    b = load_init(_init(tmp_path, _cahvor_yaml(m))).camera
    np.testing.assert_allclose([a.fx, a.fy, a.cx, a.cy, *a.distortion],
                               [b.fx, b.fy, b.cx, b.cy, *b.distortion], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("change, match", [
    ({"model": "kannala"}, r"camera\.model must be one of cahv, cahvor, cahvore, got 'kannala'"),
    ({"O": None}, r"camera\.O is missing"),
    ({"R": [0.0, 1.0]}, r"camera\.R must be a list of 3 numbers, got a list of 2 items"),
    ({"fx": 1000.0}, r"unknown key 'camera\.fx' for model cahvor"),
    ({"width": 0}, r"camera\.width must be a whole number of pixels"),
    ({"A": [0.0, 0.0, 3.0]}, r"camera is not a usable CAHVOR model: A must be a unit vector"),
])
def test_init_yaml_cahvor_errors_name_the_key(tmp_path, change, match):
    cam = _cahvor_yaml(navcam())
    for k, v in change.items():
        if v is None:
            del cam[k]
        else:
            cam[k] = v
    with pytest.raises(ConfigError, match=match):
        load_init(_init(tmp_path, cam))


def test_a_strong_fisheye_is_refused_with_its_error(tmp_path):
    m = navcam()
    cam = _cahvor_yaml(m)
    cam.update(model="cahvore", E=[0.0, 0.0, 0.0], linearity=0.0)
    cam["R"] = [0.0, 0.0, 0.0]
    cam["H"] = [float(v) for v in (600.0 * (m.H - m.hc * m.A) / m.hs + m.hc * m.A)]
    cam["V"] = [float(v) for v in (600.0 * (m.V - m.vc * m.A) / m.vs + m.vc * m.A)]
    with pytest.raises(ConfigError, match=rf"no pinhole \+ OpenCV distortion equivalent: RMS "
                                          rf".* limit {MAX_RMS_PX:g} px"):
        load_init(_init(tmp_path, cam))


# --------------------------------------------------------------------------- a drive


def test_a_drive_seen_through_the_navcam_model_tracks_within_1_percent(tmp_path):
    """A synthetic drive resampled into a 256 x 256 Navcam (the quarter-resolution CAHVOR) and
    tracked with ``camera: {model: cahvor}`` in init.yaml: the path length is within 1 %."""
    from click.testing import CliRunner

    from monovo_cli.cli import main
    from monovo_cli.io.formats import read_tum
    from monovo_cli.synth.write import synthesize

    synthesize(tmp_path / "src", preset="drive", frames=30, size=(320, 320), noise_var=10.0,
               seed=5)
    src = load_init(tmp_path / "src" / "init.yaml")
    m = navcam(scale=0.25)
    size = NAVCAM_PIXELS // 4
    uu, vv = np.meshgrid(np.arange(size, dtype=float), np.arange(size, dtype=float))
    d = m.rays(np.stack([uu.ravel(), vv.ravel()], axis=1))[1] @ m.cam_R_model.T
    K = src.camera  # the renderer's pinhole; the model's camera frame is the renderer's
    map_x = (K.fx * d[:, 0] / d[:, 2] + K.cx).reshape(size, size).astype(np.float32)
    map_y = (K.fy * d[:, 1] / d[:, 2] + K.cy).reshape(size, size).astype(np.float32)
    assert map_x.min() > 0 and map_x.max() < K.width - 1
    assert map_y.min() > 0 and map_y.max() < K.height - 1
    seq = tmp_path / "navcam"
    (seq / "frames").mkdir(parents=True)
    frames = sorted((tmp_path / "src" / "frames").glob("*.png"))
    assert len(frames) == 30
    for p in frames:
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(seq / "frames" / p.name), cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR))
    _init(seq, _cahvor_yaml(m, size), {"normal": [float(v) for v in src.plane.normal],
                                       "distance": src.plane.distance})
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(tmp_path / "out"), "-q"])
    assert r.exit_code == 0, r.output
    _, gt = read_tum(tmp_path / "src" / "groundtruth.tum")
    _, est = read_tum(tmp_path / "out" / "trajectory.tum")
    gt = np.linalg.inv(gt[0]) @ gt

    def length(poses):
        return float(np.sum(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)))

    assert length(gt) > 1.0
    assert length(est) == pytest.approx(length(gt), rel=0.01)
    assert np.linalg.norm(est[-1, :3, 3] - gt[-1, :3, 3]) < 0.01 * length(gt)


def test_a_cahvor_that_is_a_pinhole_tracks_to_the_pinholes_bytes(small_drive, tmp_path):
    """No distortion terms of rounding size: the fitted camera is the pinhole itself, and a
    drive tracked through its CAHVOR model gives the pinhole init.yaml's bytes."""
    from click.testing import CliRunner

    from monovo_cli.cli import main

    pinhole = load_init(small_drive / "init.yaml")
    assert not pinhole.camera.has_distortion
    model = cahvor_from_pinhole(pinhole.camera)
    params = _init(tmp_path, _cahvor_yaml(model, pinhole.camera.width),
                   {"normal": [float(v) for v in pinhole.plane.normal],
                    "distance": pinhole.plane.distance})
    cam = load_init(params).camera
    assert cam.distortion == (0.0, 0.0, 0.0, 0.0, 0.0) and not cam.has_distortion
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == pytest.approx(
        (pinhole.camera.fx, pinhole.camera.fy, pinhole.camera.cx, pinhole.camera.cy), abs=1e-9)
    outputs = {}
    for name, init in (("pinhole", small_drive / "init.yaml"), ("cahvor", params)):
        r = CliRunner().invoke(main, ["track", str(small_drive), "-p", str(init), "-o",
                                      str(tmp_path / name), "-q"])
        assert r.exit_code == 0, r.output
        outputs[name] = [(tmp_path / name / f).read_bytes()
                         for f in ("motion.csv", "trajectory.csv", "trajectory.tum")]
    assert outputs["cahvor"] == outputs["pinhole"]


def test_real_distortion_is_kept():
    from monovo_cli.io.jpl_camera import without_negligible_distortion

    cam = PinholeCamera(800, 600, 700.0, 698.0, 401.3, 297.9, (-0.3, 1e-18, 2e-5, 0.0, 1e-17))
    kept = without_negligible_distortion(cam)
    assert kept.distortion == (-0.3, 0.0, 2e-5, 0.0, 0.0)
