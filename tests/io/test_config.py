"""init.yaml / camera_info loading, validation and writing (monovo_cli.config)."""

from __future__ import annotations

import copy
import logging
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from monovo_cli.errors import ConfigError, MonovoError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane, normal_from_pitch_roll
from monovo_cli.io.config import InitConfig, check_frame_size, dump_init, load_init

S = math.sqrt(0.5)
BASE = {
    "camera": {"width": 688, "height": 544, "fx": 600.0, "fy": 600.0, "cx": 343.5, "cy": 271.5,
               "distortion": [0.0, 0.0, 0.0, 0.0, 0.0]},
    "ground": {"normal": [0.0, S, S], "distance": 1.5, "region": [0, 272, 688, 544]},
}

SPEC_EXAMPLE = """\
camera:
  width: 688            # px, must match the frames
  height: 544
  fx: 600.0             # px
  fy: 600.0
  cx: 343.5             # px
  cy: 271.5
  distortion: [0.0, 0.0, 0.0, 0.0, 0.0]   # optional, OpenCV k1 k2 p1 p2 [k3]
ground:                 # the planar ground model at frame 0, in camera-0 frame
  normal: [0.0, 0.7071068, 0.7071068]     # unit normal n, pointing from the camera to the ground
  distance: 1.5         # d > 0, metres: the plane is { X : n . X = d }
  region: [0, 272, 688, 544]              # optional
"""


def write_yaml(tmp_path: Path, data, name: str = "init.yaml") -> Path:
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False))
    return p


def cfg_with(**changes) -> dict:
    """BASE with changes given as 'section__key'=value (value _DEL deletes the key)."""
    d = copy.deepcopy(BASE)
    for k, v in changes.items():
        section, key = k.split("__")
        if v is _DEL:
            del d[section][key]
        else:
            d[section][key] = v
    return d


_DEL = object()


def load(tmp_path: Path, data) -> InitConfig:
    return load_init(write_yaml(tmp_path, data))


# ----------------------------------------------------------------------------- valid files


def test_spec_example_loads(tmp_path):
    cfg = load(tmp_path, SPEC_EXAMPLE)
    cam = cfg.camera
    assert isinstance(cam, PinholeCamera)
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (688, 544, 600, 600, 343.5, 271.5)
    assert cam.distortion == (0.0,) * 5
    assert cfg.plane.distance == 1.5
    assert cfg.region == (0, 272, 688, 544)
    np.testing.assert_allclose(cfg.plane.normal, [0, S, S], atol=1e-7)
    assert np.linalg.norm(cfg.plane.normal) == pytest.approx(1.0, abs=1e-12)
    assert cfg.path == tmp_path / "init.yaml"


def test_defaults_region_whole_frame_and_no_distortion(tmp_path):
    d = cfg_with(ground__region=_DEL, camera__distortion=_DEL)
    cfg = load(tmp_path, d)
    assert cfg.region == (0, 0, 688, 544)
    assert cfg.camera.distortion == (0.0,) * 5
    d["camera"]["distortion"] = None
    d["ground"]["region"] = None
    cfg = load(tmp_path, d)
    assert cfg.region == (0, 0, 688, 544)


def test_yaml11_exponent_strings_and_integral_floats_accepted(tmp_path):
    text = SPEC_EXAMPLE.replace("fx: 600.0", "fx: 6e2").replace("width: 688", "width: 688.0")
    cfg = load(tmp_path, text)
    assert cfg.camera.fx == 600.0 and cfg.camera.width == 688 and isinstance(cfg.camera.width, int)


@pytest.mark.parametrize("dist, expected", [
    ([0.1, -0.01, 0.001, 0.002], (0.1, -0.01, 0.001, 0.002, 0.0)),
    ([0.1, -0.01, 0.001, 0.002, 0.003], (0.1, -0.01, 0.001, 0.002, 0.003)),
    ([0.1, -0.01, 0.001, 0.002, 0.003, 0, 0, 0], (0.1, -0.01, 0.001, 0.002, 0.003)),
])
def test_distortion_lengths(tmp_path, dist, expected):
    assert load(tmp_path, cfg_with(camera__distortion=dist)).camera.distortion == expected


