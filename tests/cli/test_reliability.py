"""Bad input and faults: one clear line and the documented exit status, nothing lost.

One parametrised case per row of docs/reliability.md (the rows come from
``reliability_cases.CASES``, which also generates the document), then what the rows
cannot show: the rows kept by a stopped run, stdout staying pure CSV, internal errors
(exit 1), determinism, and degenerate imagery inside a sequence.
"""

from __future__ import annotations

import csv
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.formats import read_motion_csv
from monovo_cli.synth.write import synthesize
from tests.helpers.reliability_cases import CASES, Outcome, make_base_sequence, run_case

DOC = Path(__file__).resolve().parents[2] / "docs" / "reliability.md"
_BAR = re.compile(r"^\s*\d+%\||^\s*$")  # tqdm progress output (split at its \r)
MOTION_HEADER = "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status"


@pytest.fixture(scope="module")
def base_seq(tmp_path_factory) -> Path:
    return make_base_sequence(tmp_path_factory.mktemp("reliability"))


def _stderr_lines(out: Outcome) -> list[str]:
    return [ln for ln in out.stderr.splitlines() if not _BAR.match(ln)]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_case(case, base_seq, tmp_path):
    missing = [cmd for cmd in case.needs if cmd not in main.commands]
    if missing:
        pytest.skip(f"command {missing[0]!r} is not in the CLI")
    out = run_case(case, tmp_path, base_seq)
    assert out.status == case.status, out.stderr
    assert "Traceback" not in out.stderr
    msg = out.message.lower()
    for word in case.words:
        assert word.lower() in msg, f"{word!r} not in {out.message!r}"
    lines = _stderr_lines(out)
    if case.status == 0:
        assert not any(ln.startswith("Error:") for ln in lines), out.stderr
        return
    errors = [ln for ln in lines if ln.startswith("Error:")]
    assert len(errors) == 1, out.stderr
    # click's usage errors (bad options) add its 'Usage:' and 'Try ... --help' lines
    others = [ln for ln in lines if not ln.startswith(("Error:", "Usage:", "Try '"))]
    assert not others, f"more than one line on stderr: {lines}"


def test_at_least_40_bad_inputs_and_unique_ids():
    assert len({c.id for c in CASES}) == len(CASES)
    assert sum(c.status == 2 for c in CASES) >= 40


def test_doc_table_lists_every_case():
    """docs/reliability.md is generated from CASES (docs/make_reliability_table.py)."""
    text = DOC.read_text()
    rows = [ln for ln in text.splitlines() if ln.startswith("| `")]
    ids = [ln.split("`")[1] for ln in rows]
    wanted = [c.id for c in CASES if all(cmd in main.commands for cmd in c.needs)]
    assert ids == wanted, "docs/reliability.md is stale: run docs/make_reliability_table.py"
    for case, row in zip(CASES, rows):
        assert f"| {case.status} |" in row, case.id


# ----------------------------------------------------------------------------- what was done is kept


def _case(case_id: str):
    return next(c for c in CASES if c.id == case_id)


