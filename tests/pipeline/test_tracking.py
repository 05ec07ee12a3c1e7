"""The library entry point (monovo_cli.track_frames / iter_track): a sequence tracked from
Python in a few lines, against the sample drive's ground truth."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import monovo_cli
from monovo_cli.core.status import FrameStatus
from monovo_cli.evaluation.metrics import evaluate
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum
from monovo_cli.pipeline.track import track_sequence

SAMPLE = Path(__file__).resolve().parents[2] / "sample_sequences" / "navcam_drive"


@pytest.fixture(scope="module")
def run():
    return monovo_cli.track_frames(SAMPLE)


def test_five_lines_track_the_sample_drive(run):
    """docs/architecture.md's example: the run, its statuses and its trajectory."""
    assert run.frames == 60 and run.lost == 0
    assert run.status[0] == FrameStatus.OK and len(run.status) == 60
    ts, gt = read_tum(SAMPLE / "groundtruth.tum")
    ev = evaluate(run.timestamp, run.trajectory, ts, gt)
    assert ev.poses == 60
    assert ev.final_drift_pct < 0.5  # (0.04 % at the time of writing)
    assert run.path_length == pytest.approx(ev.distance_m, rel=0.01)
    assert run.std[1:].shape == (59, 6) and np.all(run.std[1:] > 0)


def test_iter_track_yields_the_frames_of_the_run(run):
    results = list(monovo_cli.iter_track(SAMPLE, load_init(SAMPLE / "init.yaml")))
    assert [r.index for r in results] == list(run.index)
    assert np.array_equal(np.array([r.world_from_cam for r in results]), run.world_from_cam)


def test_the_run_returned_is_the_run_written(run, tmp_path):
    """monovo track returns the TrackRun whose rows it wrote: same motions, statuses and
    trajectory as the library's."""
    written = track_sequence(SAMPLE, None, tmp_path / "out", monovo_cli.TrackOptions())
    idx, motions, stats = read_motion_csv(tmp_path / "out" / "motion.csv")
    assert list(idx) == list(written.index[1:])
    assert np.allclose(np.array(motions), written.prev_from_cur[1:], atol=1e-6)
    assert stats == [str(s) for s in written.status[1:]]
    assert np.array_equal(written.trajectory, run.trajectory)
    assert written.path_length == run.path_length


def test_import_stays_light():
    """``import monovo_cli`` loads neither numpy nor OpenCV; the entry points come on use."""
    code = ("import sys, monovo_cli; assert 'numpy' not in sys.modules and 'cv2' not in "
            "sys.modules; monovo_cli.track_frames; assert 'cv2' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_frame_0_is_decoded_once(tmp_path, monkeypatch):
    """track_sequence opens the sequence once: frame 0 carries the size check, the ground
    model and the first row, from one decode."""
    from monovo_cli.io.sources import ImageFolder

    calls = []
    decode = ImageFolder._decode
    monkeypatch.setattr(ImageFolder, "_decode", lambda self, i: (calls.append(i), decode(self, i))[1])
    track_sequence(SAMPLE, None, tmp_path / "out", monovo_cli.TrackOptions())
    assert calls.count(0) == 1 and sorted(calls) == list(range(60))
