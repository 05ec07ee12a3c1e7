"""PDS3 / PDS4 products as frames (io/pds.py through pdr) and the camera models in their labels."""

import sys

import numpy as np
import pytest
import yaml

from monovo_cli.errors import ConfigError, InputError
from monovo_cli.io.config import load_init
from monovo_cli.io.pds import parse_time, read_product
from monovo_cli.io.pds_camera import read_camera_model
from monovo_cli.io.sources import PdsFolder, open_frames
from tests.helpers.product_writers import MASK_12, twelve_bit, utc, write_pds3, write_pds4

pytest.importorskip("pdr")

T0 = 1074162030.25  # 2004-01-15T10:20:30.25 UTC, Spirit's sol 11


def _frame(seed=0, shape=(24, 32)):
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


CAHVOR = {"model": "cahvor", "C": [0.45, -0.3, -1.5], "A": [0.0, 0.0, 1.0],
          "H": [1222.5, 0.0, 511.5], "V": [0.0, 1222.5, 511.5], "O": [0.0, 0.0, 1.0],
          "R": [1e-4, -0.012, 0.006]}


def test_pds3_attached_label_8_bit(tmp_path):
    img = _frame()
    write_pds3(tmp_path / "a.IMG", img, start_time=utc(T0))
    fr = read_product(tmp_path / "a.IMG")
    assert fr.bits == 8 and fr.image.dtype == np.float32
    np.testing.assert_array_equal(fr.image, img)
    assert fr.timestamp == pytest.approx(T0, abs=1e-6)


def test_pds3_12_bit_samples_are_divided_by_16(tmp_path):
    img = _frame(1)
    write_pds3(tmp_path / "a.IMG", twelve_bit(img) + 7, bit_mask=MASK_12)  # + 7: below 8 bits
    fr = read_product(tmp_path / "a.IMG")
    assert fr.bits == 12
    np.testing.assert_allclose(fr.image, img + 7 / 16, atol=1e-5)
    assert fr.image.max() <= 4095 / 16


def test_pds3_bits_outside_the_mask_are_dropped(tmp_path):
    img = twelve_bit(_frame(2)) | np.uint16(0xF000)  # garbage in the 4 unused bits
    write_pds3(tmp_path / "a.IMG", img, bit_mask=MASK_12)
    np.testing.assert_array_equal(read_product(tmp_path / "a.IMG").image, (img & 0x0FFF) / 16)


def test_pds3_16_bit_without_mask_uses_all_16_bits(tmp_path):
    img = (_frame(3).astype(np.uint16) * 257)
    write_pds3(tmp_path / "a.IMG", img)
    fr = read_product(tmp_path / "a.IMG")
    assert fr.bits == 16
    np.testing.assert_allclose(fr.image, img / 256.0, atol=1e-4)


def test_pds3_detached_label_is_one_product(tmp_path):
    img = _frame(4)
    lbl = write_pds3(tmp_path / "b.IMG", img, detached=True, start_time="2004-015T10:20:31.25Z")
    assert lbl.name == "b.LBL"
    write_pds3(tmp_path / "a.IMG", _frame(5), start_time=utc(T0))
    seq = open_frames(tmp_path)
    assert isinstance(seq, PdsFolder)
    assert [p.name for p in seq.paths] == ["a.IMG", "b.LBL"]
    np.testing.assert_array_equal(seq.read(1).image, img)
    np.testing.assert_allclose(seq.timestamps, [T0, T0 + 1.0], atol=1e-6)


def test_pds4_label_and_data_file(tmp_path):
    img = _frame(6)
    write_pds4(tmp_path / "n1.xml", twelve_bit(img), bits=12, start_time="2021-02-22T21:38:15.433Z",
               data_name="N1_RAW.IMG")
    (tmp_path / "collection.xml").write_text("<Product_Collection/>")  # not an observation
    seq = open_frames(tmp_path)
    assert [p.name for p in seq.paths] == ["n1.xml"]  # its data file is not a second product
    fr = read_product(tmp_path / "n1.xml")
    # the Commanded_Parameters' 16 bits are what was asked for, the 12 what came
    assert fr.bits == 12
    np.testing.assert_array_equal(fr.image, img)
    assert fr.timestamp == pytest.approx(parse_time("2021-02-22T21:38:15.433Z"))


@pytest.mark.parametrize("text, seconds", [
    ("2004-01-15T10:20:30.250", T0),
    ("2004-015T10:20:30.25Z", T0),
    ('"2004-01-15T10:20:30.250Z"', T0),
    ("2004-01-15", T0 - 37230.25),
    ("1970-01-01T00:00:00", 0.0),
    ("N/A", None), ("UNK", None), ("2004-13-01T00:00:00", None), ("2004-367T00:00:00", None),
    ("yesterday", None), (None, None),
])
def test_parse_time(text, seconds):
    got = parse_time(text)
    if seconds is None:
        assert got is None
    else:
        assert got == pytest.approx(seconds, abs=1e-6)


