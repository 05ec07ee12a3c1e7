"""``monovo batch``: track many sequences, on a local process pool or a Dask cluster.

Tracking inside one sequence is sequential; sequences are independent, so an archive scales
out over sequences. The pieces, each usable on its own:

- :func:`find_sequences` -- every sequence under a root folder (a folder holding ``frames/``
  and ``init.yaml``), or the folders matching a glob pattern;
- :func:`track_one` -- one sequence, a pure importable function of plain arguments (paths and
  a JSON-able options dict) that returns a plain dict and never raises for a bad sequence:
  the thing to hand to ``dask.distributed``'s ``client.submit``, Ray's ``ray.remote`` or any
  other engine;
- :func:`is_complete` -- whether an output folder holds the finished results of the same
  sequence and options (the ``done.json`` marker, written last by :func:`track_one`);
- :func:`write_summary` -- ``summary.csv``, one row per sequence;
- :func:`run_batch` -- all of the above over a local ``ProcessPoolExecutor`` (default) or a
  Dask cluster (the optional ``monovo[dask]`` extra, imported only when asked for).

This module imports only the standard library at import time, so that a freshly spawned
worker can limit OpenCV/BLAS/OpenMP to one thread before numpy and OpenCV are loaded.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import multiprocessing
import os
import signal
import socket
import time
import traceback
import uuid
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from monovo_cli import __version__
from monovo_cli.errors import InputError, MonovoError, OutputError

log = logging.getLogger(__name__)

FRAMES_SUBDIR = "frames"  # as monovo_cli.frames (not imported here: it loads OpenCV)
INIT_FILE = "init.yaml"
DONE_FILE = "done.json"
SUMMARY_FILE = "summary.csv"
SUMMARY_COLUMNS = ("sequence", "frames", "status", "frames_per_s", "mean_msd", "lost", "error",
                   "reanchored", "distance_m", "seconds")
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
DONE_FORMAT = 1

#: The options of :func:`track_one` and their defaults (those of ``monovo track``).
#: ``mask``: one PNG for every sequence (absolute path); ``prior``: a motion CSV's path
#: relative to each sequence folder; ``covariance``: a CSV's path relative to each output
#: folder. The rest are ``monovo track``'s options of the same names.
DEFAULT_OPTIONS: dict[str, Any] = {
    "levels": None,
    "threshold": None,
    "max_points": None,
    "robust": "huber",
    "reanchor_fraction": 0.6,
    "photometric": True,
    "max_step_m": None,
    "max_step_deg": None,
    "mask": None,
    "prior": None,
    "covariance": None,
    "skip_bad_frames": False,
}


# --------------------------------------------------------------------------- discovery


def _natural_parts(rel: Path) -> tuple:
    from monovo_cli.frames import natural_key

    return tuple(natural_key(p) for p in rel.parts)


def available_cores() -> int:
    """The cores this process may run on: its CPU affinity where the OS has one (a SLURM
    allocation, ``taskset``), else ``os.cpu_count()``."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS, Windows
        return os.cpu_count() or 1


def is_sequence_folder(path: Path) -> bool:
    """True when ``path`` holds a ``frames/`` directory and an ``init.yaml`` file."""
    path = Path(path)
    return (path / FRAMES_SUBDIR).is_dir() and (path / INIT_FILE).is_file()


