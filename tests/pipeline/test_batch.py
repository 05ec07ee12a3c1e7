"""monovo batch: discovery, one sequence per worker, summary.csv, --resume, the Dask executor."""

from __future__ import annotations

import csv
import os
import shutil
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.errors import InputError
from monovo_cli.pipeline import batch
from monovo_cli.pipeline.batch import run_batch
from monovo_cli.pipeline.batch_job import JobOptions, find_sequences, is_complete, track_one
from monovo_cli.synth.write import synthesize

GOOD = ("a/s1", "a/s2", "b/deep/s3", "s4", "s10")
BROKEN = "broken"
COMPARED = ("motion.csv", "trajectory.csv", "trajectory.tum")


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    """Six small sequences in nested folders; ``broken`` has a corrupt init.yaml."""
    root = tmp_path_factory.mktemp("batch") / "archive"
    for seed, rel in enumerate(GOOD):
        synthesize(root / rel, preset="drive", frames=8, size=(128, 128), seed=seed)
    shutil.copytree(root / "s4", root / BROKEN)
    (root / BROKEN / "init.yaml").write_text("camera: [\n")
    (root / "notes").mkdir()  # neither frames/ nor init.yaml: not a sequence
    (root / "notes" / "readme.txt").write_text("x")
    return root


def _summary(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "summary.csv", newline="") as f:
        return {r["sequence"]: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def local_out(archive, tmp_path_factory) -> Path:
    """The archive tracked by the CLI on the local process pool with 2 workers."""
    out = tmp_path_factory.mktemp("local") / "out"
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(out), "--workers", "2", "-q"])
    assert r.exit_code == 2, r.output  # bad input in one sequence, after finishing the rest
    assert "1 of 6 sequence(s) failed, first broken" in r.output
    return out


def test_find_sequences_nested_in_natural_order(archive, tmp_path):
    rels = [p.as_posix() for p in find_sequences(archive)]
    assert rels == ["a/s1", "a/s2", "b/deep/s3", BROKEN, "s4", "s10"]
    # an output root inside the archive is not searched
    inside = archive / "b" / "out"
    shutil.copytree(archive / "s4", inside / "copy")
    try:
        assert "b/out/copy" not in [p.as_posix() for p in find_sequences(archive, exclude=[inside])]
        assert "b/out/copy" in [p.as_posix() for p in find_sequences(archive)]
    finally:
        shutil.rmtree(inside)
    # the root itself may be a sequence
    assert find_sequences(archive / "s4") == [Path(".")]


def test_find_sequences_glob_and_errors(archive, tmp_path):
    assert [p.as_posix() for p in find_sequences(archive, pattern="a/*")] == ["a/s1", "a/s2"]
    assert [p.as_posix() for p in find_sequences(archive, pattern="**/s3")] == ["b/deep/s3"]
    with pytest.raises(InputError, match="no directory under .* matches --glob 'zz\\*'"):
        find_sequences(archive, pattern="zz*")
    with pytest.raises(InputError, match="no sequence under"):
        find_sequences(tmp_path)
    with pytest.raises(InputError, match="no such directory"):
        find_sequences(tmp_path / "missing")


def test_track_one_returns_the_error_of_a_bad_sequence(archive, tmp_path):
    res = track_one(archive / BROKEN, tmp_path / "o")
    assert res["status"] == "failed" and res["error_kind"] == "input"
    assert "init.yaml: not valid YAML" in res["error"]
    with pytest.raises(TypeError, match="expected JobOptions"):  # a programming error
        track_one(archive / "s4", tmp_path / "o", {"levels": 3})


def test_local_batch_tracks_all_but_the_broken_one(archive, local_out):
    rows = _summary(local_out)
    assert list(rows) == ["a/s1", "a/s2", "b/deep/s3", BROKEN, "s4", "s10"]
    assert list(next(iter(rows.values())))[:7] == ["sequence", "frames", "status", "frames_per_s",
                                                    "mean_msd", "lost", "error"]
    assert rows[BROKEN]["status"] == "failed"
    assert "init.yaml: not valid YAML" in rows[BROKEN]["error"]
    for rel in GOOD:
        assert rows[rel]["status"] == "ok" and rows[rel]["frames"] == "8" and not rows[rel]["error"]
        assert float(rows[rel]["frames_per_s"]) > 0 and rows[rel]["lost"] == "0"
        motion = (local_out / rel / "motion.csv").read_text().splitlines()
        assert len(motion) == 1 + 7
        assert len((local_out / rel / "trajectory.csv").read_text().splitlines()) == 1 + 8
        assert len((local_out / rel / "trajectory.tum").read_text().splitlines()) == 8
        assert is_complete(archive / rel, local_out / rel) == (True, "complete")
    assert not (local_out / BROKEN / "done.json").exists()


