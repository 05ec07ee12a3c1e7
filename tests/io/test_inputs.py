"""Issue 15's acceptance: one synthetic drive as PDS3 and PDS4 products, a lossless video, ROS 1
and ROS 2 bags tracks to the PNG directory's motion.csv byte for byte; an H.264 mp4 of it ends
within 1 % of its path. Every file is written here (tests/helpers/product_writers.py)."""

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.errors import InputError
from monovo_cli.io.formats import read_trajectory_csv
from monovo_cli.io.sources import RosBag, VideoFile, open_frames, resolve_sequence
from monovo_cli.synth.write import synthesize
from tests.helpers.product_writers import (
    MASK_12,
    twelve_bit,
    utc,
    write_bag,
    write_pds3,
    write_pds4,
    write_video,
)

N_FRAMES = 8
FPS = 10.0
T0 = 1074162030.25  # a label time: 2004-01-15T10:20:30.25 UTC
STAMP0_NS = 1_700_000_000_123_000_000


def _track(seq: Path, out: Path, *extra: str) -> Path:
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", *extra])
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The synthetic drive (8 frames, 128 x 128), its PNG frames as arrays and the reference
    outputs of tracking the PNG directory."""
    root = tmp_path_factory.mktemp("inputs")
    synthesize(root / "png", preset="drive", frames=N_FRAMES, size=(128, 128), seed=7)
    frames = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
              for p in sorted((root / "png" / "frames").glob("*.png"))]
    assert len(frames) == N_FRAMES and frames[0].dtype == np.uint8 and frames[0].ndim == 2
    ref = _track(root / "png", root / "ref")
    return root, frames, ref


def _folder(root: Path, parent: Path, name: str) -> Path:
    """A sequence folder ``parent/name`` with the drive's init.yaml (the drive is in ``root``)."""
    seq = parent / name
    seq.mkdir()
    (seq / "init.yaml").write_bytes((root / "png" / "init.yaml").read_bytes())
    return seq


def _same_motion(out: Path, ref: Path) -> None:
    assert (out / "motion.csv").read_bytes() == (ref / "motion.csv").read_bytes()


def _timestamps(out: Path) -> np.ndarray:
    return read_trajectory_csv(out / "trajectory.csv")[1]


def _length(out: Path) -> float:
    _, _, poses = read_trajectory_csv(out / "trajectory.csv")
    return float(np.sum(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)))


# --------------------------------------------------------------------------- PDS


def test_pds3_attached_labels_track_identically_with_label_times(drive, tmp_path):
    pytest.importorskip("pdr")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "pds3")
    (seq / "frames").mkdir()
    for k, img in enumerate(frames):
        write_pds3(seq / "frames" / f"NLA_{k:04d}EDN.IMG", img, start_time=utc(T0 + 2.5 * k))
    out = _track(seq, tmp_path / "out")
    _same_motion(out, ref)
    np.testing.assert_allclose(_timestamps(out), T0 + 2.5 * np.arange(N_FRAMES), atol=1e-6)


def test_pds3_12_bit_detached_labels_track_identically(drive, tmp_path):
    pytest.importorskip("pdr")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "pds3_12")
    (seq / "frames").mkdir()
    for k, img in enumerate(frames):
        write_pds3(seq / "frames" / f"f{k}.IMG", twelve_bit(img), bit_mask=MASK_12, detached=True)
    assert [p.suffix for p in open_frames(seq).paths] == [".LBL"] * N_FRAMES
    out = _track(seq, tmp_path / "out")
    _same_motion(out, ref)  # 12-bit samples / 16 are the 8-bit frames exactly
    np.testing.assert_array_equal(_timestamps(out), np.arange(N_FRAMES))


def test_pds4_products_track_identically(drive, tmp_path):
    pytest.importorskip("pdr")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "pds4")
    (seq / "frames").mkdir()
    for k, img in enumerate(frames):
        write_pds4(seq / "frames" / f"n{k}.xml", img, start_time=utc(T0 + k) + "Z")
    out = _track(seq, tmp_path / "out")
    _same_motion(out, ref)
    np.testing.assert_allclose(_timestamps(out), T0 + np.arange(N_FRAMES), atol=1e-6)


# --------------------------------------------------------------------------- video


def test_lossless_video_tracks_identically_with_its_frame_times(drive, tmp_path):
    root, frames, ref = drive
    video = write_video(tmp_path / "drive.mkv", frames, fps=FPS)
    out = _track(video, tmp_path / "out", "-p", str(root / "png" / "init.yaml"))
    _same_motion(out, ref)
    np.testing.assert_allclose(_timestamps(out), np.arange(N_FRAMES) / FPS, atol=1e-9)


def test_h264_video_ends_within_1_percent_of_the_path(drive, tmp_path):
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "h264")
    write_video(seq / "drive.mp4", frames, fps=FPS, codec="libx264", quality=8)
    assert resolve_sequence(seq) == seq / "drive.mp4"  # the one video beside init.yaml
    out = _track(seq, tmp_path / "out")
    length = _length(ref)
    assert length > 0.1
    _, _, est = read_trajectory_csv(out / "trajectory.csv")
    _, _, want = read_trajectory_csv(ref / "trajectory.csv")
    assert np.linalg.norm(est[-1, :3, 3] - want[-1, :3, 3]) < 0.01 * length
    assert _length(out) == pytest.approx(length, rel=0.01)