def find_sequences(root: Path, *, pattern: str | None = None,
                   exclude: Sequence[Path] = ()) -> list[Path]:
    """The sequences under ``root`` as paths relative to it, in natural order.

    Without ``pattern``: every folder (``root`` itself included) holding ``frames/`` and
    ``init.yaml``; the search does not descend into a sequence, nor into hidden folders or
    the folders in ``exclude`` (e.g. the output root when it lies inside ``root``); symbolic
    links to folders are followed (each real folder once). With ``pattern`` (a
    :meth:`pathlib.Path.glob` pattern relative to ``root``, ``**`` allowed): every matching
    directory outside ``exclude``, whatever it holds -- ``monovo track``'s rules apply to it
    (a directory of frames with ``init.yaml`` beside them, or a folder holding ``frames/``).
    A sequence folder's relative path ``.`` stands for ``root`` itself.

    Raises InputError if ``root`` is not a directory or holds no sequence.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: {'is not a directory' if root.exists() else 'no such directory'}"
                         " (expected a folder of sequences, each a folder holding "
                         f"{FRAMES_SUBDIR}/ and {INIT_FILE})")
    excluded = {os.path.realpath(p) for p in exclude}
    found: list[Path] = []
    if pattern is not None:
        if Path(pattern).is_absolute():
            raise InputError(f"--glob {pattern!r}: expected a pattern relative to {root}")
        try:
            matches = list(root.glob(pattern))
        except (ValueError, NotImplementedError) as exc:
            raise InputError(f"--glob {pattern!r}: not a usable pattern ({exc})") from None
        for m in matches:
            real = os.path.realpath(m)
            if m.is_dir() and not any(real == e or real.startswith(e + os.sep) for e in excluded):
                found.append(m.relative_to(root))
        what = f"no directory under {root} matches --glob {pattern!r}"
    else:
        seen: set[str] = set()
        for dirpath, dirnames, _ in os.walk(root, followlinks=True):
            real = os.path.realpath(dirpath)
            if real in seen or real in excluded:
                dirnames[:] = []
                continue
            seen.add(real)
            here = Path(dirpath)
            if is_sequence_folder(here):
                found.append(here.relative_to(root))
                dirnames[:] = []  # a sequence's subfolders are its own data
                continue
            dirnames[:] = [d for d in dirnames if not d.startswith(".") and d != FRAMES_SUBDIR]
        what = (f"no sequence under {root} (a sequence is a folder holding {FRAMES_SUBDIR}/ and "
                f"{INIT_FILE}; use --glob PATTERN for other layouts)")
    if not found:
        raise InputError(what)
    return sorted(set(found), key=_natural_parts)


def sequence_name(rel: Path) -> str:
    """The summary's name of a sequence: its path relative to the root, '/'-separated."""
    return Path(rel).as_posix()


# --------------------------------------------------------------------------- one sequence


def normalize_options(options: dict[str, Any] | None) -> dict[str, Any]:
    """``options`` completed with :data:`DEFAULT_OPTIONS`; paths as strings.

    Raises ValueError for a key that is not an option (a programming error, not bad input).
    """
    options = dict(options or {})
    unknown = sorted(set(options) - set(DEFAULT_OPTIONS))
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(unknown)}; expected some of "
                         f"{', '.join(DEFAULT_OPTIONS)}")
    out = {**DEFAULT_OPTIONS, **options}
    for key in ("mask", "prior", "covariance"):
        if out[key] is not None:
            out[key] = str(out[key])
    return out


def _track_options(o: dict[str, Any]):
    from monovo_cli.estimate import EstimatorOptions
    from monovo_cli.odometry import TrackOptions

    return TrackOptions(levels=o["levels"], threshold=o["threshold"], max_points=o["max_points"],
                        reanchor_fraction=o["reanchor_fraction"], max_step_m=o["max_step_m"],
                        max_step_deg=o["max_step_deg"],
                        estimator=EstimatorOptions(robust=o["robust"], photometric=o["photometric"]))


def limit_threads() -> None:
    """OpenCV on one thread (the caller runs one sequence per core). BLAS/OpenMP read their
    thread counts from :data:`THREAD_VARIABLES` when numpy loads: set those in the worker's
    environment before it starts (the Dask nanny sets them to 1 by default)."""
    import cv2

    cv2.setNumThreads(1)


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _input_fingerprint(seq_dir: Path, prior: str | None) -> tuple[int, str]:
    """(number of frames, SHA-256 over the frame names and sizes, init.yaml and the prior).

    Frames are compared by name and size, not content: hashing an archive's images on every
    resume would cost as much as reading them for tracking.
    """
    from monovo_cli.frames import FrameSequence, find_init_yaml

    frames = FrameSequence(seq_dir)
    h = hashlib.sha256()
    for p in frames.paths:
        h.update(f"{p.name}\0{p.stat().st_size}\n".encode())
    for extra in (find_init_yaml(Path(seq_dir)), frames.times_path,
                  Path(seq_dir) / prior if prior else None):
        if extra is not None and Path(extra).is_file():
            h.update(f"{Path(extra).name}\0{_sha256(Path(extra))}\n".encode())
    return len(frames), h.hexdigest()


def _count_rows(path: Path, header: bool) -> int:
    with open(path, newline="") as f:
        n = sum(1 for line in f if line.strip())
    return n - 1 if header else n