# ----------------------------------------------------------------------------- file-level errors


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match=r"nope\.yaml: cannot read the init file \(No such file"):
        load_init(tmp_path / "nope.yaml")


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(ConfigError, match="is a directory"):
        load_init(tmp_path)


def test_not_yaml_reports_line_without_traceback(tmp_path):
    p = write_yaml(tmp_path, "camera:\n  width: [1, 2\n  height: 3\nground: {\n")
    with pytest.raises(ConfigError) as ei:
        load_init(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}: not valid YAML at line ")
    assert "\n" not in msg and "Traceback" not in msg


def test_invalid_date_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="not valid YAML"):
        load(tmp_path, "camera: 2001-13-45\n")


def test_binary_garbage(tmp_path):
    p = tmp_path / "init.yaml"
    p.write_bytes(b"\x00\xff\xfe\x07garbage")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_init(p)


@pytest.mark.parametrize("text, what", [("", "empty"), ("- 1\n- 2\n", "a list of 2 items"),
                                        ("42\n", "42"), ("hello\n", "'hello'")])
def test_not_a_mapping(tmp_path, text, what):
    with pytest.raises(ConfigError, match=what):
        load(tmp_path, text)


def test_missing_sections(tmp_path):
    with pytest.raises(ConfigError, match="missing 'camera' section.*camera_file"):
        load(tmp_path, {"ground": BASE["ground"]})
    with pytest.raises(ConfigError, match="missing 'ground' section"):
        load(tmp_path, {"camera": BASE["camera"]})


def test_camera_and_camera_file(tmp_path):
    d = copy.deepcopy(BASE)
    d["camera_file"] = "cam.yaml"
    with pytest.raises(ConfigError, match="either 'camera' or 'camera_file', not both"):
        load(tmp_path, d)


@pytest.mark.parametrize("section, key, hint", [
    (None, "grund", "did you mean 'ground'"),
    ("camera", "fxx", r"unknown key 'camera\.fxx' \(did you mean 'fx'\?\)"),
    ("camera", "distorsion", "did you mean 'distortion'"),
    ("ground", "pitch", r"unknown key 'ground\.pitch' \(did you mean 'pitch_deg'\?\)"),
    ("ground", "zzzzzz", r"expected one of normal, distance"),
])
def test_unknown_keys_suggest(tmp_path, section, key, hint):
    d = copy.deepcopy(BASE)
    (d if section is None else d[section])[key] = 1
    with pytest.raises(ConfigError, match=hint):
        load(tmp_path, d)


def test_non_string_key(tmp_path):
    d = copy.deepcopy(BASE)
    d["camera"][5] = 1
    with pytest.raises(ConfigError, match=r"unknown key 'camera\.5'"):
        load(tmp_path, d)


def test_duplicate_key(tmp_path):
    text = SPEC_EXAMPLE.replace("  fy: 600.0\n", "  fy: 600.0\n  fx: 500.0\n")
    with pytest.raises(ConfigError, match=r"line 6.*'fx' is given twice"):
        load(tmp_path, text)


# ----------------------------------------------------------------------------- camera values


def test_fx_negative_exact_message(tmp_path):
    p = write_yaml(tmp_path, cfg_with(camera__fx=-3))
    with pytest.raises(ConfigError) as ei:
        load_init(p)
    assert str(ei.value) == f"{p}: camera.fx must be > 0, got -3"


@pytest.mark.parametrize("key, value, msg", [
    ("fx", "abc", r"camera\.fx must be a number, got 'abc'"),
    ("fy", True, r"camera\.fy must be a number, got true"),
    ("fy", 0, r"camera\.fy must be > 0"),
    ("cx", float("nan"), r"camera\.cx must be a finite number, got nan"),
    ("cy", float("inf"), r"camera\.cy must be a finite number, got inf"),
    ("cx", None, r"camera\.cx must be a number, got null"),
    ("cx", [1, 2], r"camera\.cx must be a number, got a list of 2 items"),
    ("width", 688.5, r"camera\.width must be a whole number, got 688\.5"),
    ("width", 0, r"camera\.width must be a whole number of pixels in 1\.\."),
    ("height", -544, r"camera\.height must be a whole number of pixels"),
    ("height", "544x", r"camera\.height must be a number"),
    ("width", 10**40, r"camera\.width must be a whole number of pixels"),
])
def test_camera_value_errors(tmp_path, key, value, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, cfg_with(**{f"camera__{key}": value}))


