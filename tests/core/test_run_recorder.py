"""The run recorder's column blocks and the streamed checkpoint: what goes in comes out."""

from __future__ import annotations

import zipfile
from types import SimpleNamespace

import numpy as np

from monovo_cli.core.run import _BLOCK, RunRecorder
from monovo_cli.core.status import FrameStatus
from monovo_cli.io.atomic import digests_recorded
from monovo_cli.io.checkpoint import Checkpoint, read_checkpoint, write_checkpoint


def frame(k: int, rng: np.random.Generator) -> SimpleNamespace:
    """A FrameResult's fields with random numbers; every 7th frame lost, every 50th closing a gap."""
    pose = np.eye(4)
    pose[:3, 3] = rng.normal(size=3)
    lost = k % 7 == 3
    cov = np.full((6, 6), np.nan) if lost else np.diag(rng.uniform(1e-6, 1e-4, 6))
    return SimpleNamespace(index=k, timestamp=0.1 * k + 1e-9 * k * k, world_from_cam=pose,
                           prev_from_cur=np.linalg.inv(pose), msd=float(rng.uniform(5, 50)),
                           iterations=int(rng.integers(0, 30)), points=int(rng.integers(0, 10**6)),
                           status=FrameStatus.LOST if lost else FrameStatus.OK,
                           std=np.sqrt(np.diag(cov)), covariance=cov,
                           reason="duplicate of the previous frame" if lost else "",
                           gap=("closure", k) if k % 50 == 49 else None)


def test_recorder_returns_every_frame_across_blocks():
    rng = np.random.default_rng(3)
    frames = [frame(k, rng) for k in range(2 * _BLOCK + 37)]
    rec = RunRecorder()
    for f in frames:
        rec.add(f)
    run = rec.result()
    assert len(rec) == run.frames == len(frames)
    assert rec.index == list(range(len(frames)))
    assert rec.timestamp == [f.timestamp for f in frames]
    for name in ("world_from_cam", "prev_from_cur", "msd", "iterations", "points", "std",
                 "covariance"):
        np.testing.assert_array_equal(getattr(run, name),
                                      np.array([getattr(f, name) for f in frames]), err_msg=name)
    assert run.status == tuple(f.status for f in frames)
    assert run.reason == tuple(f.reason for f in frames)
    assert run.gaps == tuple((f.index, f.gap) for f in frames if f.gap is not None)
    assert rec.last_status is frames[-1].status
    assert RunRecorder().result().world_from_cam.shape == (0, 4, 4)


def test_checkpoint_keeps_the_recorder_in_blocks_of_arrays(tmp_path):
    rng = np.random.default_rng(4)
    rec = RunRecorder()
    for k in range(_BLOCK + 5):
        rec.add(frame(k, rng))
    cp = Checkpoint(next_frame=len(rec), fingerprint={"seq": "x"}, state=rec, motion_bytes=123)
    with digests_recorded() as digests:
        write_checkpoint(tmp_path, cp)
    assert digests == {}  # (no record lists the checkpoint: its bytes are not hashed)
    with zipfile.ZipFile(tmp_path / ".track-checkpoint.npz") as z:
        assert {i.compress_type for i in z.infolist()} == {zipfile.ZIP_STORED}
        assert len(z.infolist()) == 2 * 9 + 1  # two blocks of the columns, and the record
    back = read_checkpoint(tmp_path)
    assert back.next_frame == len(rec) and back.motion_bytes == 123
    for name in ("world_from_cam", "covariance", "std", "msd", "points"):
        np.testing.assert_array_equal(getattr(back.state.result(), name),
                                      getattr(rec.result(), name), err_msg=name)
    assert back.state.index == rec.index and back.state.result().status == rec.result().status
    assert back.state.gaps == rec.gaps