def _result(seq_dir: Path, out_dir: Path, **fields: Any) -> dict[str, Any]:
    base = {"sequence": str(seq_dir), "out_dir": str(out_dir), "status": "failed", "frames": None,
            "fps": None, "mean_msd": None, "lost": None, "reanchored": None, "distance_m": None,
            "seconds": None, "error": "", "error_kind": "",
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    base.update(fields)
    return base


def track_one(seq_dir: str | Path, out_dir: str | Path, options: dict[str, Any] | None = None, *,
              overwrite: bool = False, single_thread: bool = True) -> dict[str, Any]:
    """Track one sequence into ``out_dir`` as ``monovo track SEQ -o OUT`` does; never raises
    for a bad sequence.

    ``seq_dir``: a sequence folder (``frames/`` and ``init.yaml``) or a directory of frames
    with ``init.yaml`` beside them. ``options``: keys of :data:`DEFAULT_OPTIONS` (unknown
    keys raise ValueError). ``overwrite``: replace results already in ``out_dir`` (else such
    a folder is an error). ``single_thread``: run OpenCV on one thread (see
    :func:`limit_threads`).

    Writes motion.csv, trajectory.csv, trajectory.tum and trajectory.png, then, last,
    ``done.json`` (what :func:`is_complete` checks). Returns a JSON-able dict: ``status``
    ``"ok"`` with ``frames``, ``fps``, ``mean_msd`` (grey levels^2), ``lost``, ``reanchored``,
    ``distance_m``, ``seconds``; or ``"failed"`` with ``error`` (one line) and
    ``error_kind`` ``"input"`` (a MonovoError: a file to fix) or ``"internal"`` (anything
    else; ``traceback`` holds the details). KeyboardInterrupt and other BaseExceptions
    propagate.
    """
    opts = normalize_options(options)
    seq_dir, out_dir = Path(seq_dir), Path(out_dir)
    t0 = time.perf_counter()
    try:
        if single_thread:
            limit_threads()
        from monovo_cli.runner import RESULT_FILES, track_sequence

        done = out_dir / DONE_FILE
        if done.exists():
            if not overwrite:
                raise OutputError(f"{out_dir}: already holds results ({DONE_FILE}); use "
                                  "overwrite (--overwrite / --resume) or another output folder")
            done.unlink()
        summary = track_sequence(
            seq_dir, None, out_dir, _track_options(opts), overwrite=overwrite,
            skip_bad_frames=opts["skip_bad_frames"],
            mask=Path(opts["mask"]) if opts["mask"] else None,
            prior=seq_dir / opts["prior"] if opts["prior"] else None,
            covariance=out_dir / opts["covariance"] if opts["covariance"] else None)
        n_frames, fingerprint = _input_fingerprint(seq_dir, opts["prior"])
        rows = {"motion.csv": (_count_rows(out_dir / "motion.csv", True), n_frames - 1),
                "trajectory.csv": (_count_rows(out_dir / "trajectory.csv", True), n_frames),
                "trajectory.tum": (_count_rows(out_dir / "trajectory.tum", False), n_frames)}
        for name, (got, expected) in rows.items():
            if got != expected:
                raise RuntimeError(f"{out_dir / name}: {got} rows after tracking, expected "
                                   f"{expected} for {n_frames} frames")
        names = list(RESULT_FILES) + ([opts["covariance"]] if opts["covariance"] else [])
        files = {n: {"bytes": (out_dir / n).stat().st_size, "sha256": _sha256(out_dir / n)}
                 for n in names if (out_dir / n).is_file()}
        stats = {"frames": summary.frames, "fps": summary.fps, "mean_msd": summary.mean_msd,
                 "lost": summary.lost, "reanchored": summary.reanchored,
                 "distance_m": summary.distance_m, "seconds": summary.seconds}
        marker = {"format": DONE_FORMAT, "monovo": __version__, "frames": n_frames,
                  "inputs_sha256": fingerprint, "options": opts, "result": stats, "files": files}
        from monovo_cli.outputs import atomic_write_text

        atomic_write_text(done, json.dumps(marker, indent=1, sort_keys=True) + "\n")
        return _result(seq_dir, out_dir, status="ok", **stats)
    except MonovoError as exc:
        log.debug("%s failed", seq_dir, exc_info=True)
        return _result(seq_dir, out_dir, error=str(exc), error_kind="input",
                       seconds=time.perf_counter() - t0)
    except Exception as exc:
        log.debug("%s failed", seq_dir, exc_info=True)
        return _result(seq_dir, out_dir, error=f"internal error: {type(exc).__name__}: {exc}",
                       error_kind="internal", traceback=traceback.format_exc(),
                       seconds=time.perf_counter() - t0)


def is_complete(seq_dir: str | Path, out_dir: str | Path,
                options: dict[str, Any] | None = None) -> tuple[bool, str]:
    """Whether ``out_dir`` holds the finished results of ``seq_dir`` tracked with ``options``.

    Complete means: ``done.json`` (written by :func:`track_one` after every other output)
    is there and readable; it was written for the same options (:func:`normalize_options`)
    and the same inputs (number of frames, frame names and sizes, init.yaml, times.txt and
    the prior); and every file it lists is there with the size and SHA-256 it recorded --
    motion.csv with one row per frame >= 1, trajectory.csv and .tum with one per frame, as
    checked before the marker was written. Returns ``(complete, reason)``, the reason
    saying what is missing or different.
    """
    seq_dir, out_dir = Path(seq_dir), Path(out_dir)
    opts = normalize_options(options)
    done = out_dir / DONE_FILE
    if not done.is_file():
        return False, f"no {DONE_FILE}"
    try:
        marker = json.loads(done.read_text())
        if marker.get("format") != DONE_FORMAT:
            return False, f"{DONE_FILE} of another format ({marker.get('format')!r})"
        if marker.get("options") != opts:
            return False, "tracked with other options"
        n_frames, fingerprint = _input_fingerprint(seq_dir, opts["prior"])
        if (marker.get("frames"), marker.get("inputs_sha256")) != (n_frames, fingerprint):
            return False, "the sequence's frames, init.yaml, times.txt or prior changed"
        for name, want in marker["files"].items():
            path = out_dir / name
            if not path.is_file():
                return False, f"{name} is missing"
            if path.stat().st_size != want["bytes"] or _sha256(path) != want["sha256"]:
                return False, f"{name} changed since it was written"
        for name in ("motion.csv", "trajectory.csv", "trajectory.tum"):
            if name not in marker["files"]:
                return False, f"{DONE_FILE} does not list {name}"
    except (OSError, ValueError, KeyError, TypeError, AttributeError, MonovoError) as exc:
        return False, f"{DONE_FILE} or the inputs cannot be checked ({type(exc).__name__}: {exc})"
    return True, "complete"


def done_result(seq_dir: Path, out_dir: Path) -> dict[str, Any]:
    """The result dict of a complete sequence (status ``skipped``), from its ``done.json``."""
    stats = json.loads((Path(out_dir) / DONE_FILE).read_text())["result"]
    return _result(seq_dir, out_dir, status="skipped", worker="", **stats)


# --------------------------------------------------------------------------- summary


def _cell(value: Any, spec: str) -> str:
    return "" if value is None else format(value, spec)


def summary_rows(results: Sequence[dict[str, Any]]) -> list[list[str]]:
    """``summary.csv`` rows (:data:`SUMMARY_COLUMNS`) of result dicts whose ``sequence`` is
    the name to show."""
    rows = []
    for r in results:
        error = " ".join(str(r.get("error") or "").split())  # one line, whatever it held
        rows.append([r["sequence"], _cell(r.get("frames"), "d"), r["status"],
                     _cell(r.get("fps"), ".2f"), _cell(r.get("mean_msd"), ".4f"),
                     _cell(r.get("lost"), "d"), error, _cell(r.get("reanchored"), "d"),
                     _cell(r.get("distance_m"), ".4f"), _cell(r.get("seconds"), ".2f")])
    return rows


def write_summary(path: Path, results: Sequence[dict[str, Any]]) -> None:
    """Write ``summary.csv`` atomically: a header, then one row per result (see
    :func:`summary_rows`); status ``ok``, ``skipped`` (complete from an earlier run, its
    figures from then), ``failed`` (``error`` says why) or ``pending`` (not run: the batch
    was interrupted)."""
    from monovo_cli.outputs import atomic_write_text

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS)
    w.writerows(summary_rows(results))
    atomic_write_text(Path(path), buf.getvalue())