def test_camera_missing_key(tmp_path):
    with pytest.raises(ConfigError, match=r"camera\.cy is missing"):
        load(tmp_path, cfg_with(camera__cy=_DEL))


def test_camera_not_mapping(tmp_path):
    with pytest.raises(ConfigError, match="camera must be a mapping"):
        load(tmp_path, {"camera": [1, 2], "ground": BASE["ground"]})


@pytest.mark.parametrize("value, msg", [
    ([0.1, 0.2, 0.3], "list of 4, 5 or 8 numbers"),
    ("0 0 0 0", "list of 4, 5 or 8 numbers"),
    ([0, 0, "x", 0], r"camera\.distortion\[2\] must be a number"),
    ([0, 0, 0, float("nan")], r"camera\.distortion\[3\] must be a finite number"),
    ([0, 0, 0, 0, 0, 0.1, 0, 0], "rational model"),
])
def test_distortion_errors(tmp_path, value, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, cfg_with(camera__distortion=value))


# ----------------------------------------------------------------------------- ground values


def test_both_ground_forms(tmp_path):
    with pytest.raises(ConfigError, match=r"both normal \+ distance and height \+ pitch_deg"):
        load(tmp_path, cfg_with(ground__height=1.5, ground__pitch_deg=45))


def test_no_ground_form(tmp_path):
    with pytest.raises(ConfigError, match=r"ground needs normal \+ distance, or height \+ pitch_deg"):
        load(tmp_path, cfg_with(ground__normal=_DEL, ground__distance=_DEL))


def test_half_forms(tmp_path):
    with pytest.raises(ConfigError, match=r"ground\.distance is missing"):
        load(tmp_path, cfg_with(ground__distance=_DEL))
    with pytest.raises(ConfigError, match=r"ground\.pitch_deg is missing"):
        load(tmp_path, cfg_with(ground__normal=_DEL, ground__distance=_DEL, ground__height=1.0))


@pytest.mark.parametrize("value, msg", [
    ([0, 1], r"ground\.normal must be a list of 3 numbers"),
    ([0, 1, "z"], r"ground\.normal\[2\] must be a number"),
    ([0, 0, 0], "must not be zero-length"),
    ([0, 0.0, -1.0], "not in front of the camera"),
])
def test_normal_errors(tmp_path, value, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, cfg_with(ground__normal=value))


def test_camera_looking_up_at_the_road_is_fine(tmp_path):
    """A camera pitched 2 deg *up* (normal z < 0) sees the road in the lower image: valid when
    the region's rays meet the plane in front of it (KITTI's start)."""
    p = math.radians(-2.0)
    normal = [0.0, math.cos(p), math.sin(p)]
    cfg = load(tmp_path, cfg_with(ground__normal=normal, ground__region=[0, 330, 688, 544]))
    assert cfg.plane.normal[2] < 0
    level = load(tmp_path, cfg_with(ground__normal=[0, 1.0, 0.0]))  # level, region below centre
    assert level.plane.normal[2] == 0
    with pytest.raises(ConfigError, match="not visible in region"):  # the whole frame: sky too
        load(tmp_path, cfg_with(ground__normal=normal, ground__region=[0, 0, 688, 544]))


def test_non_unit_normal_normalised_with_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="monovo_cli.io.config"):
        cfg = load(tmp_path, cfg_with(ground__normal=[0, 3.0, 4.0]))
    np.testing.assert_allclose(cfg.plane.normal, [0, 0.6, 0.8])
    assert any("normalised" in r.getMessage() and "length 5" in r.getMessage() for r in caplog.records)


def test_unit_normal_no_warning(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="monovo_cli.io.config"):
        load(tmp_path, BASE)
    assert not caplog.records


@pytest.mark.parametrize("key, value, msg", [
    ("distance", 0, r"ground\.distance must be > 0"),
    ("distance", -1.5, r"ground\.distance must be > 0, got -1\.5"),
    ("distance", ".nan", r"ground\.distance must be a number"),
])
def test_distance_errors(tmp_path, key, value, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, cfg_with(**{f"ground__{key}": value}))


def _hp(**ground) -> dict:
    d = copy.deepcopy(BASE)
    d["ground"] = {"height": 1.5, "pitch_deg": 45.0, **ground}
    return d