def test_bad_frame_keeps_the_rows_done(base_seq, tmp_path):
    out = run_case(_case("frame-mid-empty"), tmp_path, base_seq)
    assert out.status == 2
    motion = (tmp_path / "out" / "motion.csv").read_text().splitlines()
    assert motion[0].startswith(MOTION_HEADER)
    assert [r.split(",")[0] for r in motion[1:]] == ["1", "2"]
    traj = (tmp_path / "out" / "trajectory.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in traj[1:]] == ["0", "1", "2"]
    assert len((tmp_path / "out" / "trajectory.tum").read_text().splitlines()) == 3


def test_skip_bad_frames_records_lost_and_goes_on(base_seq, tmp_path):
    out = run_case(_case("frame-mid-skip"), tmp_path, base_seq)
    assert out.status == 0, out.stderr
    rows = list(csv.DictReader((tmp_path / "out" / "motion.csv").open()))
    assert [int(r["frame"]) for r in rows] == [1, 2, 3, 4, 5]
    assert [r["status"] for r in rows][2] == "lost"
    assert rows[2]["points"] == "0"
    # its std states the prediction's uncertainty (SPEC.md): finite, and covering its error
    std = np.array([float(rows[2][f"std_{k}"]) for k in ("tx", "ty", "tz", "rx", "ry", "rz")])
    assert np.all(std > 0) and np.all(np.isfinite(std))
    _, gt, _ = read_motion_csv(base_seq / "groundtruth_motion.csv")
    err = np.abs(np.array([float(rows[2][k]) for k in ("tx", "ty", "tz")]) - gt[2][:3, 3])
    assert np.all(err < 4 * std[:3]), (err, std)
    # the next frame's motion starts from that predicted pose: its std carries its error too
    std4 = np.array([float(rows[3][f"std_{k}"]) for k in ("tx", "ty", "tz")])
    err4 = np.abs(np.array([float(rows[3][k]) for k in ("tx", "ty", "tz")]) - gt[3][:3, 3])
    assert np.all(err4 < 4 * std4) and np.all(std4 >= std[:3]), (err4, std4)
    assert "nan" not in (tmp_path / "out" / "motion.csv").read_text().lower()
    traj = (tmp_path / "out" / "trajectory.tum").read_text().split()
    assert len(traj) == 6 * 8 and all(math.isfinite(float(v)) for v in traj)
    # the lost frame carries the constant-velocity prediction: the motion of frame 2 again
    t2 = np.array([float(rows[1][k]) for k in ("tx", "ty", "tz")])
    t3 = np.array([float(rows[2][k]) for k in ("tx", "ty", "tz")])
    np.testing.assert_allclose(t3, t2, atol=1e-9)


def test_the_rerun_a_bad_frame_suggests_works(base_seq, tmp_path):
    """The message of a bad frame in the middle names a rerun; that rerun, into the same
    folder, is accepted and records the frame as lost."""
    import shutil

    seq, out = tmp_path / "seq", tmp_path / "out"
    shutil.copytree(base_seq, seq)
    sorted((seq / "frames").glob("*.png"))[3].write_bytes(b"")
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q"])
    assert r.exit_code == 2
    suggested = "rerun with --skip-bad-frames --overwrite to record bad frames as lost"
    assert suggested in r.output, r.output
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", "--skip-bad-frames",
                                  "--overwrite"])
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader((out / "motion.csv").open()))
    assert [r["status"] for r in rows][2] == "lost"
    # streaming: nothing to replace, the flag alone
    r = CliRunner().invoke(main, ["track", str(seq), "-o", "-", "-q"])
    assert r.exit_code == 2
    assert "rerun with --skip-bad-frames to record bad frames as lost" in r.output
    assert "--overwrite" not in r.output


def test_a_blank_frame_0_is_not_told_to_lower_the_threshold(base_seq, tmp_path):
    """No threshold gives points on a constant frame: the message does not suggest one."""
    out = run_case(_case("textureless-frame0"), tmp_path, base_seq)
    assert out.status == 2
    assert "lower" not in out.stderr and "--threshold" not in out.stderr, out.stderr


def test_streaming_error_keeps_stdout_pure_csv(base_seq, tmp_path):
    out = run_case(_case("frame-mid-stream"), tmp_path, base_seq)
    assert out.status == 2
    lines = out.stdout.splitlines()
    assert lines[0].startswith(MOTION_HEADER) and len(lines) == 3
    assert all(ln.count(",") == lines[0].count(",") for ln in lines)
    assert "Error:" not in out.stdout and "Error:" in out.stderr