# --------------------------------------------------------------------------- executors


@dataclass(frozen=True)
class _Job:
    index: int
    seq_dir: Path
    out_dir: Path


class _Stop(BaseException):
    """SIGTERM in a pool worker: unwinds track_sequence (which flushes what it has done)."""


def _raise_stop(signum, frame):  # noqa: ARG001
    raise _Stop()


def _init_worker(log_level: int) -> None:
    """Initializer of a local pool worker: one thread for BLAS/OpenMP/OpenCV (set before
    numpy and OpenCV load), Ctrl-C left to the parent, SIGTERM unwinds cleanly."""
    for var in THREAD_VARIABLES:
        os.environ[var] = "1"
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _raise_stop)
    logging.basicConfig(level=log_level, format="monovo: %(levelname)s: %(message)s")
    logging.getLogger("monovo_cli").setLevel(log_level)
    limit_threads()


def _pool_task(task: Callable[..., dict], seq_dir: str, out_dir: str, options: dict,
               overwrite: bool) -> dict:
    try:
        return task(seq_dir, out_dir, options, overwrite=overwrite)
    except _Stop:
        os._exit(143)


def _lost(job: _Job, why: str) -> dict[str, Any]:
    return _result(job.seq_dir, job.out_dir, error=f"internal error: {why}", error_kind="internal",
                   worker="")


