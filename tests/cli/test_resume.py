"""``monovo track --resume``: a run killed (SIGKILL) at random points and continued from its
checkpoint writes the bytes of an uninterrupted run.

Each run is a real subprocess killed while motion.csv grows (after a random number of rows,
before or after a checkpoint, or while one is written), then ``--resume`` runs to the end in
a fresh process. motion.csv, the covariance CSV, trajectory.csv and trajectory.tum (and the
terrain products with ``--terrain-out``) are compared byte for byte with a clean run's.
"""

from __future__ import annotations

import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.io.checkpoint import CHECKPOINT_FILE, OLD_CHECKPOINT_FILE

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

FRAMES = 60
EVERY = "5"
RESULTS = ("motion.csv", "covariance.csv", "trajectory.csv", "trajectory.tum")
TERRAIN = ("terrain.ply", "heightmap.csv")
TIMEOUT = 120


@pytest.fixture(scope="module")
def seq(synth_drive) -> Path:
    """60 frames of 192x192 (three re-anchors)."""
    return synth_drive(preset="drive", frames=FRAMES, size=(192, 192), seed=4)


def _track(seq: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "monovo_cli", "-q", "track", str(seq), "-o", str(out),
            "--covariance", str(out / "covariance.csv"), "--checkpoint-every", EVERY, *extra]


def _run(args: list[str]) -> subprocess.CompletedProcess:
    done = subprocess.run(args, capture_output=True, text=True, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    return done


def _rows(path: Path) -> int:
    try:
        return max(path.read_bytes().count(b"\n") - 1, 0)
    except FileNotFoundError:
        return 0


def _kill_after(args: list[str], motion: Path, rows: int) -> int:
    """Start ``args``, SIGKILL it once motion.csv holds ``rows`` rows; the rows then."""
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + TIMEOUT
    while _rows(motion) < rows and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    proc.send_signal(signal.SIGKILL)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == -signal.SIGKILL, f"the run ended before the kill: {err}"
    return _rows(motion)


def _kill_and_resume(seq: Path, clean: Path, tmp_path: Path, seed: int, kills: int,
                     names: tuple[str, ...], *extra: str,
                     rows: tuple[int, int] = (1, FRAMES - 8)) -> list[tuple[int, bool]]:
    """Kill a run ``kills`` times after a random number of rows in ``rows`` (``seed``),
    resume each and compare ``names`` with ``clean``'s: (rows at the kill, whether a
    checkpoint was there to resume from) of each kill."""
    rng = random.Random(seed)
    killed_at = []
    for k in range(kills):
        out = tmp_path / f"killed{k}"
        at = _kill_after(_track(seq, out, *extra), out / "motion.csv", rng.randint(*rows))
        killed_at.append((at, (out / CHECKPOINT_FILE).is_file()))
        _run(_track(seq, out, *extra, "--resume"))
        for name in names:
            assert (out / name).read_bytes() == (clean / name).read_bytes(), \
                f"{name} after a kill at row {at} and --resume"
        assert not (out / CHECKPOINT_FILE).exists(), "the finished run kept its checkpoint"
        assert not list(out.glob(".*.tmp")), "temporary files left behind"
    return killed_at


def test_resume_after_sigkill_at_five_random_points_gives_the_clean_bytes(seq, tmp_path):
    clean = tmp_path / "clean"
    _run(_track(seq, clean))
    killed_at = _kill_and_resume(seq, clean, tmp_path, 25, 5, RESULTS)
    rows = [at for at, _ in killed_at]
    assert len(set(rows)) == 5 and max(rows) < FRAMES - 1, killed_at
    assert sum(checkpoint for _, checkpoint in killed_at) >= 3, killed_at


def test_resume_with_terrain_out_gives_the_clean_terrain(seq, tmp_path):
    clean = tmp_path / "clean"
    _run(_track(seq, clean, "--terrain-out"))
    _kill_and_resume(seq, clean, tmp_path, 7, 2, RESULTS + TERRAIN, "--terrain-out")


def test_resume_through_lost_frames_and_the_recovery(seq, tmp_path):
    """Frames of noise in the middle: the kill lands in the run of lost frames or at the
    recovery after it, whose state (the feature hypothesis' frames, the lost count, the
    tracker's state) the checkpoint holds. Three of them, one more than ``reinit_after``
    (six were recovered the same way, re-anchored on the next frame, at twice the cost: a
    lost frame runs every capture attempt, and the test tracks them five times)."""
    noisy = tmp_path / "seq"
    shutil.copytree(seq, noisy)
    frames = sorted((noisy / "frames").glob("*.png"))
    assert len(frames) == FRAMES
    import cv2

    rng = np.random.default_rng(3)
    for path in frames[25:28]:
        cv2.imwrite(str(path), rng.integers(0, 256, (192, 192), dtype=np.uint8))
    clean = tmp_path / "clean"
    _run(_track(noisy, clean))
    statuses = [ln.split(",")[10] for ln in (clean / "motion.csv").read_text().splitlines()[1:]]
    assert statuses[24:27] == ["lost"] * 3 and statuses[27] != "lost", statuses
    killed_at = _kill_and_resume(noisy, clean, tmp_path, 6, 2, RESULTS, rows=(24, 28))
    assert all(checkpoint for _, checkpoint in killed_at), killed_at


def _invoke(*args: str):
    return CliRunner().invoke(main, ["-q", "track", *args])


def test_resume_without_a_checkpoint_starts_from_frame_0(seq, tmp_path):
    clean, out = tmp_path / "clean", tmp_path / "out"
    assert _invoke(str(seq), "-o", str(clean)).exit_code == 0
    r = _invoke(str(seq), "-o", str(out), "--resume")
    assert r.exit_code == 0, r.output
    for name in ("motion.csv", "trajectory.csv", "trajectory.tum"):
        assert (out / name).read_bytes() == (clean / name).read_bytes(), name


def test_resume_of_a_finished_run_says_so_and_leaves_it(seq, tmp_path):
    out = tmp_path / "out"
    assert _invoke(str(seq), "-o", str(out)).exit_code == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "--resume"])
    assert r.exit_code == 0, r.output
    assert r.output == f"nothing to resume: the run in {out} is finished\n"
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before