@pytest.mark.parametrize("ground, msg", [
    ({"height": 0}, r"ground\.height must be > 0"),
    ({"height": -2}, r"ground\.height must be > 0"),
    ({"pitch_deg": 0}, r"ground\.pitch_deg must be in \(0, 180\)"),
    ({"pitch_deg": 180}, r"ground\.pitch_deg must be in \(0, 180\)"),
    ({"pitch_deg": -10}, r"ground\.pitch_deg must be in \(0, 180\)"),
    ({"pitch_deg": "steep"}, r"ground\.pitch_deg must be a number"),
    ({"roll_deg": 90}, r"ground\.roll_deg must be in \(-90, 90\)"),
    ({"roll_deg": -95}, r"ground\.roll_deg must be in \(-90, 90\)"),
    ({"roll_deg": False}, r"ground\.roll_deg must be a number"),
])
def test_height_pitch_errors(tmp_path, ground, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, _hp(**ground))


# ----------------------------------------------------------------------------- region


@pytest.mark.parametrize("region, msg", [
    ([0, 0, 688], r"ground\.region must be a list of 4 whole numbers"),
    ("0 0 688 544", r"ground\.region must be a list of 4 whole numbers"),
    ([0, 0.5, 688, 544], r"ground\.region\[1\] must be a whole number"),
    ([0, 272, 689, 544], r"extends outside the 688x544 image"),
    ([-1, 272, 688, 544], r"extends outside the 688x544 image"),
    ([0, 272, 688, 545], r"extends outside"),
    ([100, 272, 100, 544], r"empty or inverted"),
    ([0, 544, 688, 272], r"empty or inverted"),
    ([0, 500, 30, 544], r"covers 0\.35% of the image; make it at least 1%"),
])
def test_region_errors(tmp_path, region, msg):
    with pytest.raises(ConfigError, match=msg):
        load(tmp_path, cfg_with(ground__region=region))


def test_region_integral_floats_ok(tmp_path):
    assert load(tmp_path, cfg_with(ground__region=[0.0, 272.0, 688, 544])).region == (0, 272, 688, 544)


# ----------------------------------------------------------------------------- visibility


def test_plane_not_visible_in_upper_image(tmp_path):
    # Pitched 10 deg down: the horizon is at v ~ cy - fy tan(10) ~ 166, so the top of
    # the whole-frame default region looks at the sky.
    d = _hp(pitch_deg=10.0)
    with pytest.raises(ConfigError, match=r"not visible in region \[0, 0, 688, 544\].*"
                                          r"check normal/pitch_deg"):
        load(tmp_path, d)
    d["ground"]["region"] = [0, 272, 688, 544]
    cfg = load(tmp_path, d)
    assert cfg.region == (0, 272, 688, 544)


def test_plane_too_oblique(tmp_path):
    # Horizon at v_h = cy - fy/tan(p); a row 0.03 px below it has depth ~ 2e4 * d.
    p = 10.0
    v_h = 271.5 - 600.0 * math.tan(math.radians(p))
    y0 = math.ceil(v_h)
    if y0 - v_h > 0.05:  # keep the region top just below the horizon
        p = math.degrees(math.atan((271.5 - (y0 - 0.03)) / 600.0))
    with pytest.raises(ConfigError, match=r"too oblique.*times the plane distance"):
        load(tmp_path, _hp(pitch_deg=p, region=[0, y0, 688, 544]))


def test_visibility_with_distortion(tmp_path):
    d = cfg_with(camera__distortion=[-0.2, 0.05, 0.0, 0.0, 0.0])
    assert load(tmp_path, d).camera.distortion[0] == -0.2


# ----------------------------------------------------------------------------- height / pitch / roll


@pytest.mark.parametrize("pitch", [5.0, 30.0, 45.0, 60.0, 89.0, 90.0, 120.0])
def test_height_pitch_equals_normal_distance(tmp_path, pitch):
    p = math.radians(pitch)
    region = [0, 400, 688, 544]
    a = load(tmp_path, _hp(height=2.25, pitch_deg=pitch, region=region))
    d = cfg_with(ground__normal=[0.0, math.cos(p), math.sin(p)], ground__distance=2.25,
                 ground__region=region)
    b = load(tmp_path, d)
    np.testing.assert_allclose(a.plane.normal, b.plane.normal, atol=1e-15)
    assert a.plane.distance == b.plane.distance == 2.25
    assert a.region == b.region
    np.testing.assert_allclose(a.plane.normal, [0.0, math.cos(p), math.sin(p)], atol=1e-15)


