"""Nothing lost on interruption: real subprocesses get SIGINT, SIGTERM and SIGKILL mid-run.

After Ctrl-C (exit 130) or SIGTERM (exit 143) motion.csv holds whole rows for the frames
done and trajectory.csv / .tum hold exactly those frames; after kill -9 every file under
a final name is whole (motion.csv is streamed row by row, the trajectory files are only
ever renamed into place), and a fresh rerun reproduces the uninterrupted outputs byte for
byte. Every file is compared with an uninterrupted reference run of the same sequence.

The runs that are compared by prefix use ``--no-smooth``: by default the trajectory files
hold the poses re-scaled in hindsight over the frames done (monovo_cli.mapping.smoothing), so
an interrupted run's earlier poses differ from the uninterrupted run's, which knew more; the
files are written by the same code either way. With the default, an interrupted run keeps
whole rows of exactly the frames done (:func:`test_signal_with_smoothing_keeps_whole_rows`).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from monovo_cli.cli import main

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

FRAMES = 300
RESULTS = ("motion.csv", "trajectory.csv", "trajectory.tum")
TIMEOUT = 120


@pytest.fixture(scope="module")
def drive(synth_drive, tmp_path_factory):
    """A 300-frame 128x128 drive (~2 s of tracking) and its uninterrupted outputs with
    ``--no-smooth`` (the poses as streamed)."""
    seq = synth_drive(preset="drive", frames=FRAMES, size=(128, 128), seed=4)
    ref = tmp_path_factory.mktemp("signals") / "ref"
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(ref), "-q", "--no-smooth"])
    assert r.exit_code == 0, r.output
    return seq, {name: (ref / name).read_text() for name in RESULTS}


def _default_sigint() -> None:
    # A child of a non-interactive shell's background job starts with SIGINT ignored, and
    # Python then installs no KeyboardInterrupt handler; give the child a normal terminal's.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)


def _monovo(*args: str) -> list[str]:
    return [sys.executable, "-m", "monovo_cli", *args]


def _rows(path: Path) -> int:
    try:
        with open(path, "rb") as f:
            return max(f.read().count(b"\n") - 1, 0)
    except FileNotFoundError:
        return 0


def _wait_for_rows(proc: subprocess.Popen, motion: Path, rows: int) -> None:
    """Poll until motion.csv holds ``rows`` rows; fail if the run ends first."""
    deadline = time.monotonic() + TIMEOUT
    while _rows(motion) < rows:
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"run ended (status {proc.returncode}) before {rows} rows: {err}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("timed out waiting for rows")
        time.sleep(0.005)


def _check_prefix(out: Path, reference: dict[str, str], *, exact: bool) -> int:
    """Every result file is a whole-line prefix of the reference's; returns the motion rows.

    ``exact``: trajectory.csv / .tum hold exactly the frames of motion.csv (frame 0 too).
    """
    motion = (out / "motion.csv").read_text()
    assert motion.endswith("\n"), "motion.csv ends in a partial row"
    assert reference["motion.csv"].startswith(motion)
    rows = motion.count("\n") - 1
    assert rows >= 0
    for name in ("trajectory.csv", "trajectory.tum"):
        path = out / name
        if not path.exists():
            assert not exact or rows == 0, f"{name} missing after {rows} rows"
            continue
        text = path.read_text()
        assert text.endswith("\n") and reference[name].startswith(text), f"{name} is not whole"
        frames = text.count("\n") - (name == "trajectory.csv")
        if exact:
            assert frames == rows + 1, f"{name}: {frames} frames for {rows} motion rows"
        else:
            assert frames <= rows + 1
    return rows


@pytest.mark.parametrize("signum, status, word", [
    (signal.SIGINT, 130, "interrupted"),
    (signal.SIGTERM, 143, "terminated"),
])
def test_signal_keeps_exactly_the_frames_done(drive, tmp_path, signum, status, word):
    seq, reference = drive
    out = tmp_path / "out"
    proc = _start(_monovo("track", str(seq), "-o", str(out), "-q", "--no-smooth"))
    _wait_for_rows(proc, out / "motion.csv", 5)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == status, err
    assert word in err and "Traceback" not in err
    rows = _check_prefix(out, reference, exact=True)
    assert 5 <= rows < FRAMES - 1, "the signal did not arrive mid-run"
    assert not list(out.glob(".*.tmp")), "temporary files left behind"


def test_signal_with_smoothing_keeps_whole_rows(drive, tmp_path):
    """Default options: after Ctrl-C the trajectory files hold one whole row per frame done
    (frames and timestamps as the reference's), motion.csv is the reference's prefix."""
    seq, reference = drive
    out = tmp_path / "out"
    proc = _start(_monovo("track", str(seq), "-o", str(out), "-q"))
    _wait_for_rows(proc, out / "motion.csv", 20)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 130, err
    motion = (out / "motion.csv").read_text()
    assert reference["motion.csv"].startswith(motion) and motion.endswith("\n")
    rows = motion.count("\n") - 1
    assert 20 <= rows < FRAMES - 1, "the signal did not arrive mid-run"
    for name, sep, skip in (("trajectory.csv", ",", 1), ("trajectory.tum", " ", 0)):
        got = [ln.split(sep) for ln in (out / name).read_text().splitlines()[skip:]]
        ref = [ln.split(sep) for ln in reference[name].splitlines()[skip:]]
        assert len(got) == rows + 1 and all(len(g) == len(ref[0]) for g in got), name
        key = 2 if skip else 1  # frame and timestamp / timestamp
        assert [g[:key] for g in got] == [r[:key] for r in ref[:rows + 1]], name
        assert all(float(v) == float(v) for g in got for v in g), f"{name}: not numbers"


def test_sigint_while_streaming_keeps_stdout_pure_csv(drive):
    seq, reference = drive
    proc = _start(_monovo("track", str(seq), "-o", "-", "-q"))
    first = proc.stdout.readline()  # the header: tracking has started
    for _ in range(5):
        first += proc.stdout.readline()
    proc.send_signal(signal.SIGINT)
    rest, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 130, err
    stdout = first + rest
    assert stdout.endswith("\n") and reference["motion.csv"].startswith(stdout)
    assert "interrupted" in err
    assert "on disk" not in err and "went to stdout; no file was written" in err, err


@pytest.mark.parametrize("seed", [1, 9])  # rows 36 and 120: before and after a checkpoint
def test_kill9_leaves_whole_files_and_a_rerun_reproduces(drive, tmp_path, seed):
    """kill -9 at a random frame: whole rows only; restarting from scratch gives the
    uninterrupted outputs byte for byte."""
    seq, reference = drive
    out = tmp_path / "out"
    target = random.Random(seed).randint(2, 150)  # past the 100-frame checkpoint sometimes
    proc = _start(_monovo("track", str(seq), "-o", str(out), "-q", "--no-smooth"))
    _wait_for_rows(proc, out / "motion.csv", target)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == -signal.SIGKILL
    rows = _check_prefix(out, reference, exact=False)
    assert rows >= target
    if rows >= 100:  # the 100-frame checkpoint was written
        assert (out / "trajectory.csv").read_text().count("\n") >= 101
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", "--no-smooth"])
    assert r.exit_code == 2 and "--overwrite" in r.output  # results are never clobbered
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", "--overwrite",
                                  "--no-smooth"])
    assert r.exit_code == 0, r.output
    for name in RESULTS:
        assert (out / name).read_text() == reference[name], name
    assert not list(out.glob(".*.tmp")), "temporary files of the killed run left behind"


_CHECKPOINT_EVERY_FRAME = """
import sys
from pathlib import Path
from monovo_cli.core.options import TrackOptions
from monovo_cli.pipeline.track import track_sequence
track_sequence(Path(sys.argv[1]), None, Path(sys.argv[2]), TrackOptions(), smooth=False,
               checkpoint_every=1)
"""


def test_kill9_during_trajectory_checkpoints_never_leaves_a_partial_file(drive, tmp_path):
    """With a checkpoint after every frame the kill lands in or near a rename; whatever
    carries a final name is a whole prefix of the reference."""
    seq, reference = drive
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        proc = _start([sys.executable, "-c", _CHECKPOINT_EVERY_FRAME, str(seq), str(out)])
        _wait_for_rows(proc, out / "motion.csv", 10 + 7 * attempt)
        time.sleep(random.Random(attempt).random() * 0.01)
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=TIMEOUT)
        rows = _check_prefix(out, reference, exact=False)
        assert rows >= 10
        for name in ("trajectory.csv", "trajectory.tum"):
            assert (out / name).is_file()  # checkpointed every frame
