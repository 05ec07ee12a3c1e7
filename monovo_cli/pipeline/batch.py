"""``monovo batch``: track many sequences, on a local process pool or a Dask cluster.

Sequences are independent, so an archive scales out over them. The per-sequence pieces live
in :mod:`monovo_cli.pipeline.batch_job` (``find_sequences``, ``track_one``: one sequence, a
pure function of picklable arguments returning a plain dict, for any engine;
``is_complete``; ``write_summary``). :func:`run_batch` schedules them on a local
``ProcessPoolExecutor`` (default) or a Dask cluster (the ``monovo[dask]`` extra, imported
only when asked for), ``resume`` skipping finished ones, and keeps ``summary.csv`` current.

Only the standard library is imported at import time, so that a freshly spawned worker can
limit OpenCV/BLAS/OpenMP to one thread before numpy and OpenCV are loaded.

Long module: the two engines' scheduling (pool and Dask) share one loop of results, resume
and interruption handling, kept together so that both keep summary.csv the same way.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import time
import uuid
from collections import deque
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from monovo_cli.errors import MonovoError, OutputError
from monovo_cli.pipeline.batch_job import (
    DONE_FILE,
    THREAD_VARIABLES,
    JobOptions,
    available_cores,
    checked_job_options,
    done_result,
    find_sequences,
    is_complete,
    limit_threads,
    missing_init_yaml,
    recorded_failure,
    result,
    sequence_name,
    track_one,
)
from monovo_cli.pipeline.batch_summary import SUMMARY_FILE, write_summary

log = logging.getLogger(__name__)



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
    numpy and OpenCV load), Ctrl-C left to the parent, SIGTERM unwinds cleanly. The worker
    writes no log line itself: track_one returns them and the parent logs them
    (:func:`relog`), so that they never cut through the parent's progress bar."""
    for var in THREAD_VARIABLES:
        os.environ[var] = "1"
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _raise_stop)
    logging.getLogger().addHandler(logging.NullHandler())  # (not logging's last resort)
    logging.getLogger("monovo_cli").setLevel(log_level)
    limit_threads()


def relog(name: str, res: dict[str, Any]) -> None:
    """Log, in this process, the lines a sequence's run logged where it ran (``res["log"]``
    of :func:`track_one`: (level, logger name, message)), each after the sequence's
    ``name``, through the logger that wrote it."""
    for level, logger, message in res.get("log") or ():
        logging.getLogger(logger).log(level, "%s: %s", name, message)


def _pool_task(task: Callable[..., dict], seq_dir: str, out_dir: str, options: JobOptions,
               overwrite: bool) -> dict:
    try:
        return task(seq_dir, out_dir, options, overwrite=overwrite)
    except _Stop:
        os._exit(143)


def _lost(job: _Job, why: str) -> dict[str, Any]:
    return result(job.seq_dir, job.out_dir, error=f"internal error: {why}", error_kind="internal",
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


def _run_pool(jobs: list[_Job], workers: int, task: Callable[..., dict], options: JobOptions,
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
              options: JobOptions, overwrite: bool, on_result: Callable[[_Job, dict], None],
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
        """How many sequences ended with ``status``."""
        return sum(r["status"] == status for r in self.results)

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The results of the sequences that failed, in order."""
        return [r for r in self.results if r["status"] == "failed"]

    @property
    def internal_errors(self) -> list[dict[str, Any]]:
        """The failures that are monovo's fault: internal errors and lost workers (not bad
        input, not sequences tracked to the end with most of their frames lost)."""
        return [r for r in self.failed if r.get("error_kind") not in ("input", "lost")]

    @property
    def input_errors(self) -> list[dict[str, Any]]:
        """The failures on bad input (a file to fix)."""
        return [r for r in self.failed if r.get("error_kind") == "input"]


def _existing_results(out_dir: Path) -> bool:
    from monovo_cli.pipeline.track import RESULT_FILES  # (not at import: it loads numpy)
    return any((out_dir / n).exists() for n in (*RESULT_FILES, DONE_FILE))


def run_batch(root: str | Path, out_root: str | Path, options: JobOptions | None = None, *,
              pattern: str | None = None, workers: int | None = None,
              scheduler: str | None = None, dask: bool = False, resume: bool = False,
              overwrite: bool = False, retries: int = 2, log_level: int = logging.WARNING,
              progress: Callable[[int, int], None] | None = None,
              task: Callable[..., dict] = track_one,
              summary_every_s: float = 5.0) -> BatchSummary:
    """``monovo batch``: track every sequence under ``root`` into ``out_root/<relative path>``.

    Sequences come from :func:`find_sequences` (``pattern``: a glob); a folder holding
    ``frames/`` but no ``init.yaml`` is logged and recorded as failed (bad input), not run.
    Each is tracked by
    ``task`` (:func:`track_one`, or a function of the same signature) with ``options``
    (:class:`~monovo_cli.pipeline.batch_job.JobOptions`, None for the defaults; the tasks
    get the dataclass itself, pickled), on a local pool of ``workers`` spawned processes
    (default: :func:`available_cores`), on a Dask LocalCluster of ``workers`` processes
    (``dask``), or on the Dask scheduler at ``scheduler`` (``tcp://HOST:PORT``; its workers
    must see ``root`` and ``out_root`` at the same paths and have monovo installed).

    ``resume``: skip the sequences whose outputs are complete (:func:`is_complete`) and
    recorded as a success, and redo the others -- a sequence that failed (more than half of
    its frames lost, :func:`recorded_failure`) is tracked again, so it is reported failed
    with its reason until it succeeds; ``overwrite``: redo all. Without either, an output
    folder that already holds results is an OutputError before anything runs. A sequence
    that fails is recorded and the others go on. ``out_root/summary.csv`` (:func:`write_summary`) is rewritten
    atomically at least every ``summary_every_s`` seconds while results come in, at the
    end, and when the batch is interrupted (unfinished sequences ``pending``); at the end (or
    the interruption) ``out_root/index.html`` too, every sequence's report.html linked, the
    failed ones first (:func:`~monovo_cli.pipeline.report.write_index`).
    ``progress(done, total)`` is called as sequences finish (skipped ones count as done).

    Raises MonovoError for a bad root, pattern, output root or executor (Dask missing or
    unreachable), TypeError for ``options`` that are not JobOptions.
    """
    t0 = time.perf_counter()
    root, out_root = Path(root), Path(out_root)
    opts = checked_job_options(options)
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
        res = result(seq_dir, out_dir, status="pending", worker="")
        missing = missing_init_yaml(seq_dir)
        if missing is not None:  # failed here, no worker started for it
            res = result(seq_dir, out_dir, error=missing, error_kind="input", worker="")
            log.warning("%s: %s", name, missing)
        elif resume:
            complete, why = is_complete(seq_dir, out_dir, opts)
            failure = recorded_failure(out_dir) if complete else None
            if complete and failure is None:
                res = done_result(seq_dir, out_dir)
            elif failure is not None:
                log.info("%s: redone (it failed: %s)", name, failure)
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
        relog(name, res)
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
        from monovo_cli.pipeline.report import write_index

        write_index(out_root, results)
    return BatchSummary(results, time.perf_counter() - t0, summary_path, executor,
                        None if scheduler else workers)