@pytest.mark.parametrize("pitch, roll", [(45.0, 10.0), (30.0, -20.0), (70.0, 45.0), (60.0, 0.0)])
def test_roll_convention(tmp_path, pitch, roll):
    cfg = load(tmp_path, _hp(pitch_deg=pitch, roll_deg=roll, region=[0, 400, 688, 544]))
    n = cfg.plane.normal
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    p, r = math.radians(pitch), math.radians(roll)
    # Documented: n = Rz(r)^T (0, cos p, sin p) = (sin r cos p, cos r cos p, sin p).
    c, s = math.cos(r), math.sin(r)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(n, Rz.T @ [0, math.cos(p), math.sin(p)], atol=1e-12)
    np.testing.assert_allclose(n, normal_from_pitch_roll(pitch, roll), atol=1e-15)
    assert n[2] == pytest.approx(math.sin(p))  # roll about the optical axis keeps the tilt
    # Horizon (n . ray = 0) in the image: positive roll -> it rises to the right (v decreases).
    fx = fy = 600.0
    cx, cy = 343.5, 271.5

    def horizon_v(u):
        x = (u - cx) / fx
        y = -(n[2] + n[0] * x) / n[1]
        return cy + fy * y

    slope = (horizon_v(600.0) - horizon_v(100.0)) / 500.0
    assert slope == pytest.approx(-math.tan(r), abs=1e-9)


def test_pitch_90_looks_straight_down(tmp_path):
    cfg = load(tmp_path, _hp(pitch_deg=90, roll_deg=30))
    np.testing.assert_allclose(cfg.plane.normal, [0, 0, 1], atol=1e-15)
    assert cfg.region == (0, 0, 688, 544)


def test_from_height_pitch_helper():
    g = Plane.from_height_pitch(1.2, 30.0)
    assert g.distance == 1.2
    np.testing.assert_allclose(g.normal, [0, math.cos(math.radians(30)), 0.5], atol=1e-15)


# ----------------------------------------------------------------------------- dump_init


def test_dump_load_round_trip(tmp_path):
    n = np.array([0.1, 0.6, 0.79])
    n /= np.linalg.norm(n)
    cam = PinholeCamera(640, 480, 512.3456789, 510.0000001, 319.5, 239.25,
                        (-0.21, 0.0345, 1e-20, -3.5e-4, 0.0))
    plane = Plane(n, 1.2345678901234567)
    out = tmp_path / "sub_init.yaml"
    dump_init(out, cam, plane, (0, 200, 640, 480))
    cfg = load_init(out)
    assert cfg.camera == cam
    assert cfg.plane == plane and cfg.region == (0, 200, 640, 480)
    assert cfg.path == out
    assert [p.name for p in tmp_path.iterdir()] == ["sub_init.yaml"]  # no temp files left
    # Written as plain YAML in the documented format (docs/guide.md).
    raw = yaml.safe_load(out.read_text())
    assert set(raw) == {"camera", "ground"}
    assert raw["camera"]["distortion"][2] == 1e-20  # a YAML float, not a string


def test_dump_without_region_loads_whole_frame(tmp_path):
    g = Plane.from_height_pitch(1.0, 90.0)
    cam = PinholeCamera(64, 48, 50.0, 50.0, 31.5, 23.5)
    dump_init(tmp_path / "init.yaml", cam, g)
    cfg = load_init(tmp_path / "init.yaml")
    assert cfg.region == (0, 0, 64, 48)
    assert cfg.plane == g


@pytest.mark.parametrize("cam, ground, msg", [
    (PinholeCamera(64, 48, -50.0, 50.0, 31.5, 23.5), Plane((0.0, 0.0, 1.0), 1.0), r"fx must be > 0"),
    (PinholeCamera(64, 48, 50.0, 50.0, 31.5, 23.5), Plane((0.0, 0.0, 1.0), float("nan")), "non-finite"),
    (PinholeCamera(64, 48, 50.0, 50.0, 31.5, 23.5), Plane((0.0, 0.0, -1.0), 1.0), "not in front"),
])
def test_dump_refuses_invalid(tmp_path, cam, ground, msg):
    out = tmp_path / "init.yaml"
    with pytest.raises(ConfigError, match=msg):
        dump_init(out, cam, ground)
    assert not out.exists()


