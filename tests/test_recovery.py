"""Never lost for good (issue 13): recovery after unusable frames, reasons, exit status 3."""

import csv
import logging
import shutil

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.odometry import track
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.frames import FrameSequence
from monovo_cli.synth.write import synthesize


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    root = tmp_path_factory.mktemp("recovery") / "d"
    synthesize(root, preset="drive", frames=24, size=(160, 160), noise_var=10.0, seed=11)
    return root


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _noise_frames(seq, frames, seed=0):
    rng = np.random.default_rng(seed)
    for k in frames:
        path = sorted((seq / "frames").glob("*.png"))[k]
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        cv2.imwrite(str(path), rng.integers(0, 256, img.shape, dtype=np.uint8))


def test_noise_in_the_middle_is_lost_with_a_reason_and_tracking_resumes(drive, tmp_path):
    """Three frames of pure noise: lost (each with its reason), never re-initialised on noise;
    the frames after them are tracked again and the drive ends near the truth."""
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _noise_frames(seq, [9, 10, 11])
    cfg = load_init(seq / "init.yaml")
    fs = FrameSequence(seq / "frames")
    res = list(track(((f.index, f.timestamp, f.image) for f in fs), cfg.camera, cfg.plane,
                     cfg.region, TrackOptions()))
    for r in res[9:12]:
        assert r.status == FrameStatus.LOST and r.reason
    assert all(r.status != FrameStatus.LOST for r in res[12:])
    assert all(r.status != FrameStatus.REINIT for r in res)  # the drive's keyframe is recovered
    _, truth = read_tum(seq / "groundtruth.tum")
    err = np.linalg.norm(res[-1].world_from_cam[:3, 3] - truth[-1][:3, 3])
    path = np.sum(np.linalg.norm(np.diff([t[:3, 3] for t in truth], axis=0), axis=1))
    assert err < 0.05 * path  # the three predicted frames bridge the gap; the rest is tracked


def test_a_jump_is_bridged_by_a_fresh_keyframe(drive, tmp_path):
    """Frames 8..23 replaced by a part of the drive the keyframe never saw (frames shifted by
    a jump the predictor cannot follow) are not lost for more than ``reinit_after`` in a row."""
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    paths = sorted((seq / "frames").glob("*.png"))
    far = tmp_path / "far"
    synthesize(far, preset="drive", frames=24, size=(160, 160), noise_var=10.0, seed=12)
    for k, p in enumerate(paths[8:], start=8):
        shutil.copyfile(sorted((far / "frames").glob("*.png"))[k], p)
    cfg = load_init(seq / "init.yaml")
    res = list(track(((f.index, f.timestamp, f.image) for f in FrameSequence(seq / "frames")),
                     cfg.camera, cfg.plane, cfg.region, TrackOptions()))
    run = longest = 0
    for r in res:
        run = run + 1 if r.status == FrameStatus.LOST else 0
        longest = max(longest, run)
    assert longest <= TrackOptions().reinit_after
    assert res[-1].status in (FrameStatus.OK, FrameStatus.REANCHORED)
    reinit = [r for r in res if r.status == FrameStatus.REINIT]
    assert reinit and all("re-initialised after" in r.reason for r in reinit)


def test_noise_sequence_exits_3_every_frame_lost_with_a_reason(drive, tmp_path):
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _noise_frames(seq, range(1, 24))
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q"])
    assert r.exit_code == 3, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "23 of 23 frames lost" in lines[0] and str(out) in lines[0]
    rows = _rows(out / "motion.csv")
    assert list(rows[0])[-1] == "reason"
    assert len(rows) == 23 and all(x["status"] == "lost" and x["reason"] for x in rows)
    for name in ("trajectory.csv", "trajectory.tum"):
        assert (out / name).is_file()  # outputs kept


def test_batch_marks_a_mostly_lost_sequence_failed(drive, tmp_path):
    root = tmp_path / "archive"
    shutil.copytree(drive, root / "good")
    shutil.copytree(drive, root / "noise")
    _noise_frames(root / "noise", range(1, 24))
    r = CliRunner().invoke(main, ["batch", str(root), "-o", str(tmp_path / "o"), "-q",
                                  "--workers", "1"])
    rows = {x["sequence"]: x for x in _rows(tmp_path / "o" / "summary.csv")}
    assert rows["good"]["status"] == "ok"
    assert rows["noise"]["status"] == "failed" and "frames lost" in rows["noise"]["error"]
    assert r.exit_code != 0


def test_verbose_logs_each_lost_frame_with_its_reason(drive, tmp_path, caplog):
    seq = tmp_path / "seq"
    shutil.copytree(drive, seq)
    _noise_frames(seq, [5])
    with caplog.at_level(logging.INFO, logger="monovo_cli"):
        r = CliRunner().invoke(main, ["track", str(seq), "-o", str(tmp_path / "o"), "-v"])
    assert r.exit_code == 0, r.output
    assert any(m.startswith("frame 5 lost: ") for m in caplog.messages)