def _terminate(executor: ProcessPoolExecutor) -> None:
    """Stop a pool now: cancel what has not started, SIGTERM the workers (they flush the
    frames done), wait for them."""
    procs = list((getattr(executor, "_processes", None) or {}).values())  # no public API < 3.14
    executor.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=30)


def _run_pool(jobs: list[_Job], workers: int, task: Callable[..., dict], options: dict,
              overwrite: bool, on_result: Callable[[_Job, dict], None], log_level: int) -> None:
    """Run ``jobs`` on a ``ProcessPoolExecutor`` of ``workers`` spawned processes.

    At most ``workers`` jobs are in flight, so when a worker process dies (killed, out of
    memory, a crash in native code) and the pool breaks, the suspects are known: they are
    rerun one at a time in a fresh pool; one that breaks a pool on its own is recorded as
    failed, the others go on.
    """
    ctx = multiprocessing.get_context("spawn")  # no fork of a process with OpenCV threads
    pending: deque[_Job] = deque(jobs)
    suspects: deque[_Job] = deque()
    while pending or suspects:
        isolate = bool(suspects)
        source = suspects if isolate else pending
        width = 1 if isolate else max(1, min(workers, len(source)))
        executor = ProcessPoolExecutor(max_workers=width, mp_context=ctx,
                                       initializer=_init_worker, initargs=(log_level,))
        running: dict[Any, _Job] = {}
        broken = False
        try:
            while (source or running) and not broken:
                while source and len(running) < width and not broken:
                    job = source.popleft()
                    try:
                        fut = executor.submit(_pool_task, task, str(job.seq_dir),
                                              str(job.out_dir), options, overwrite)
                    except BrokenProcessPool:  # a worker died since the last wait
                        source.appendleft(job)
                        broken = True
                    else:
                        running[fut] = job
                if not running:
                    break
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    job = running.pop(fut)
                    try:
                        on_result(job, fut.result())
                    except BrokenProcessPool:
                        broken = True
                        if isolate:
                            on_result(job, _lost(job, "the worker process died while tracking "
                                                      "this sequence (killed, out of memory, or "
                                                      "a crash in native code)"))
                        else:
                            suspects.append(job)
                    except Exception as exc:  # e.g. a result that cannot be pickled
                        on_result(job, _lost(job, f"{type(exc).__name__}: {exc}"))
            if broken:
                wait(running)
                for fut, job in running.items():
                    if fut.exception() is None:
                        on_result(job, fut.result())
                    else:
                        suspects.append(job)
                running.clear()
                if not isolate:
                    log.warning("a worker process died; rerunning %d sequence(s) one at a time "
                                "to find the one that killed it", len(suspects))
        except BaseException:
            _terminate(executor)
            raise
        executor.shutdown(wait=True)


def _import_distributed(what: str):
    try:
        import distributed
    except ImportError:
        raise MonovoError(f"{what}: needs Dask, which is not installed; install it with "
                          "pip install 'monovo[dask]'") from None
    return distributed