def _interrupted(seq: Path, out: Path, rows: int = 12) -> None:
    _kill_after(_track(seq, out), out / "motion.csv", rows)
    assert (out / CHECKPOINT_FILE).is_file()


@pytest.mark.parametrize("args, words", [
    (("--threshold", "9"), "options.track.threshold differs"),
    (("--no-smooth",), "options.smooth differs"),
])
def test_resume_with_other_options_is_refused(seq, tmp_path, args, words):
    out = tmp_path / "out"
    _interrupted(seq, out)
    motion = (out / "motion.csv").read_bytes()
    r = _invoke(str(seq), "-o", str(out), "--covariance", str(out / "covariance.csv"), *args)
    assert r.exit_code == 2 and "its run was interrupted: use --resume to continue it" in r.output
    r = _invoke(str(seq), "-o", str(out), "--covariance", str(out / "covariance.csv"),
                "--resume", *args)
    assert r.exit_code == 2
    assert words in r.output and "use --overwrite or another -o" in r.output
    assert r.output.count("\n") == 1 and "Traceback" not in r.output
    assert (out / "motion.csv").read_bytes() == motion, "a refused resume changed the results"


def test_resume_with_other_frames_is_refused(seq, tmp_path):
    copy, out = tmp_path / "seq", tmp_path / "out"
    shutil.copytree(seq, copy)
    _interrupted(copy, out)
    frame = sorted((copy / "frames").glob("*.png"))[-1]
    frame.write_bytes(frame.read_bytes() + b"\0")
    r = _invoke(str(copy), "-o", str(out), "--covariance", str(out / "covariance.csv"),
                "--resume")
    assert r.exit_code == 2 and "inputs.frames.list_sha256 differs" in r.output, r.output