def test_streaming_subprocess_stdout_is_only_csv(base_seq, tmp_path):
    """Through a real pipe, without -q: the progress bar and the error stay on stderr."""
    seq = tmp_path / "seq"
    import shutil

    shutil.copytree(base_seq, seq)
    sorted((seq / "frames").glob("*.png"))[4].write_bytes(b"")
    proc = subprocess.run([sys.executable, "-m", "monovo_cli", "track", str(seq), "-o", "-"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(MOTION_HEADER) and [ln.split(",")[0] for ln in lines[1:]] == \
        ["1", "2", "3"]
    err = [ln for ln in proc.stderr.splitlines() if not _BAR.match(ln)]
    assert len(err) == 1 and err[0].startswith("Error:") and "frame_000004.png" in err[0]


# ----------------------------------------------------------------------------- internal errors


def test_internal_error_is_one_line_and_status_1(base_seq, tmp_path, monkeypatch):
    import monovo_cli.pipeline.track as runner

    def boom(*a, **k):
        raise RuntimeError("simulated fault")

    monkeypatch.setattr(runner, "track_sequence", boom)
    r = CliRunner().invoke(main, ["track", str(base_seq), "-o", str(tmp_path / "o")])
    assert r.exit_code == 1
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: internal error: RuntimeError")
    assert "simulated fault" in lines[0] and "-v" in lines[0]


_FAULTY = """
import sys
import monovo_cli.pipeline.track as runner
def boom(*a, **k):
    raise RuntimeError("simulated fault")
runner.track_sequence = boom
from monovo_cli.cli import main
sys.argv[0] = "monovo"
main()
"""


@pytest.mark.parametrize("verbose", [False, True])
def test_internal_error_traceback_only_with_verbose(base_seq, tmp_path, verbose):
    args = [sys.executable, "-c", _FAULTY, "track", str(base_seq), "-o", str(tmp_path / "o")]
    proc = subprocess.run(args + (["-v"] if verbose else []), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1
    assert "simulated fault" in proc.stderr
    if verbose:
        assert "Traceback" in proc.stderr and "boom" in proc.stderr
    else:
        assert "Traceback" not in proc.stderr
        assert proc.stderr.strip().splitlines() == [
            "Error: internal error: RuntimeError: simulated fault (run with -v for the traceback)"]


def test_bad_input_traceback_only_with_vv(base_seq, tmp_path):
    """A user error is one line, with -v too; -vv adds its traceback for debugging."""
    args = [sys.executable, "-m", "monovo_cli", "track", str(tmp_path / "nope"), "-o",
            str(tmp_path / "o")]
    quiet = subprocess.run(args, capture_output=True, text=True, timeout=120)
    verbose = subprocess.run(args + ["-v"], capture_output=True, text=True, timeout=120)
    loud = subprocess.run(args + ["-vv"], capture_output=True, text=True, timeout=120)
    assert quiet.returncode == verbose.returncode == loud.returncode == 2
    assert verbose.stderr == quiet.stderr and len(quiet.stderr.strip().splitlines()) == 1
    assert "Traceback" not in quiet.stderr and "Traceback" in loud.stderr
    assert "monovo: ERROR: details\nTraceback" in loud.stderr
    assert quiet.stderr.strip().splitlines()[-1] == loud.stderr.strip().splitlines()[-1]


# ----------------------------------------------------------------------------- determinism

_WITH_THREADS = """
import sys
import cv2
cv2.setNumThreads(int(sys.argv.pop(1)))
from monovo_cli.cli import main
sys.argv[0] = "monovo"
main()
"""


@pytest.fixture(scope="module")
def drive(synth_drive) -> Path:
    return synth_drive(preset="drive", frames=40, size=(128, 128), seed=7)


@pytest.fixture(scope="module")
def rolling_drive(tmp_path_factory) -> Path:
    """A drive over rolling ground: its keyframes solve a relief of more than a hundred
    heights, whose normal equations a threaded BLAS splits among its threads."""
    seq = tmp_path_factory.mktemp("determinism") / "rolling"
    synthesize(seq, preset="drive", frames=24, size=(192, 192), terrain="rolling", seed=5)
    return seq


def _outputs(out: Path) -> dict[str, bytes]:
    return {n: (out / n).read_bytes() for n in ("motion.csv", "trajectory.csv", "trajectory.tum")}


def test_same_inputs_same_bytes(drive, tmp_path):
    runs = []
    for k in range(2):
        r = CliRunner().invoke(main, ["track", str(drive), "-o", str(tmp_path / f"o{k}"), "-q"])
        assert r.exit_code == 0, r.output
        runs.append(_outputs(tmp_path / f"o{k}"))
    assert runs[0] == runs[1]


@pytest.mark.parametrize("seq", ["drive", "rolling_drive"])
def test_same_bytes_with_one_or_two_blas_and_opencv_threads(seq, request, tmp_path):
    """BLAS/OpenMP threads (their variables, read when numpy loads) and OpenCV's threads
    (set before the run, and by --threads while tracking), each 1 or 2: the same bytes."""
    from monovo_cli.pipeline.batch_job import THREAD_VARIABLES

    seq = request.getfixturevalue(seq)
    runs = {}
    for blas, opencv in ((1, 1), (2, 1), (1, 2)):
        out = tmp_path / f"blas{blas}_opencv{opencv}"
        env = {**os.environ, **{var: str(blas) for var in THREAD_VARIABLES}}
        proc = subprocess.run([sys.executable, "-c", _WITH_THREADS, str(opencv), "track",
                               str(seq), "-o", str(out), "-q", "--threads", str(opencv)],
                              capture_output=True, text=True, timeout=300, env=env)
        assert proc.returncode == 0, proc.stderr
        runs[blas, opencv] = _outputs(out)
    for knob in ((2, 1), (1, 2)):
        for name, data in runs[knob].items():
            assert data == runs[1, 1][name], f"{name}: (BLAS, OpenCV) threads {knob} vs (1, 1)"


def test_one_blas_thread_inside_and_restored_after():
    from monovo_cli.pipeline import threads

    with threads.one_blas_thread():
        controls = threads._controls
    assert controls, "numpy's BLAS has no thread control here"
    found = [get() for get, _ in controls]
    for _, set_ in controls:
        set_(2)
    try:
        with threads.one_blas_thread():
            with threads.one_blas_thread():  # nested: still one
                assert [get() for get, _ in controls] == [1] * len(controls)
            assert [get() for get, _ in controls] == [1] * len(controls)
        assert [get() for get, _ in controls] == [2] * len(controls)
    finally:
        for (_, set_), count in zip(controls, found, strict=True):
            set_(count)


@pytest.mark.parametrize("threads", [1, 2])
def test_opencv_runs_on_the_threads_asked_while_tracking_and_is_restored_after(
        drive, tmp_path, monkeypatch, threads):
    """--threads 1 is one thread: OpenCV's idle pool workers wait by yielding the processor
    again and again, and kept a second core busy through a run asked for one."""
    from monovo_cli.core.odometry import Odometry
    from monovo_cli.pipeline.track import track_sequence

    seen, advance = [], Odometry.advance

    def counting(self, *args, **kwargs):
        seen.append(cv2.getNumThreads())
        return advance(self, *args, **kwargs)

    monkeypatch.setattr(Odometry, "advance", counting)
    before = cv2.getNumThreads()
    cv2.setNumThreads(3)
    try:
        track_sequence(drive, None, tmp_path / "o", TrackOptions(), threads=threads)
        assert cv2.getNumThreads() == 3
    finally:
        cv2.setNumThreads(before)
    assert len(seen) == 40 and set(seen) == {threads}


def test_streamed_rows_equal_motion_csv(drive, tmp_path):
    r = CliRunner().invoke(main, ["track", str(drive), "-o", "-", "-q"])
    assert r.exit_code == 0
    f = CliRunner().invoke(main, ["track", str(drive), "-o", str(tmp_path / "o"), "-q"])
    assert f.exit_code == 0
    assert r.stdout == (tmp_path / "o" / "motion.csv").read_text()


# ----------------------------------------------------------------------------- degenerate imagery


def _degenerate_images(shape: tuple[int, int]) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    return {
        "black": np.zeros(shape, np.uint8),
        "saturated": np.full(shape, 255, np.uint8),
        "constant": np.full(shape, 128, np.uint8),
        "noise": rng.integers(0, 256, shape).astype(np.uint8),
    }


@pytest.fixture(scope="module")
def degenerate_runs(tmp_path_factory) -> dict[str, tuple[int, str, dict]]:
    """Per kind, a 12-frame drive with frame 6 replaced by that image, tracked:
    ``(exit status, CLI output, {frame: motion row}, output text, {frame: image})``;
    also ``"noise-at-3"`` (the noise at frame 3) and ``"all"``: one 16-frame drive holding
    every kind (frames 4, 7, 10, 13)."""
    root = tmp_path_factory.mktemp("degenerate")
    images = _degenerate_images((128, 128))
    plans = {name: (12, {6: img}) for name, img in images.items()}
    plans["noise-at-3"] = (12, {3: images["noise"]})
    plans["all"] = (16, dict(zip((4, 7, 10, 13), images.values())))
    runs = {}
    for name, (n, replace) in plans.items():
        seq = root / name
        synthesize(seq, preset="drive", frames=n, size=(128, 128), seed=4)
        frames = sorted((seq / "frames").glob("*.png"))
        for k, img in replace.items():
            cv2.imwrite(str(frames[k]), img)
        out = root / f"{name}_out"
        r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q"])
        rows = {}
        if (out / "motion.csv").exists():
            rows = {int(row["frame"]): row for row in csv.DictReader((out / "motion.csv").open())}
        texts = "".join((out / f).read_text() for f in ("motion.csv", "trajectory.csv",
                                                          "trajectory.tum") if (out / f).exists())
        runs[name] = (r.exit_code, r.output + repr(r.exception), rows, texts, replace)
    return runs


@pytest.mark.parametrize("kind", ["black", "saturated", "constant", "noise", "noise-at-3", "all"])
def test_degenerate_frames_never_nan_never_raise(degenerate_runs, kind):
    """All-black, saturated, constant and pure-noise frames inside a drive: no exception,
    every frame has a row, no value is NaN or infinite."""
    status, output, rows, texts, _ = degenerate_runs[kind]
    assert status == 0, output
    assert sorted(rows) == list(range(1, len(rows) + 1)) and len(rows) >= 11
    assert "nan" not in texts.lower() and "inf" not in texts.lower()


@pytest.mark.parametrize("kind", ["black", "saturated", "constant", "noise", "noise-at-3", "all"])
def test_degenerate_frames_are_lost(degenerate_runs, kind):
    status, output, rows, _, replaced = degenerate_runs[kind]
    assert status == 0, output
    got = {k: rows[k]["status"] for k in replaced}
    assert got == {k: "lost" for k in replaced}, got


def test_the_exit_status_table_lists_every_status():
    """Every status a command exits with has its row (0, 1, 2, 3 and the signals')."""
    text = DOC.read_text()
    table = text[text.index("## Exit statuses"):text.index("## Bad inputs")]
    statuses = {ln.split("|")[1].strip() for ln in table.splitlines() if ln.startswith("| ")}
    assert {"0", "1", "2", "3", "130", "141", "143"} <= statuses, statuses
