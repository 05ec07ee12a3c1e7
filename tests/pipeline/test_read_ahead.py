"""Frames decoded ahead on a thread of their own give the same outputs, and a frame that
cannot be read is reported at its place."""

from __future__ import annotations

import shutil

import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.errors import InputError
from monovo_cli.io.sources import open_frames
from monovo_cli.pipeline.read_ahead import read_frames


def test_the_reader_thread_hands_over_the_same_frames_in_order(small_drive):
    frames = open_frames(small_drive / "frames")
    one = [(i, f.image.tobytes(), e) for i, f, e in read_frames(frames, 1, threads=1)]
    two = [(i, f.image.tobytes(), e) for i, f, e in read_frames(frames, 1, threads=3)]
    assert [i for i, _, _ in one] == list(range(1, len(frames))) and one == two


def test_an_unreadable_frame_comes_at_its_place_and_closing_stops_the_reader(tmp_path, small_drive):
    seq = tmp_path / "seq"
    shutil.copytree(small_drive, seq)
    bad = sorted((seq / "frames").glob("*.png"))[4]
    bad.write_bytes(b"not a png")
    frames = open_frames(seq / "frames")
    got = list(read_frames(frames, 1, threads=2))
    assert [i for i, _, _ in got] == list(range(1, len(frames)))
    assert isinstance(got[3][2], InputError) and got[3][1] is None
    it = read_frames(frames, 1, threads=2)
    next(it)
    it.close()  # (the reader thread is joined: the test would hang otherwise)


@pytest.mark.parametrize("threads", ["2", "3"])
def test_track_writes_the_same_bytes_with_and_without_the_reader(tmp_path, small_drive, threads):
    outs = {}
    for n in ("1", threads):
        out = tmp_path / f"out{n}"
        r = CliRunner().invoke(main, ["track", str(small_drive), "-o", str(out), "-q",
                                      "--threads", n])
        assert r.exit_code == 0, r.output
        outs[n] = {p.name: p.read_bytes() for p in out.iterdir()
                   if p.name in ("motion.csv", "trajectory.csv", "trajectory.tum")}
    assert len(outs["1"]) == 3 and outs["1"] == outs[threads]