def test_batch_outputs_are_those_of_monovo_track(archive, local_out, tmp_path):
    r = CliRunner().invoke(main, ["track", str(archive / "a/s2"), "-o", str(tmp_path / "t"), "-q"])
    assert r.exit_code == 0, r.output
    for name in COMPARED:
        assert (tmp_path / "t" / name).read_bytes() == (local_out / "a/s2" / name).read_bytes()


def test_one_or_two_workers_and_monovo_track_give_the_same_bytes(tmp_path):
    """A drive over rolling ground (its relief's normal equations are what a threaded BLAS
    splits) and a flat one: the same bytes from 1 worker, 2 workers and ``monovo track`` in
    this process, whatever its threads."""
    archive = tmp_path / "archive"
    synthesize(archive / "rolling", preset="drive", frames=24, size=(192, 192),
               terrain="rolling", seed=5)
    synthesize(archive / "flat", preset="drive", frames=8, size=(128, 128), seed=1)
    for workers in ("1", "2"):
        r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(tmp_path / workers),
                                      "--workers", workers, "-q"])
        assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["track", str(archive / "rolling"), "-o", str(tmp_path / "t"),
                                  "-q"])
    assert r.exit_code == 0, r.output
    for rel in ("rolling", "flat"):
        for name in COMPARED:
            one = (tmp_path / "1" / rel / name).read_bytes()
            assert one == (tmp_path / "2" / rel / name).read_bytes(), f"{rel}/{name}"
            if rel == "rolling":
                assert one == (tmp_path / "t" / name).read_bytes(), f"{name}: batch vs track"


def test_resume_redoes_only_the_incomplete(archive, local_out, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(local_out, out)
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(out), "-q"])
    assert r.exit_code == 2 and "already holds results of 5 of 6" in r.output
    assert "--resume" in r.output
    # an interrupted batch: one sequence lost its marker, one a file, one was cut short
    (out / "a/s1" / "done.json").unlink()
    (out / "b/deep/s3" / "trajectory.tum").unlink()
    motion = out / "s10" / "motion.csv"
    motion.write_text("".join(motion.read_text().splitlines(keepends=True)[:4]))
    redo = {"a/s1", "b/deep/s3", "s10"}
    for rel in GOOD:
        assert is_complete(archive / rel, out / rel)[0] == (rel not in redo)
    assert "trajectory.tum is missing" in is_complete(archive / "b/deep/s3", out / "b/deep/s3")[1]
    assert "motion.csv changed" in is_complete(archive / "s10", out / "s10")[1]
    before = {rel: (out / rel / "motion.csv").stat().st_mtime_ns for rel in GOOD}
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(out), "--resume", "-q",
                                  "--workers", "2"])
    assert r.exit_code == 2, r.output
    rows = _summary(out)
    assert {rel: rows[rel]["status"] for rel in GOOD} == {
        rel: "ok" if rel in redo else "skipped" for rel in GOOD}
    assert rows[BROKEN]["status"] == "failed"
    for rel in GOOD:
        assert ((out / rel / "motion.csv").stat().st_mtime_ns == before[rel]) == (rel not in redo)
        assert is_complete(archive / rel, out / rel)[0]
        for name in COMPARED:
            assert (out / rel / name).read_bytes() == (local_out / rel / name).read_bytes()
    # other tracking options: nothing is complete any more
    tukey = JobOptions(track=TrackOptions(estimator=EstimatorOptions(robust="tukey")))
    assert is_complete(archive / "s4", out / "s4", tukey) == (False, "tracked with other options")