def _run_dask(jobs: list[_Job], scheduler: str | None, workers: int, task: Callable[..., dict],
              options: dict, overwrite: bool, on_result: Callable[[_Job, dict], None],
              retries: int, log_level: int = logging.WARNING) -> None:
    """Run ``jobs`` on the Dask scheduler at ``scheduler``, or on a LocalCluster of
    ``workers`` single-threaded worker processes when it is None.

    A task whose worker dies is rescheduled by Dask itself (up to the scheduler's
    ``distributed.scheduler.allowed-failures``, then KilledWorker); a task that raised is
    retried ``retries`` times (track_one returns its errors, so this only covers failures
    around it, e.g. unpickling on a worker). A future that still fails is recorded as a
    failed sequence.
    """
    what = f"--scheduler {scheduler}" if scheduler else "--dask"
    distributed = _import_distributed(what)
    dask_log = logging.getLogger("distributed")
    saved_level = dask_log.level
    dask_log.setLevel(max(log_level, logging.WARNING))  # its INFO lines are not for our users
    try:
        _run_dask_client(distributed, what, jobs, scheduler, workers, task, options, overwrite,
                         on_result, retries)
    finally:
        dask_log.setLevel(saved_level)


def _run_dask_client(distributed, what, jobs, scheduler, workers, task, options, overwrite,
                     on_result, retries) -> None:
    cluster = None
    try:
        if scheduler is None:
            cluster = distributed.LocalCluster(n_workers=max(1, min(workers, len(jobs))),
                                               threads_per_worker=1, processes=True,
                                               dashboard_address=None,
                                               silence_logs=logging.ERROR)
            client = distributed.Client(cluster)
        else:
            client = distributed.Client(scheduler, timeout=10)
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise MonovoError(f"{what}: cannot reach the Dask scheduler ({type(exc).__name__}: "
                          f"{exc})") from None
    token = uuid.uuid4().hex[:12]
    futures: dict[Any, _Job] = {}
    try:
        for job in jobs:
            fut = client.submit(task, str(job.seq_dir), str(job.out_dir), options,
                                overwrite=overwrite, key=f"monovo-track-{token}-{job.index}",
                                pure=False, retries=retries)
            futures[fut] = job
        for fut in distributed.as_completed(list(futures)):
            job = futures[fut]
            try:
                res = fut.result()
            except Exception as exc:  # KilledWorker, a worker without monovo, ...
                res = _lost(job, f"{type(exc).__name__}: {exc}")
            on_result(job, res)
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# --------------------------------------------------------------------------- the batch


@dataclass
class BatchSummary:
    """What :func:`run_batch` did. ``results``: one dict per sequence in discovery order
    (``sequence`` its relative name, ``status`` ok / skipped / failed / pending)."""

    results: list[dict[str, Any]]
    seconds: float
    summary_path: Path
    executor: str
    workers: int | None = None

    def count(self, status: str) -> int:
        return sum(r["status"] == status for r in self.results)

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.results if r["status"] == "failed"]

    @property
    def internal_errors(self) -> list[dict[str, Any]]:
        return [r for r in self.failed if r.get("error_kind") != "input"]


def _existing_results(out_dir: Path) -> bool:
    from monovo_cli.runner import RESULT_FILES

    return any((out_dir / n).exists() for n in (*RESULT_FILES, DONE_FILE))