def test_label_times_must_increase_or_times_txt_overrides(tmp_path):
    for k, t in enumerate([T0, T0 + 2.0, T0 + 1.0]):
        write_pds3(tmp_path / f"f{k}.IMG", _frame(k), start_time=utc(t))
    with pytest.raises(InputError, match=r"f2\.IMG: label time .* does not follow f1\.IMG's .*; "
                                         r"give the timestamps in times\.txt"):
        open_frames(tmp_path)
    (tmp_path / "times.txt").write_text("0.0\n0.5\n1.0\n")
    np.testing.assert_array_equal(open_frames(tmp_path).timestamps, [0.0, 0.5, 1.0])


def test_some_labels_without_time(tmp_path):
    write_pds3(tmp_path / "f0.IMG", _frame(0), start_time=utc(T0))
    write_pds3(tmp_path / "f1.IMG", _frame(1))
    with pytest.raises(InputError, match=r"f1\.IMG: the label has no START_TIME"):
        open_frames(tmp_path)


def test_labels_without_time_count_frames(tmp_path):
    for k in range(3):
        write_pds3(tmp_path / f"f{k}.IMG", _frame(k))
    np.testing.assert_array_equal(open_frames(tmp_path).timestamps, [0.0, 1.0, 2.0])


def test_pds3_camera_model(tmp_path):
    write_pds3(tmp_path / "a.IMG", _frame(), camera=CAHVOR)
    cam = read_camera_model(tmp_path / "a.IMG")
    assert (cam.kind, cam.width, cam.height, cam.frame) == ("cahvor", 32, 24, "ROVER_NAV_FRAME")
    assert cam.vectors == {k: CAHVOR[k] for k in "CAHVOR"}
    assert cam.linearity == 1.0


@pytest.mark.parametrize("mtype, linearity, expected", [(1, 0.3, 1.0), (2, 0.3, 0.0), (3, 0.3, 0.3)])
def test_pds4_cahvore_model_type_sets_the_linearity(tmp_path, mtype, linearity, expected):
    camera = dict(CAHVOR, model="cahvore", E=[0.001, 0.0, 0.0], type=mtype, linearity=linearity)
    write_pds4(tmp_path / "a.xml", _frame(), camera=camera)
    cam = read_camera_model(tmp_path / "a.xml")
    assert cam.kind == "cahvore" and cam.linearity == expected
    assert cam.vectors["E"] == [0.001, 0.0, 0.0] and cam.vectors["H"] == CAHVOR["H"]


def test_camera_file_naming_a_product_gives_the_same_camera_as_init_yaml(tmp_path):
    img = _frame(0, (1024, 1024))
    write_pds3(tmp_path / "a.IMG", img, camera=CAHVOR)
    ground = {"normal": [0.0, 0.7071068, 0.7071068], "distance": 1.5}
    (tmp_path / "from_label.yaml").write_text(yaml.safe_dump({"camera_file": "a.IMG",
                                                              "ground": ground}))
    (tmp_path / "inline.yaml").write_text(yaml.safe_dump({
        "camera": dict(CAHVOR, width=1024, height=1024), "ground": ground}))
    a = load_init(tmp_path / "from_label.yaml").camera
    b = load_init(tmp_path / "inline.yaml").camera
    assert a == b and a.fx == pytest.approx(1222.5, rel=1e-3)


def test_camera_file_product_without_model(tmp_path):
    write_pds3(tmp_path / "a.IMG", _frame())
    (tmp_path / "init.yaml").write_text(yaml.safe_dump({
        "camera_file": "a.IMG", "ground": {"normal": [0, 0.6, 0.8], "distance": 1.0}}))
    with pytest.raises(ConfigError, match=r"a\.IMG: the label has no camera model .*\(camera_file "
                                          r"of .*init\.yaml\)"):
        load_init(tmp_path / "init.yaml")


def test_junk_product_is_one_line(tmp_path):
    (tmp_path / "bad.IMG").write_bytes(b"\x00\x01 not a PDS product" * 20)
    with pytest.raises(InputError, match=r"bad\.IMG: (no image in the PDS product|cannot read)"):
        read_product(tmp_path / "bad.IMG")


def test_missing_pdr_says_how_to_install(tmp_path, monkeypatch):
    write_pds3(tmp_path / "a.IMG", _frame())
    monkeypatch.setitem(sys.modules, "pdr", None)
    with pytest.raises(InputError, match=r"needs the 'pdr' package: pip install 'monovo\[pds\]'"):
        read_product(tmp_path / "a.IMG")