# ----------------------------------------------------------------------------- camera_info


CAMERA_INFO = """\
image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [500.5, 0, 320.25, 0, 501.5, 240.75, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.1, 0.01, 0.001, -0.002, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [500.5, 0, 320.25, 0, 0, 501.5, 240.75, 0, 0, 0, 1, 0]
"""

GROUND_HP = {"height": 1.0, "pitch_deg": 40.0, "region": [0, 240, 640, 480]}


def test_camera_file_relative_to_init(tmp_path):
    (tmp_path / "calib").mkdir()
    (tmp_path / "calib" / "cam.yaml").write_text(CAMERA_INFO)
    cfg = load(tmp_path, {"camera_file": "calib/cam.yaml", "ground": GROUND_HP})
    cam = cfg.camera
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (640, 480, 500.5, 501.5, 320.25, 240.75)
    assert cam.distortion == (-0.1, 0.01, 0.001, -0.002, 0.0)


def test_camera_file_absolute_and_no_distortion(tmp_path):
    info = tmp_path / "elsewhere.yaml"
    info.write_text(CAMERA_INFO.split("distortion_model")[0])
    sub = tmp_path / "seq"
    sub.mkdir()
    cfg = load_init(write_yaml(sub, {"camera_file": str(info), "ground": GROUND_HP}))
    assert cfg.camera.distortion == (0.0,) * 5


def test_camera_file_missing_names_that_file(tmp_path):
    with pytest.raises(ConfigError, match=r"cam\.yaml: cannot read the camera_file named in .*init\.yaml"):
        load(tmp_path, {"camera_file": "cam.yaml", "ground": GROUND_HP})


@pytest.mark.parametrize("text, msg", [
    ("just text\n", "not a camera_info file"),
    ("image_width: 640\nimage_height: 480\n", r"not a camera_info file: camera_matrix is missing"),
    (CAMERA_INFO.replace("plumb_bob", "equidistant"), r"distortion_model 'equidistant' is not supported"),
    (CAMERA_INFO.replace("[500.5, 0, 320.25", "[500.5, 3, 320.25"), "skew"),
    (CAMERA_INFO.replace("data: [500.5, 0, 320.25, 0, 501.5, 240.75, 0, 0, 1]", "data: [1, 2]"),
     r"camera_matrix\.data must be 9 numbers"),
    (CAMERA_INFO.replace("image_width: 640", "image_width: -640"), r"image_width must be a whole number"),
    (CAMERA_INFO.replace("[-0.1, 0.01, 0.001, -0.002, 0.0]", "[1, 2]"),
     r"distortion_coefficients\.data must be a list of 4, 5 or 8"),
    ("image_width: [\n", "not valid YAML at line"),
])
def test_camera_file_not_camera_info(tmp_path, text, msg):
    (tmp_path / "cam.yaml").write_text(text)
    with pytest.raises(ConfigError, match=msg) as ei:
        load(tmp_path, {"camera_file": "cam.yaml", "ground": GROUND_HP})
    assert str(ei.value).startswith(str(tmp_path / "cam.yaml") + ": ")


def test_camera_file_must_be_a_name(tmp_path):
    with pytest.raises(ConfigError, match="camera_file must be a file name"):
        load(tmp_path, {"camera_file": 3, "ground": GROUND_HP})


# ----------------------------------------------------------------------------- frame size


def test_check_frame_size(tmp_path):
    cfg = load(tmp_path, BASE)
    check_frame_size(cfg, 688, 544, Path("frames/frame_000000.png"))
    with pytest.raises(ConfigError) as ei:
        check_frame_size(cfg, 512, 512, Path("frames/frame_000000.png"))
    assert str(ei.value) == (f"{cfg.path}: camera is 688x544 but frames are 512x512 "
                             "(frames/frame_000000.png); use the init.yaml of the camera that "
                             "took them")


# ----------------------------------------------------------------------------- properties