def test_resume_compares_the_frames_fingerprint(archive, local_out, tmp_path):
    """A sequence moved with its files' times is still complete; a frame rewritten under
    its name and size, or a new times.txt, makes it incomplete."""
    seq = tmp_path / "moved" / "s4"
    shutil.copytree(archive / "s4", seq)  # keeps the modification times
    out = local_out / "s4"
    assert is_complete(seq, out) == (True, "complete")
    changed = (False, "the sequence's frames, init.yaml, times.txt or prior changed")
    last = sorted((seq / "frames").glob("*.png"))[-1]
    st = last.stat()
    os.utime(last, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert is_complete(seq, out) == changed
    os.utime(last, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert is_complete(seq, out) == (True, "complete")
    (seq / "times.txt").write_text("".join(f"{0.1 * k:.1f}\n" for k in range(8)))
    assert is_complete(seq, out) == changed


def test_dask_local_cluster_gives_identical_outputs(archive, local_out, tmp_path):
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(out), "-q",
                                      "--scheduler", cluster.scheduler_address])
        assert r.exit_code == 2, r.output
        rows = _summary(out)
        assert rows[BROKEN]["status"] == "failed" and "init.yaml" in rows[BROKEN]["error"]
        # a worker dying halfway through a sequence: Dask reruns the task on a new worker
        flaky = run_batch(archive, tmp_path / "flaky", scheduler=cluster.scheduler_address,
                          task=_dies_once_track, pattern="a/s1")
    assert [r["status"] for r in flaky.results] == ["ok"]
    assert (tmp_path / "flaky" / "a" / ".s1.died").exists()  # it did die once
    for rel in GOOD:
        assert rows[rel]["status"] == "ok"
        for name in COMPARED:
            assert (out / rel / name).read_bytes() == (local_out / rel / name).read_bytes(), (
                f"{rel}/{name} differs between the Dask and the local executor")
            if rel == "a/s1":
                assert (tmp_path / "flaky" / rel / name).read_bytes() == (
                    local_out / rel / name).read_bytes()


def test_dask_missing_is_a_clear_usage_error(archive, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(tmp_path / "o"), "--dask"])
    assert r.exit_code == 2
    assert "needs Dask, which is not installed; install it with pip install 'monovo[dask]'" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "o").exists()


def _dies_once_track(seq_dir, out_dir, options, *, overwrite=False):
    """track_one, except that the worker dies the first time, after it began writing."""
    out_dir = Path(out_dir)
    once = out_dir.parent / f".{Path(seq_dir).name}.died"
    if not once.exists():
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "motion.csv").write_text("frame,tx\n1,0.1\n")
        once.touch()
        os._exit(3)
    return track_one(seq_dir, out_dir, options, overwrite=overwrite)


def _flaky_track(seq_dir, out_dir, options, *, overwrite=False):
    """track_one, except that the worker process dies in 's2' after it began writing (as
    under the OOM killer or a node going away). 's1', if it was running in the same pool,
    is lost with it and must be redone alone. (An earlier version also killed 's1' once;
    when the pool broke before 's1' started, its one death fell on its lone rerun, so the
    test depended on timing.)"""
    name, out_dir = Path(seq_dir).name, Path(out_dir)
    if name == "s2":
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "motion.csv").write_text("frame,tx\n1,0.1\n")
        os._exit(3)
    import cv2

    res = track_one(seq_dir, out_dir, options, overwrite=overwrite)
    return {**res, "threads": (os.environ.get("OMP_NUM_THREADS"), cv2.getNumThreads())}


def test_a_dying_worker_fails_only_its_sequence(archive, local_out, tmp_path):
    out = tmp_path / "o"
    s = run_batch(archive, out, workers=2, task=_flaky_track, pattern="a/*")
    status = {r["sequence"]: r["status"] for r in s.results}
    assert status == {"a/s1": "ok", "a/s2": "failed"}  # s1 done, or redone alone
    (bad,) = s.internal_errors
    assert "worker process died" in bad["error"]
    assert s.results[0]["threads"] == ("1", 1)  # single-threaded workers
    assert _summary(out)["a/s2"]["status"] == "failed"
    for name in COMPARED:
        assert (out / "a/s1" / name).read_bytes() == (local_out / "a/s1" / name).read_bytes()