def test_video_frames_in_any_order(drive, tmp_path):
    _, frames, _ = drive
    seq = open_frames(write_video(tmp_path / "d.mkv", frames, fps=FPS))
    assert isinstance(seq, VideoFile) and (len(seq), seq.width, seq.height) == (N_FRAMES, 128, 128)
    for k in (5, 2, 7, 0, 1):  # backwards means decoding from the start again
        fr = seq.read(k)
        np.testing.assert_array_equal(fr.image, frames[k])
        assert fr.path == Path(f"{tmp_path / 'd.mkv'}[{k}]")
    seq.close()


def test_a_file_ffmpeg_cannot_read_is_one_line(tmp_path):
    bad = tmp_path / "drive.mp4"
    bad.write_bytes(b"not a video at all" * 50)
    with pytest.raises(InputError, match=r"drive\.mp4: not a video ffmpeg can read \(.+\)"):
        open_frames(bad)


# --------------------------------------------------------------------------- ROS bags


def _stamps():
    return [STAMP0_NS + k * 100_000_000 for k in range(N_FRAMES)]


def test_ros2_bag_tracks_identically_with_header_stamps(drive, tmp_path):
    pytest.importorskip("rosbags")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "ros2")
    write_bag(seq / "run", frames, _stamps(), ros=2)
    out = _track(seq / "run", tmp_path / "out", "--topic", "/navcam/image_raw")
    _same_motion(out, ref)
    np.testing.assert_allclose(_timestamps(out), np.array(_stamps()) * 1e-9, rtol=0, atol=1e-6)


def test_ros1_bag_of_compressed_images_tracks_identically(drive, tmp_path):
    pytest.importorskip("rosbags")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "ros1")
    write_bag(seq / "run.bag", frames, _stamps(), ros=1, compressed=True)
    out = _track(seq, tmp_path / "out")  # the folder's one bag, its one image topic
    _same_motion(out, ref)


def test_bag_topics_must_be_named_when_several(drive, tmp_path):
    pytest.importorskip("rosbags")
    root, frames, ref = drive
    seq = _folder(root, tmp_path, "two")
    bag = write_bag(seq / "run", frames, _stamps(), ros=2,
                    extra_topics={"/hazcam/image_raw": frames[::-1]})
    r = CliRunner().invoke(main, ["track", str(bag), "-o", str(tmp_path / "o1")])
    assert r.exit_code == 2
    assert "2 image topics (/hazcam/image_raw, /navcam/image_raw); name one with --topic" in r.output
    r = CliRunner().invoke(main, ["track", str(bag), "-o", str(tmp_path / "o2"), "--topic", "/x"])
    assert r.exit_code == 2 and "no topic '/x' (image topics: /hazcam/image_raw" in r.output
    _same_motion(_track(bag, tmp_path / "o3", "--topic", "/navcam/image_raw"), ref)


def test_bag_16_bit_big_endian_and_record_times(tmp_path):
    pytest.importorskip("rosbags")
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 65536, (6, 9), dtype=np.uint16) for _ in range(3)]
    bag_ns = [5_000_000_000 + k * 50_000_000 for k in range(3)]
    write_bag(tmp_path / "b", frames, [0, 0, 0], ros=2, encoding="mono16", bigendian=True,
              bag_ns=bag_ns)
    seq = open_frames(tmp_path / "b")
    assert isinstance(seq, RosBag) and seq.stamp_source == "bag"  # headers unset
    np.testing.assert_allclose(seq.timestamps, np.array(bag_ns) * 1e-9)
    for k in (2, 0, 1):
        np.testing.assert_allclose(seq.read(k).image, frames[k] * (255.0 / 65535.0), rtol=1e-6)
    seq.close()  # reading again reopens the bag
    np.testing.assert_allclose(seq.read(2).image, frames[2] * (255.0 / 65535.0), rtol=1e-6)


def test_missing_rosbags_says_how_to_install(tmp_path, monkeypatch):
    bag = tmp_path / "run.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(InputError, match=r"needs the 'rosbags' package: pip install 'monovo\[ros\]'"):
        open_frames(bag)


# --------------------------------------------------------------------------- batch


def test_batch_finds_videos_bags_and_products(drive, tmp_path):
    pytest.importorskip("rosbags")
    pytest.importorskip("pdr")
    root, frames, ref = drive
    archive = tmp_path / "archive"
    archive.mkdir()
    (archive / "png").symlink_to(root / "png", target_is_directory=True)
    pds = _folder(root, archive, "pds")
    (pds / "frames").mkdir()
    for k, img in enumerate(frames):
        write_pds3(pds / "frames" / f"f{k}.IMG", img)
    videos = _folder(root, archive, "videos")
    write_video(videos / "drive.mkv", frames, fps=FPS)
    write_video(videos / "again.mkv", frames, fps=FPS)
    (videos / "notes.txt").write_text("not a sequence")
    bags = _folder(root, archive, "bags")
    write_bag(bags / "run2", frames, _stamps(), ros=2)
    write_bag(bags / "run1.bag", frames, _stamps(), ros=1)
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(tmp_path / "results"), "-q",
                                  "--workers", "1"])
    assert r.exit_code == 0, r.output
    names = ["bags/run1.bag", "bags/run2", "pds", "png", "videos/again.mkv", "videos/drive.mkv"]
    summary = (tmp_path / "results" / "summary.csv").read_text().splitlines()
    assert [line.split(",")[0] for line in summary[1:]] == names
    assert all(",ok," in line for line in summary[1:])
    for name in names:
        _same_motion(tmp_path / "results" / name, ref)