def _assert_valid(cfg: InitConfig) -> None:
    cam, g = cfg.camera, cfg.plane
    assert isinstance(cam.width, int) and 0 < cam.width and 0 < cam.height
    assert cam.fx > 0 and cam.fy > 0 and math.isfinite(cam.cx) and math.isfinite(cam.cy)
    assert len(cam.distortion) == 5 and all(math.isfinite(c) for c in cam.distortion)
    n = g.normal
    assert abs(np.linalg.norm(n) - 1.0) < 1e-9
    assert g.distance > 0 and math.isfinite(g.distance)
    x0, y0, x1, y1 = cfg.region
    assert 0 <= x0 < x1 <= cam.width and 0 <= y0 < y1 <= cam.height
    # The normal may point level or up (a road seen by a level camera): what must hold is that
    # every ray of the region meets the plane in front of the camera, at a finite depth.
    corners = np.array([[x0, y0], [x1 - 1, y0], [x0, y1 - 1], [x1 - 1, y1 - 1]], float)
    dots = cam.rays(corners) @ n
    assert np.all(dots > 0) and np.all(g.distance / dots < np.inf)


_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6), st.integers(),
    st.floats(allow_nan=True, allow_infinity=True), st.floats(-2000, 2000),
    st.text(max_size=12), st.sampled_from(["1e3", "abc", ".nan", "-0", "688", "", "1.5e-3"]),
)
_values = st.recursive(
    _scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=9),
                            st.dictionaries(st.one_of(st.text(max_size=10), st.integers()), inner,
                                            max_size=5)),
    max_leaves=20,
)
_KEYS = ["camera", "camera_file", "ground", "width", "height", "fx", "fy", "cx", "cy",
         "distortion", "normal", "distance", "pitch_deg", "roll_deg", "region"]


@st.composite
def _mutated_config(draw):
    """A valid config (either ground form) with a few random edits, at any level."""
    d = copy.deepcopy(BASE)
    if draw(st.booleans()):
        d["ground"] = {"height": 1.5, "pitch_deg": 45.0, "roll_deg": 5.0}
    for _ in range(draw(st.integers(1, 3))):
        target = draw(st.sampled_from([d, d.get("camera"), d.get("ground")]))
        if not isinstance(target, dict):
            continue
        key = draw(st.one_of(st.sampled_from(_KEYS), st.sampled_from(sorted(target, key=str) or ["x"])))
        action = draw(st.sampled_from(["set", "delete", "scalar", "number", "number"]))
        if action == "number" and target is not d:
            key = draw(st.sampled_from(sorted(target, key=str) or ["x"]))
            target[key] = draw(st.one_of(st.integers(-10, 2000), st.floats(-90, 2000)))
        elif action == "delete":
            target.pop(key, None)
        elif action == "scalar":
            target[key] = draw(_scalars)
        else:
            target[key] = draw(_values)
    return d


def _load_accepted_or_rejected(p) -> None:
    """load_init either gives a valid config or one MonovoError line, nothing else."""
    try:
        cfg = load_init(p)
    except MonovoError as exc:
        assert "\n" not in str(exc)
        event("rejected")
        return
    event("accepted")
    _assert_valid(cfg)


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.one_of(_mutated_config(), _values))
# A level camera (normal (0, 1, 0)) over the lower half of the image: accepted, and valid.
@example(data={**BASE, "ground": {"normal": [0, 1, 0], "distance": 1.5, "region": [0, 272, 688, 544]}})
def test_property_load_init_structured(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("prop") / "init.yaml"
    try:
        p.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False))
    except yaml.YAMLError:
        return
    _load_accepted_or_rejected(p)


@settings(max_examples=250, deadline=None)
@given(text=st.one_of(
    st.text(max_size=200),
    st.lists(st.sampled_from(SPEC_EXAMPLE.splitlines(keepends=True) + [
        "  pitch_deg: 30\n", "  height: 2\n", "camera_file: x.yaml\n", "  - 1\n", "&a [*a]\n",
        "  region: [0, 0, 10, 10]\n", "  fx: !!binary abc\n", "? [1]\n: 2\n", "<<: {a: 1}\n",
        "ground: !!python/object:os.system {}\n", "\t", "\x00", "{", "'", "- ", ": ",
    ]), max_size=25).map("".join),
))
def test_property_load_init_raw_text(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("raw") / "init.yaml"
    p.write_bytes(text.encode("utf-8", "surrogatepass"))
    _load_accepted_or_rejected(p)