def test_internal_errors_exit_1(archive, tmp_path, monkeypatch):
    def fake(root, out, options, **kw):
        res = {"sequence": "x", "status": "failed", "error": "internal error: boom",
               "error_kind": "internal"}
        return batch.BatchSummary([res], 0.1, Path(out) / "summary.csv", "local", 1)

    monkeypatch.setattr(batch, "run_batch", fake)
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(tmp_path / "o"), "-q"])
    # (run_batch logged the error as a warning when it came, -q or not)
    assert r.exit_code == 1 and "1 of 1 sequence(s) failed, first x (its error above" in r.output


@pytest.mark.parametrize("args, message", [
    (["--resume", "--overwrite"], "--resume and --overwrite exclude each other"),
    (["--covariance", "/abs/cov.csv"], "expected a path relative to each sequence"),
    (["--workers", "0"], "--workers"),
])
def test_batch_usage_errors(archive, tmp_path, args, message):
    r = CliRunner().invoke(main, ["batch", str(archive), "-o", str(tmp_path / "o"), *args])
    assert r.exit_code == 2 and message in r.output, r.output


@pytest.fixture(scope="module")
def noisy_archive(tmp_path_factory) -> Path:
    """One good sequence and one whose frames after the first are pure noise (most lost):
    4 frames, 3 of them noise (a lost frame runs every capture attempt, and the tests track
    it six times)."""
    import cv2
    import numpy as np

    root = tmp_path_factory.mktemp("noisy") / "archive"
    synthesize(root / "good", preset="drive", frames=8, size=(128, 128), seed=1)
    synthesize(root / "noisy", preset="drive", frames=4, size=(128, 128), seed=3)
    rng = np.random.default_rng(0)
    frames = sorted((root / "noisy" / "frames").glob("*.png"))
    assert len(frames) == 4
    for path in frames[1:]:
        cv2.imwrite(str(path), rng.integers(0, 256, (128, 128), dtype=np.uint8))
    return root


def test_a_mostly_lost_sequence_fails_on_data_with_status_3_on_every_rerun(noisy_archive,
                                                                           tmp_path):
    out = tmp_path / "out"
    for extra in ([], ["--resume"], ["--resume"], ["--overwrite"]):
        r = CliRunner().invoke(main, ["batch", str(noisy_archive), "-o", str(out), "-q",
                                      "--workers", "1", *extra])
        assert r.exit_code == 3, (extra, r.output)
        assert "1 of 2 sequence(s) failed, first noisy (its error above" in r.output
        rows = _summary(out)
        assert rows["noisy"]["status"] == "failed", extra
        assert rows["noisy"]["error"] == "3 of 3 frames lost (more than half)", extra
        assert rows["good"]["status"] == ("skipped" if extra == ["--resume"] else "ok")
        assert (out / "noisy" / "trajectory.csv").is_file()  # the outputs are kept


def test_resume_tracks_again_a_sequence_its_done_json_records_as_failed(noisy_archive,
                                                                        tmp_path):
    out = tmp_path / "out"
    s = run_batch(noisy_archive, out, workers=1, pattern="noisy")
    assert [r["error_kind"] for r in s.results] == ["lost"]
    assert not s.internal_errors and not s.input_errors
    before = (out / "noisy" / "motion.csv").stat().st_mtime_ns
    s = run_batch(noisy_archive, out, workers=1, pattern="noisy", resume=True)
    assert [(r["status"], r["error_kind"]) for r in s.results] == [("failed", "lost")]
    assert (out / "noisy" / "motion.csv").stat().st_mtime_ns != before


def test_a_failure_is_told_once_with_its_flags(noisy_archive, tmp_path):
    """Each failure's error is logged as it comes (with the command line's flags), -q or not
    (a warning), and the last line points at it instead of repeating it."""
    args = ["batch", str(noisy_archive), "-o", str(tmp_path / "o"), "--workers", "1",
            "--glob", "good", "--threshold", "1e9"]
    for extra in ([], ["-q", "--overwrite"]):
        r = CliRunner().invoke(main, [*args, *extra])
        assert r.exit_code == 2, r.output
        assert r.output.count("only 0 observation points") == 1, r.output
        assert "monovo: WARNING: good: " in r.output and "lower --threshold" in r.output
        assert "gradient threshold" not in r.output
        assert "first good (its error above" in r.output