@pytest.mark.parametrize("args, words", [
    (("-o", "-"), "--resume continues the run in an output directory"),
    (("-o", "OUT", "--overwrite"), "--overwrite starts it afresh"),
])
def test_resume_refuses_stdout_and_overwrite(seq, tmp_path, args, words):
    args = tuple(str(tmp_path / "out") if a == "OUT" else a for a in args)
    r = _invoke(str(seq), *args, "--resume")
    assert r.exit_code == 2 and words in r.output, r.output
    assert r.output.count("\n") == 1


def test_a_damaged_checkpoint_is_one_line(seq, tmp_path):
    out = tmp_path / "out"
    _interrupted(seq, out)
    (out / CHECKPOINT_FILE).write_bytes(b"not a pickle")
    r = _invoke(str(seq), "-o", str(out), "--covariance", str(out / "covariance.csv"),
                "--resume")
    assert r.exit_code == 2 and "not a readable checkpoint" in r.output, r.output
    assert r.output.count("\n") == 1


class _Payload:
    """Unpickled, it creates the file ``marker``: what a crafted checkpoint could do."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


@pytest.mark.parametrize("name", [CHECKPOINT_FILE, OLD_CHECKPOINT_FILE])
def test_a_pickle_in_place_of_the_checkpoint_runs_nothing(seq, tmp_path, name):
    """A pickle that would run code when loaded, under the checkpoint's name or the one
    monovo's pickled checkpoints had: --resume refuses it in one line (exit 2), the code
    never runs and the outputs stay as they were."""
    import pickle

    out, marker = tmp_path / "out", tmp_path / "ran"
    _interrupted(seq, out)
    (out / CHECKPOINT_FILE).unlink()
    payload = pickle.dumps({"format": "monovo-checkpoint-5", "checkpoint": _Payload(marker)})
    pickle.loads(payload)  # (the payload works: it creates the marker)
    assert marker.is_file()
    marker.unlink()
    (out / name).write_bytes(payload)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    r = _invoke(str(seq), "-o", str(out), "--covariance", str(out / "covariance.csv"),
                "--resume")
    assert r.exit_code == 2, r.output
    assert r.output.count("\n") == 1 and "Traceback" not in r.output, r.output
    assert not marker.exists(), "the checkpoint's code ran"
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    if name == OLD_CHECKPOINT_FILE:
        assert r.output == (f"Error: {out / OLD_CHECKPOINT_FILE}: the checkpoint of an earlier "
                            "monovo, a pickle, which this one never loads (loading one can run "
                            "code); start the run afresh: use --overwrite or another -o\n")
    else:
        assert "not a readable checkpoint (not an .npz archive)" in r.output, r.output


def test_an_earlier_monovo_s_checkpoint_gives_way_to_overwrite(seq, tmp_path):
    out = tmp_path / "out"
    _interrupted(seq, out)
    (out / CHECKPOINT_FILE).rename(out / OLD_CHECKPOINT_FILE)
    r = _invoke(str(seq), "-o", str(out), "--overwrite")
    assert r.exit_code == 0, r.output
    assert not (out / OLD_CHECKPOINT_FILE).exists() and (out / "trajectory.csv").is_file()


def test_resume_of_a_finished_mostly_lost_run_exits_as_it_did(seq, tmp_path):
    """A retry loop that resumes a finished run sees its outcome again: exit 3 when more than
    half of its frames were lost, as the run itself exited: the drive's first 12 frames, 10
    of them noise (each lost frame tries every capture, so more of them only cost time)."""
    import cv2

    lossy = tmp_path / "lossy"
    shutil.copytree(seq, lossy)
    frames = sorted((lossy / "frames").glob("*.png"))
    for p in frames[12:]:
        p.unlink()
    frames = frames[:12]
    assert len(frames) > 10
    rng = np.random.default_rng(0)
    for p in frames[2:]:
        shape = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE).shape
        cv2.imwrite(str(p), rng.integers(0, 256, shape).astype(np.uint8))
    out = tmp_path / "out"
    first = CliRunner().invoke(main, ["track", str(lossy), "-o", str(out), "-q"])
    assert first.exit_code == 3, first.output
    again = CliRunner().invoke(main, ["track", str(lossy), "-o", str(out), "--resume", "-q"])
    assert again.exit_code == 3 and "frames lost (more than half)" in again.output