def run_batch(root: str | Path, out_root: str | Path, options: dict[str, Any] | None = None, *,
              pattern: str | None = None, workers: int | None = None,
              scheduler: str | None = None, dask: bool = False, resume: bool = False,
              overwrite: bool = False, retries: int = 2, log_level: int = logging.WARNING,
              progress: Callable[[int, int], None] | None = None,
              task: Callable[..., dict] = track_one,
              summary_every_s: float = 5.0) -> BatchSummary:
    """``monovo batch``: track every sequence under ``root`` into ``out_root/<relative path>``.

    Sequences come from :func:`find_sequences` (``pattern``: a glob). Each is tracked by
    ``task`` (:func:`track_one`, or a function of the same signature) with ``options``
    (keys of :data:`DEFAULT_OPTIONS`), on a local pool of ``workers`` spawned processes
    (default: :func:`available_cores`), on a Dask LocalCluster of ``workers`` processes
    (``dask``), or on the Dask scheduler at ``scheduler`` (``tcp://HOST:PORT``; its workers
    must see ``root`` and ``out_root`` at the same paths and have monovo installed).

    ``resume``: skip the sequences whose outputs are complete (:func:`is_complete`) and redo
    the others; ``overwrite``: redo all. Without either, an output folder that already holds
    results is an OutputError before anything runs. A sequence that fails is recorded and
    the others go on. ``out_root/summary.csv`` (:func:`write_summary`) is rewritten
    atomically at least every ``summary_every_s`` seconds while results come in, at the
    end, and when the batch is interrupted (unfinished sequences ``pending``).
    ``progress(done, total)`` is called as sequences finish (skipped ones count as done).

    Raises MonovoError for a bad root, pattern, output root or executor (Dask missing or
    unreachable), ValueError for unknown option keys.
    """
    t0 = time.perf_counter()
    root, out_root = Path(root), Path(out_root)
    opts = normalize_options(options)
    if resume and overwrite:
        raise MonovoError("choose one of resume (skip complete sequences) and overwrite "
                          "(redo all)")
    if scheduler is not None and not str(scheduler).strip():
        raise MonovoError("--scheduler: expected an address like tcp://HOST:8786, got ''")
    use_dask = dask or scheduler is not None
    if use_dask:  # fail before any work if Dask is missing
        _import_distributed(f"--scheduler {scheduler}" if scheduler else "--dask")
    workers = int(workers) if workers else available_cores()
    if workers < 1:
        raise MonovoError(f"--workers {workers}: expected at least 1")
    rels = find_sequences(root, pattern=pattern, exclude=[out_root])
    if out_root.exists() and not out_root.is_dir():
        raise OutputError(f"{out_root}: exists and is not a directory; give -o a directory")
    try:
        out_root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out_root}: cannot create the output folder ({exc.strerror})") from None

    results: list[dict[str, Any]] = []
    jobs: list[_Job] = []
    blocked: list[str] = []
    for i, rel in enumerate(rels):
        seq_dir, out_dir = (root / rel).resolve(), (out_root / rel).resolve()
        name = sequence_name(rel)
        res = _result(seq_dir, out_dir, status="pending", worker="")
        if resume:
            complete, why = is_complete(seq_dir, out_dir, opts)
            if complete:
                res = done_result(seq_dir, out_dir)
            elif _existing_results(out_dir):
                log.info("%s: redone (%s)", name, why)
        elif not overwrite and _existing_results(out_dir):
            blocked.append(name)
        results.append({**res, "sequence": name})
        if res["status"] == "pending":
            jobs.append(_Job(i, seq_dir, out_dir))
    if blocked:
        raise OutputError(f"{out_root}: already holds results of {len(blocked)} of {len(rels)} "
                          f"sequence(s) (first: {blocked[0]}); use --resume to skip the complete "
                          "ones, --overwrite to redo all, or another -o")

    summary_path = out_root / SUMMARY_FILE
    total = len(results)
    total_done = [total - len(jobs)]
    last_write = [time.monotonic()]

    def on_result(job: _Job, res: dict[str, Any]) -> None:
        name = results[job.index]["sequence"]
        results[job.index] = {**res, "sequence": name}
        total_done[0] += 1
        if res["status"] == "failed":
            log.warning("%s: %s", name, res["error"])
        if progress is not None:
            progress(total_done[0], total)
        if time.monotonic() - last_write[0] >= summary_every_s:
            write_summary(summary_path, results)
            last_write[0] = time.monotonic()

    if progress is not None:
        progress(total_done[0], total)
    executor = "dask" if use_dask else "local"
    # Every task may replace what is in its folder: results from before this batch were
    # refused above unless resume/overwrite allowed them, so anything there now is from an
    # earlier attempt in this batch (a lost worker's task, rescheduled), to be redone.
    try:
        if jobs and use_dask:
            _run_dask(jobs, scheduler, workers, task, opts, True, on_result, retries, log_level)
        elif jobs:
            _run_pool(jobs, workers, task, opts, True, on_result, log_level)
    finally:
        write_summary(summary_path, results)
    return BatchSummary(results, time.perf_counter() - t0, summary_path, executor,
                        None if scheduler else workers)