def test_a_folder_with_frames_but_no_init_yaml_is_named_and_failed(tmp_path, caplog):
    root = tmp_path / "archive"
    (root / "sol1" / "frames").mkdir(parents=True)
    (root / "sol1" / "frames" / "frame_000000.png").write_bytes(b"")
    assert find_sequences(root) == [Path("sol1")]
    s = run_batch(root, tmp_path / "out")  # no worker is started for it
    assert [(r["sequence"], r["status"], r["error_kind"]) for r in s.results] == [
        ("sol1", "failed", "input")]
    assert "holds frames/ but no init.yaml" in s.results[0]["error"]
    assert _summary(tmp_path / "out")["sol1"]["status"] == "failed"
    r = CliRunner().invoke(main, ["batch", str(root), "-o", str(tmp_path / "o2")])
    assert r.exit_code == 2, r.output
    assert "1 of 1 sequence(s) failed, first sol1" in r.output
    assert any("sol1" in m and "no init.yaml" in m for m in caplog.messages), caplog.messages


def test_a_sequence_s_log_lines_come_back_to_the_parent(monkeypatch, tmp_path, caplog):
    """A worker's log lines travel back in its result and are logged by the parent, through
    its handlers (above the progress bar), each with its sequence's name, instead of being
    written by the worker onto the parent's terminal."""
    import logging

    import monovo_cli.pipeline.track as track

    def fake_track(*args, **kwargs):
        logging.getLogger("monovo_cli.pipeline.track").info("frame 1 lost: too far")
        raise InputError("frame_000002.png: cannot read the image")

    monkeypatch.setattr(track, "track_sequence", fake_track)
    caplog.set_level(logging.INFO, logger="monovo_cli")
    res = track_one(tmp_path / "seq", tmp_path / "o", single_thread=False)
    assert res["status"] == "failed" and "cannot read" in res["error"]
    assert res["log"] == [(logging.INFO, "monovo_cli.pipeline.track", "frame 1 lost: too far")]
    caplog.clear()
    batch.relog("sol1", res)
    assert [(r.name, r.getMessage()) for r in caplog.records] == [
        ("monovo_cli.pipeline.track", "sol1: frame 1 lost: too far")]


def test_track_one_passes_terrain_out_threads_and_checkpoint_every(monkeypatch, tmp_path):
    import monovo_cli.pipeline.track as track

    seen = {}

    def fake_track(*args, **kwargs):
        seen.update(kwargs)
        raise InputError("stop here")

    monkeypatch.setattr(track, "track_sequence", fake_track)
    track_one(tmp_path / "seq", tmp_path / "o", single_thread=False)
    assert (seen["terrain_out"], seen["threads"]) == (False, 1) and "checkpoint_every" not in seen
    job = JobOptions(terrain_out=True, threads=3, checkpoint_every=7)
    track_one(tmp_path / "seq", tmp_path / "o", job, single_thread=False)
    assert (seen["terrain_out"], seen["threads"], seen["checkpoint_every"]) == (True, 3, 7)


def test_a_complete_sequence_stays_complete_whatever_the_threads_or_checkpoints():
    """--threads and --checkpoint-every leave the outputs as they are, and a sequence that
    finished has the same outputs with --skip-bad-frames: --resume keeps it. --terrain-out
    adds outputs: it does not. A done.json from before these options were recorded is read
    with their defaults."""
    from dataclasses import asdict

    from monovo_cli.pipeline.batch_job import same_job_options

    recorded = asdict(JobOptions())
    assert same_job_options(recorded, JobOptions(threads=4, checkpoint_every=0,
                                                 skip_bad_frames=True))
    assert not same_job_options(recorded, JobOptions(terrain_out=True))
    assert not same_job_options(recorded, JobOptions(topic="/cam"))
    older = {k: v for k, v in recorded.items() if k not in ("terrain_out", "threads",
                                                             "checkpoint_every")}
    assert same_job_options(older, JobOptions())
    assert not same_job_options("garbage", JobOptions())
