"""The archive in numbers: a throughput model of ``monovo batch`` built from measured parts.

    python -m benchmarks.throughput                                  # measure, model, check
    python -m benchmarks.throughput --frames 30 --check 4 60 256     # the defaults
    python -m benchmarks.throughput --save parts.json                # keep the measured parts
    python -m benchmarks.throughput --parts parts.json --no-check    # the model only, no runs

**Measured on this machine** (one core per sequence, as ``monovo batch`` runs it):

* **per frame, by size** (256², 512², 1024²): ``track_one`` -- ``monovo batch``'s
  per-sequence function -- in this process on a ``--frames``-frame and on a 2-frame drive
  (``monovo synth --preset drive``, noise variance 10); the slope between the two is the
  cost of one more frame (reading it from the page cache, decoding, tracking, its rows),
  the intercept the **per-sequence** cost in the worker (opening the sequence, frame 0's
  ground model, frame 1's search without a prediction, trajectory files, trajectory.png,
  report.html, the inputs' fingerprint, done.json). ``benchmarks.profile`` splits the frame
  loop of the long drive into its parts (decode, pyramid, estimator, acceptance, other);
* **bytes**: the PNG bytes a frame reads, and the bytes a sequence writes (per frame and
  per sequence, from the two drives' output folders);
* **per batch**: ``run_batch`` on one 2-frame sequence with 1 worker less the sequence's
  own time: starting the spawned worker (interpreter, numpy, OpenCV, monovo imports),
  discovery, summary.csv and index.html; and **per sequence on the executor**: ``run_batch``
  on ``--tiny`` 2-frame sequences against one;
* **Dask** (when ``dask.distributed`` is installed): the same two on a LocalCluster of one
  single-threaded worker already up (``--scheduler``), the cluster's start, and the
  scheduler's time per task (no-op tasks through it);
* **a frame inside the workers**: one batch over the drives above per executor -- the local
  pool; the pool with ``MALLOC_TRIM_THRESHOLD_=65536`` in its environment; ``--dask`` with
  Dask's default configuration, whose nanny sets that variable for its workers; ``--dask``
  with it unset (``distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_: null``) --
  timed by the worker (its CPU time around ``track_one``). Setting the variable turns off
  glibc's adaptive mmap threshold, so every large temporary array is mapped, faulted in and
  unmapped again: frames cost 1.5-2x. A Dask nanny started in a process also writes the
  variable into that process's environment, and every process it spawns later inherits it;
  the script puts the environment back after each Dask run, so the local pool's figures and
  the check are not slowed.

**The model** (:func:`predict`). N frames of side S in sequences of L frames (n = ⌈N/L⌉
sequences, each tracked by one worker from start to end) on M nodes of C cores (P = M·C
single-threaded workers):

    T_seq    = t_seq(S) + t_task + L · (t_frame(S) + t_fetch)      one sequence, on one core
    makespan = ⌈n / P⌉ · T_seq                                     the workers' rounds
    read     = (N · (b_in(S) + b_out(S)) + n · b_seq(S)) / min(B, M · b_node)
    sched    = n · t_sched                                         serial at the scheduler
    wall     = t_start + max(makespan, read, sched)

The makespan's parts are printed apart: compute ⌈n/P⌉·L·t_frame, per-sequence overheads
⌈n/P⌉·(t_seq + t_task), waits for files ⌈n/P⌉·L·t_fetch.

``t_fetch`` is the wait for a frame's file that the worker's one thread cannot hide (a
per-file latency plus the bytes at one stream's speed), ``B`` the shared file system's
aggregate bandwidth, ``b_node`` a node's network: assumptions, printed with the answer.
When n ≤ P every sequence runs at once and the makespan is one sequence's time: more nodes
cannot help, only shorter sequences can.

The answer for a cluster takes the per-frame and per-sequence parts and the workers' start
in CPU time (what a dedicated core would take; this machine is shared), the executor's
dispatch and scheduler time in wall time, Dask's when it is installed.

**The check** runs ``benchmarks.batch_speedup``'s measurement (its ``make_archive`` and
``timed_batch``) with 1 and with 2 workers right after the parts were measured, with the
frames in the page cache (no storage term), and compares: its wall time with the model's
from the parts in wall time and from those in CPU time; the same on the cores the other
processes of the machine left free meanwhile (``timed_batch`` measures their CPU); and the
batch's CPU time (this process and its workers) with the sum of the parts.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import json
import math
import os
import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from benchmarks.docs_section import writes_section

SIZES = (256, 512, 1024)
GB = 1e9

# --------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class Parts:
    """The measured parts. Seconds and bytes; the dicts are by image side (px).

    ``frame_s``: one more frame of a sequence on one core (read from the page cache,
    decoded, tracked, written). ``seq_s``: a sequence's fixed cost in its worker (open,
    frame 0's model, frame 1's search, outputs, done.json). ``in_bytes``: bytes read per
    frame; ``out_frame_bytes`` / ``out_seq_bytes``: bytes written per frame / per sequence.
    ``start_s``: per batch, starting the workers (in parallel, one per core) and finishing
    (summary.csv, index.html). ``task_s``: per sequence, the executor's own cost on the
    worker's core (pickling, dispatch, the result). ``sched_s``: per sequence, serial at
    the scheduler (0 for the local pool, whose parent is not the limit at these rates).
    """

    frame_s: dict[int, float]
    seq_s: dict[int, float]
    in_bytes: dict[int, float]
    out_frame_bytes: dict[int, float]
    out_seq_bytes: dict[int, float]
    start_s: float
    task_s: float
    sched_s: float = 0.0

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> Parts:
        by_size = {k: {int(s): float(v) for s, v in d[k].items()}
                   for k in ("frame_s", "seq_s", "in_bytes", "out_frame_bytes", "out_seq_bytes")}
        return cls(**by_size, start_s=float(d["start_s"]), task_s=float(d["task_s"]),
                   sched_s=float(d.get("sched_s", 0.0)))


@dataclass(frozen=True)
class Storage:
    """Where the frames are read from (assumptions). ``shared_Bps``: the shared file
    system's aggregate bandwidth, bytes/s (``inf``: not a limit, e.g. the page cache);
    ``node_Bps``: one node's network; ``latency_s`` and ``stream_Bps``: a worker's wait for
    one frame's file (open and first byte; one stream's speed), which its single thread
    does not overlap with tracking."""

    shared_Bps: float = 10 * GB
    node_Bps: float = 1.25 * GB  # 10 Gb/s
    latency_s: float = 0.001
    stream_Bps: float = 0.5 * GB

    def fetch_s(self, nbytes: float) -> float:
        """Seconds a worker waits for a file of ``nbytes``."""
        return self.latency_s + (nbytes / self.stream_Bps if math.isfinite(self.stream_Bps) else 0.0)


#: Storage that is no limit: frames in the page cache (this machine's check).
PAGE_CACHE = Storage(shared_Bps=math.inf, node_Bps=math.inf, latency_s=0.0, stream_Bps=math.inf)


@dataclass(frozen=True)
class Prediction:
    """What :func:`predict` gives, seconds. ``compute``/``overhead``/``fetch`` are the
    makespan's parts (frames tracked, per-sequence costs, waits for files), ``makespan``
    their sum; ``read`` the storage bound, ``sched`` the scheduler's; ``wall`` the answer;
    ``bound`` which term sets it."""

    sequences: int
    slots: int
    busy: int
    waves: int
    seq_time: float
    compute: float
    overhead: float
    fetch: float
    makespan: float
    read: float
    sched: float
    start: float
    wall: float
    bound: str


def predict(parts: Parts, *, frames: int, side: int, seq_len: int, nodes: int, cores: int,
            storage: Storage = PAGE_CACHE) -> Prediction:
    """Wall time of ``monovo batch`` over ``frames`` frames of ``side``² in sequences of
    ``seq_len`` frames on ``nodes`` x ``cores`` single-threaded workers (module docstring)."""
    if min(frames, seq_len, nodes, cores) < 1:
        raise ValueError("frames, seq_len, nodes and cores must be >= 1")
    n = math.ceil(frames / seq_len)
    slots = nodes * cores
    waves = math.ceil(n / slots)
    fetch_frame = storage.fetch_s(parts.in_bytes[side])
    per_seq = parts.seq_s[side] + parts.task_s
    seq_time = per_seq + seq_len * (parts.frame_s[side] + fetch_frame)
    compute = waves * seq_len * parts.frame_s[side]
    overhead = waves * per_seq
    fetch = waves * seq_len * fetch_frame
    makespan = waves * seq_time
    nbytes = frames * (parts.in_bytes[side] + parts.out_frame_bytes[side]) + n * parts.out_seq_bytes[side]
    bandwidth = min(storage.shared_Bps, nodes * storage.node_Bps)
    read = nbytes / bandwidth if math.isfinite(bandwidth) else 0.0
    sched = n * parts.sched_s
    top = max(makespan, read, sched)
    if top == makespan:
        bound = "sequence length" if n <= slots and slots > 1 else "compute"
    elif top == read:
        bound = "storage" if storage.shared_Bps <= nodes * storage.node_Bps else "node network"
    else:
        bound = "scheduler"
    return Prediction(n, slots, min(n, slots), waves, seq_time, compute, overhead, fetch,
                      makespan, read, sched, parts.start_s, parts.start_s + top, bound)


def duration(s: float) -> str:
    """Seconds as a short human figure: '42 s', '3.5 min', '2.1 h', '1.3 d'."""
    if s < 100:
        return f"{s:.3g} s"
    if s < 6000:
        return f"{s / 60:.3g} min"
    if s < 48 * 3600:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} d"


def scale_table(parts: Parts, *, frames: int, side: int, seq_len: int, nodes: list[int],
                cores: int, storage: Storage) -> str:
    """Markdown: the prediction per number of nodes."""
    lines = ["| nodes | workers busy / all | sequence rounds | compute (frames) | per-sequence "
             "overheads | waits for files | read at min(B, M·b_node) | scheduler | wall | bound |",
             "|" + " --- |" * 10]
    for m in nodes:
        p = predict(parts, frames=frames, side=side, seq_len=seq_len, nodes=m, cores=cores,
                    storage=storage)
        lines.append(f"| {m} | {p.busy} / {p.slots} | {p.waves} | {duration(p.compute)} | "
                     f"{duration(p.overhead)} | {duration(p.fetch)} | {duration(p.read)} | "
                     f"{duration(p.sched)} | **{duration(p.wall)}** | {p.bound} |")
    return "\n".join(lines)


# --------------------------------------------------------------------------- measuring


def _timed(fn, *args, **kwargs) -> tuple[float, float, object]:
    """(wall s, CPU s of this process, result) of one call."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return time.perf_counter() - w0, time.process_time() - c0, out


def _folder_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in Path(path).rglob("*") if p.is_file())


@dataclass
class SizeParts:
    """One image size's measurements: ``track_one`` on the long and on the 2-frame drive,
    interleaved pairs of (wall, CPU) seconds; the profile of the long drive; bytes; and
    ``is_complete`` on the long drive's outputs."""

    side: int
    frames: int
    longs: list[tuple[float, float]]
    shorts: list[tuple[float, float]]
    profile: object  # benchmarks.profile.Profile
    png_bytes: float
    out_long: int
    out_short: int
    resume_check_s: float
    others: float | None = None  # cores the machine's other processes used meanwhile (mean)

    def frame_s(self, cpu: bool = False) -> float:
        """Median over the pairs of the slope: one more frame, s."""
        k = 1 if cpu else 0
        return statistics.median((lo[k] - sh[k]) / (self.frames - 2)
                                 for lo, sh in zip(self.longs, self.shorts))

    def seq_s(self, cpu: bool = False) -> float:
        """Median over the pairs of the intercept: a sequence's fixed cost, s."""
        k = 1 if cpu else 0
        return statistics.median(sh[k] - 2 * (lo[k] - sh[k]) / (self.frames - 2)
                                 for lo, sh in zip(self.longs, self.shorts))

    def median(self, which: str, cpu: bool = False) -> float:
        return statistics.median(t[1 if cpu else 0] for t in getattr(self, which))

    @property
    def out_frame_bytes(self) -> float:
        return (self.out_long - self.out_short) / (self.frames - 2)

    @property
    def out_seq_bytes(self) -> float:
        return self.out_short - 2 * self.out_frame_bytes


def measure_size(side: int, frames: int, tmp: Path, seed: int = 0, repeats: int = 3) -> SizeParts:
    """Render a ``frames``-frame and a 2-frame drive of ``side``² and time ``track_one`` on
    them in ``repeats`` interleaved pairs (after a first call that warms the caches), profile
    the long one, count bytes, time ``is_complete`` on the long one's outputs."""
    from benchmarks import profile
    from benchmarks.batch_speedup import _machine_busy_cpu
    from monovo_cli.pipeline.batch_job import is_complete, track_one
    from monovo_cli.synth.write import synthesize

    long_seq, short_seq = tmp / f"drive_{side}", tmp / f"pair_{side}"
    synthesize(long_seq, preset="drive", frames=frames, size=(side, side), noise_var=10.0, seed=seed)
    synthesize(short_seq, preset="drive", frames=2, size=(side, side), noise_var=10.0, seed=seed)
    track_one(short_seq, tmp / f"warm_{side}", overwrite=True)
    busy0, w0, c0 = _machine_busy_cpu(), time.perf_counter(), time.process_time()
    longs, shorts = [], []
    for seq, out, into in ((short_seq, "pair", shorts), (long_seq, "drive", longs)) * repeats:
        w, c, res = _timed(track_one, seq, tmp / f"out_{out}_{side}", overwrite=True)
        if res["status"] != "ok":
            raise SystemExit(f"{seq}: {res['error']}")
        into.append((w, c))
    prof = profile.profile_drive(long_seq, tmp / f"prof_{side}")
    busy1, w1, c1 = _machine_busy_cpu(), time.perf_counter(), time.process_time()
    others = None if busy0 is None or busy1 is None else max(0.0, busy1 - busy0 - (c1 - c0)) / (w1 - w0)
    pngs = sorted((long_seq / "frames").glob("*.png"))
    t0 = time.perf_counter()
    complete, why = is_complete(long_seq, tmp / f"out_drive_{side}")
    resume_check = time.perf_counter() - t0
    if not complete:
        raise SystemExit(f"is_complete: {why}")
    return SizeParts(side, frames, longs, shorts, prof,
                     statistics.mean(p.stat().st_size for p in pngs),
                     _folder_bytes(tmp / f"out_drive_{side}"), _folder_bytes(tmp / f"out_pair_{side}"),
                     resume_check, others)


def _noop(x):
    return x


@dataclass
class ExecutorParts:
    """Seconds: per batch (``start``) and per sequence on the executor (``task``), from
    ``run_batch`` on 1 and on ``k`` 2-frame 256² sequences with one worker, less the
    sequences' own time; the ``run_batch`` walls (and CPU: this process and its children,
    the local pool only) they come from; for Dask also the cluster's start and the
    scheduler's time per no-op task."""

    name: str
    one: float
    many: float
    k: int
    start: float
    task: float
    one_cpu: float | None = None
    many_cpu: float | None = None
    start_cpu: float | None = None
    task_cpu: float | None = None
    cluster_start: float | None = None
    sched: float | None = None


def measure_executor(name: str, one_root: Path, many_root: Path, k: int,
                     seq: tuple[float, float], tmp: Path, repeats: int = 3) -> ExecutorParts:
    """``name`` 'local' (a fresh process pool per batch) or 'dask' (a LocalCluster of one
    single-threaded worker, up before the batches; ``--scheduler``). ``seq``: (wall, CPU)
    of one of the 2-frame sequences tracked in this process."""
    from benchmarks.batch_speedup import timed_batch

    def runs(**kw) -> tuple[dict, dict]:
        ones = [timed_batch(one_root, tmp / f"{name}_one", **kw) for _ in range(repeats)]
        many = timed_batch(many_root, tmp / f"{name}_many", **kw)
        mid = sorted(ones, key=lambda t: t["wall"])[len(ones) // 2]
        return mid, many

    cluster_start = sched = None
    if name == "local":
        one, many = runs(workers=1)
    else:
        from distributed import Client, LocalCluster

        saved = dict(os.environ)  # the nanny writes its pre-spawn-environ into ours
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        cluster_start = time.perf_counter() - t0
        try:
            addr = cluster.scheduler_address
            timed_batch(one_root, tmp / "dask_warm", scheduler=addr)  # the worker's imports
            one, many = runs(scheduler=addr)
            with Client(addr) as client:
                client.gather(client.map(_noop, range(50), pure=False))  # warm
                n = 1000
                t0 = time.perf_counter()
                client.gather(client.map(_noop, range(n), pure=False))
                sched = (time.perf_counter() - t0) / n
        finally:
            cluster.close()
            _restore_environ(saved)
    task = (many["wall"] - one["wall"]) / (k - 1) - seq[0]
    start = one["wall"] - seq[0] - max(0.0, task)  # a negative task: noise, counted as 0
    ex = ExecutorParts(name, one["wall"], many["wall"], k, start, task,
                       cluster_start=cluster_start, sched=sched)
    if one["cpu"] is not None:
        ex.one_cpu, ex.many_cpu = one["cpu"], many["cpu"]
        ex.task_cpu = (many["cpu"] - one["cpu"]) / (k - 1) - seq[1]
        ex.start_cpu = one["cpu"] - seq[1] - max(0.0, ex.task_cpu)
    return ex


def _restore_environ(saved: dict[str, str]) -> None:
    """Put ``os.environ`` back as ``saved``: a Dask nanny started in this process writes its
    ``distributed.nanny.pre-spawn-environ`` (``MALLOC_TRIM_THRESHOLD_``, ``PYTHONHASHSEED``)
    into it, and every process spawned later -- a local pool's workers -- would inherit it."""
    for k in set(os.environ) - set(saved):
        del os.environ[k]
    os.environ.update(saved)


#: The executors :func:`worker_frame_costs` compares: (label, run_batch's keywords, variables
#: set in this process's environment meanwhile, Dask configuration meanwhile).
WORKER_SETUPS = (
    ("local process pool", {"workers": 1}, {}, {}),
    ("local process pool, MALLOC_TRIM_THRESHOLD_=65536 in its environment", {"workers": 1},
     {"MALLOC_TRIM_THRESHOLD_": "65536"}, {}),
    ("Dask LocalCluster (`--dask`), Dask's default configuration", {"workers": 1, "dask": True},
     {}, {}),
    ("Dask LocalCluster (`--dask`), `distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_` "
     "unset", {"workers": 1, "dask": True}, {},
     {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}),
)


@dataclass
class WorkerFrames:
    """ms per frame in one executor's worker, by side, from the long drive less the 2-frame
    drive over (frames - 2): ``wall`` from ``summary.csv``'s ``seconds`` (the frame loop's
    wall time), ``cpu`` the worker process's CPU time over the whole task."""

    label: str
    wall: dict[int, float]
    cpu: dict[int, float]


def cpu_timed_track_one(seq_dir, out_dir, options=None, *, overwrite=False, single_thread=True) -> dict:
    """:func:`track_one` with the CPU time of the worker process over it (``cpu_s``): a task
    for ``run_batch(task=...)``, importable by a Dask worker."""
    from monovo_cli.pipeline.batch_job import track_one

    c0 = time.process_time()
    res = track_one(seq_dir, out_dir, options, overwrite=overwrite, single_thread=single_thread)
    return {**res, "cpu_s": time.process_time() - c0}


def _slope(results: dict[str, dict], key: str, i: int, sz: SizeParts) -> float:
    """ms per frame between the ``i``-th size's 2-frame and long drive's ``key`` seconds."""
    a, b = results[f"{i}_{sz.side}_a_pair"][key], results[f"{i}_{sz.side}_b_drive"][key]
    return 1000 * (b - a) / (sz.frames - 2)


def worker_frame_costs(sizes: list[SizeParts], tmp: Path, dask: bool = True) -> list[WorkerFrames]:
    """The per-frame cost inside each of :data:`WORKER_SETUPS`' workers: one batch over the
    drives :func:`measure_size` rendered (a 2-frame drive first, to warm the worker up; then
    each size's 2-frame and long drive), on one worker. Dask setups only with ``dask``."""
    from monovo_cli.pipeline.batch import run_batch

    root = tmp / "worker_archive"
    root.mkdir(exist_ok=True)
    first = sizes[0].side
    shutil.copytree(tmp / f"pair_{first}", root / "0_warm")  # (a link: found once, as its target)
    for i, sz in enumerate(sizes, start=1):
        (root / f"{i}_{sz.side}_a_pair").symlink_to(tmp / f"pair_{sz.side}", target_is_directory=True)
        (root / f"{i}_{sz.side}_b_drive").symlink_to(tmp / f"drive_{sz.side}", target_is_directory=True)
    out = []
    for label, kw, env, config in WORKER_SETUPS:
        if kw.get("dask") and not dask:
            continue
        saved = dict(os.environ)
        os.environ.update(env)
        try:
            with contextlib.ExitStack() as stack:
                if config:
                    import dask as dask_config

                    stack.enter_context(dask_config.config.set(config))
                res = run_batch(root, tmp / "worker_out", overwrite=True, task=cpu_timed_track_one, **kw)
        finally:
            _restore_environ(saved)
        bad = [r["sequence"] for r in res.results if r["status"] != "ok"]
        if bad:
            raise SystemExit(f"{label}: failed {bad}")
        by = {r["sequence"]: r for r in res.results}

        out.append(WorkerFrames(label, *({sz.side: _slope(by, key, i, sz) for i, sz in enumerate(sizes, 1)}
                                         for key in ("seconds", "cpu_s"))))
    return out


def worker_table(rows: list[WorkerFrames], sizes: list[SizeParts]) -> str:
    """Markdown: ms per frame in each executor's worker, wall (CPU in brackets), and the ratio
    of the CPU figure to the local pool's."""
    base = rows[0].cpu
    head = " | ".join(f"{s.side}² ms/frame | × local (CPU)" for s in sizes)
    lines = [f"| executor (one worker) | {head} |", "|" + " --- |" * (1 + 2 * len(sizes))]
    for r in rows:
        lines.append(f"| {r.label} | " + " | ".join(
            f"{r.wall[s.side]:.1f} ({r.cpu[s.side]:.1f}) | {r.cpu[s.side] / base[s.side]:.2f}"
            for s in sizes) + " |")
    lines.append("\n(in this process, `track_one`'s slope: " + ", ".join(
        f"{s.side}² {1000 * s.frame_s():.1f} ({1000 * s.frame_s(True):.1f}) ms" for s in sizes) + ")")
    return "\n".join(lines)


def parts_from(sizes: list[SizeParts], local: ExecutorParts, dask: ExecutorParts | None = None,
               *, cpu: bool) -> Parts:
    """The model's parts. ``cpu``: per frame, per sequence and the local pool's start and
    dispatch in CPU time (a dedicated core), else in wall time (this machine as it was).
    With ``dask``: its dispatch (wall) and scheduler time per sequence replace the pool's
    dispatch, and its client's start is added to the workers' start (spawn and imports, as
    the pool's). Negative figures (noise around a cost too small to see) count as 0."""
    start = local.start_cpu if cpu else local.start
    task = local.task_cpu if cpu else local.task
    sched = 0.0
    if dask is not None:
        start, task, sched = start + max(0.0, dask.start), dask.task, dask.sched or 0.0
    return Parts(frame_s={s.side: s.frame_s(cpu) for s in sizes},
                 seq_s={s.side: s.seq_s(cpu) for s in sizes},
                 in_bytes={s.side: s.png_bytes for s in sizes},
                 out_frame_bytes={s.side: s.out_frame_bytes for s in sizes},
                 out_seq_bytes={s.side: s.out_seq_bytes for s in sizes},
                 start_s=max(0.0, start), task_s=max(0.0, task), sched_s=max(0.0, sched))


# --------------------------------------------------------------------------- tables


def parts_table(sizes: list[SizeParts]) -> str:
    """Markdown: the measured per-size parts, wall (CPU in brackets)."""
    cols = " | ".join(f"{s.side}²" for s in sizes)
    lines = [f"| part | {cols} |", "|" + " --- |" * (1 + len(sizes))]

    def row(label, cells):
        lines.append(f"| {label} | " + " | ".join(cells) + " |")

    row("**t_frame**: one more frame, ms (`track_one`, slope between the two drives)",
        [f"**{1000 * s.frame_s():.1f}** ({1000 * s.frame_s(True):.1f})" for s in sizes])
    for part in ("decode", "pyramid", "estimator", "acceptance", "other"):
        row(f"&nbsp;&nbsp;profile: {part}, ms/frame",
            [f"{s.profile.ms_per_frame(part):.1f} ({s.profile.ms_per_frame(part, cpu=True):.1f})"
             for s in sizes])
    row("&nbsp;&nbsp;profile: frame loop, ms/frame (frame 0's model and frame 1's search "
        "spread over the drive)",
        [f"{1000 * s.profile.loop / s.profile.frames:.1f} "
         f"({1000 * s.profile.loop_cpu / s.profile.frames:.1f})" for s in sizes])
    row("**t_seq**: a sequence's fixed cost in its worker, s (intercept)",
        [f"**{s.seq_s():.2f}** ({s.seq_s(True):.2f})" for s in sizes])
    row(f"&nbsp;&nbsp;`track_one` on the 2-frame drive, s (median of {len(sizes[0].shorts)})",
        [f"{s.median('shorts'):.2f} ({s.median('shorts', True):.2f})" for s in sizes])
    row(f"&nbsp;&nbsp;`track_one` on the {sizes[0].frames}-frame drive, s (median of "
        f"{len(sizes[0].longs)})",
        [f"{s.median('longs'):.2f} ({s.median('longs', True):.2f})" for s in sizes])
    row("**b_in**: PNG bytes per frame (8-bit grey, noise variance 10)",
        [f"**{s.png_bytes / 1e3:.0f} kB**" for s in sizes])
    row("b_out: bytes written per frame (motion.csv, trajectory.csv/.tum rows; report.html, "
        "whose keyframe thumbnails stop at 16, adds to it over short drives)",
        [f"{s.out_frame_bytes:.0f} B" for s in sizes])
    row("b_seq: bytes written per sequence (trajectory.png, report.html, run.yaml, done.json)",
        [f"{s.out_seq_bytes / 1e3:.0f} kB" for s in sizes])
    row(f"`--resume`'s check of one finished {sizes[0].frames}-frame sequence "
        "(`is_complete`, in the submitting process), ms",
        [f"{1000 * s.resume_check_s:.1f}" for s in sizes])
    row("cores the machine's other processes used meanwhile (mean over the timed runs)",
        ["" if s.others is None else f"{s.others:.2f}" for s in sizes])
    return "\n".join(lines)


def executor_table(execs: list[ExecutorParts], seq: tuple[float, float]) -> str:
    """Markdown: the executors' costs, wall (CPU in brackets where measured)."""
    def both(w, c, spec):
        return format(w, spec) + ("" if c is None else f" ({format(c, spec)})")

    lines = ["| executor | `run_batch`, 1 sequence (s, median of 3) | `run_batch`, k sequences (s) | "
             "**t_start** per batch (s) | **t_task** per sequence (s) | cluster start (s) | "
             "**t_sched**, scheduler per no-op task (ms) |", "|" + " --- |" * 7]
    for e in execs:
        label = ("local process pool (spawned, 1 worker)" if e.name == "local"
                 else "Dask, LocalCluster of 1 worker already up (`--scheduler`)")
        lines.append(f"| {label} | {both(e.one, e.one_cpu, '.2f')} | "
                     f"{both(e.many, e.many_cpu, '.2f')} (k = {e.k}) | "
                     f"**{both(e.start, e.start_cpu, '.2f')}** | **{both(e.task, e.task_cpu, '+.3f')}** | "
                     f"{'' if e.cluster_start is None else f'{e.cluster_start:.1f}'} | "
                     f"{'' if e.sched is None else f'**{1000 * e.sched:.2f}**'} |")
    lines.append(f"\n(one 2-frame 256² sequence alone, `track_one` in this process: {seq[0]:.2f} s "
                 f"wall, {seq[1]:.2f} s CPU; t_task = (k sequences' batch - 1 sequence's) / (k - 1) "
                 "- that, shown as it came out and counted as 0 when negative (noise); t_start = "
                 "1 sequence's batch - that - t_task; the CPU is this process's and its "
                 "children's, the pool's workers)")
    return "\n".join(lines)


# --------------------------------------------------------------------------- the check


def fractional(parts: Parts, *, sequences: int, seq_len: int, side: int, cores: float) -> float:
    """Wall time of ``sequences`` sequences when only ``cores`` (a fraction, > 0) of the
    machine's cores are ours: the work shared out over them, never less than one sequence."""
    one = parts.seq_s[side] + parts.task_s + seq_len * parts.frame_s[side]
    return parts.start_s + max(one, sequences * one / cores)


def predicted_cpu(parts: Parts, *, sequences: int, seq_len: int, side: int, workers: int) -> float:
    """CPU seconds of a local batch: each worker's start (spawn, imports; the parent's
    bookkeeping counted with it), then every sequence's work."""
    used = min(workers, sequences)
    return used * parts.start_s + sequences * (parts.seq_s[side] + parts.task_s
                                               + seq_len * parts.frame_s[side])


@dataclass
class CheckRow:
    run: int
    workers: int
    wall: float
    cpu: float
    others: float | None
    load: float
    pred_wall: float      # parts in wall time, ``workers`` cores of our own
    pred_idle: float      # parts in CPU time, ``workers`` cores of our own
    pred_cpu: float       # CPU seconds of the batch
    free: float           # cores the other processes left us (at most ``workers``)
    pred_free: float      # parts in CPU time on ``free`` cores

    @property
    def quiet(self) -> bool:
        """The other processes used less than 0.2 core on average meanwhile."""
        return self.others is not None and self.others / self.wall < 0.2


def check(parts_wall: Parts, parts_cpu: Parts, sequences: int, frames: int, side: int,
          repeats: int, tmp: Path) -> list[CheckRow]:
    """``benchmarks.batch_speedup``'s runs (its archive and timer) with 1 and 2 workers,
    interleaved, each against the model."""
    from benchmarks.batch_speedup import make_archive, timed_batch

    root = tmp / "check_archive"
    make_archive(root, sequences, frames, (side, side))
    rows = []
    for r in range(1, repeats + 1):
        for w in (1, 2):
            t = timed_batch(root, tmp / f"check_{w}", workers=w)
            kw = {"frames": sequences * frames, "side": side, "seq_len": frames, "nodes": 1,
                  "cores": w}
            others = (t["others"] or 0.0) / t["wall"]  # cores the others used, on average
            free = min(float(w), max(0.1, (os.cpu_count() or 1) - others))
            rows.append(CheckRow(
                r, w, t["wall"], t["cpu"], t["others"], t["load"],
                predict(parts_wall, **kw).wall, predict(parts_cpu, **kw).wall,
                predicted_cpu(parts_cpu, sequences=sequences, seq_len=frames, side=side, workers=w),
                free, fractional(parts_cpu, sequences=sequences, seq_len=frames, side=side, cores=free)))
    return rows


def check_table(rows: list[CheckRow]) -> str:
    lines = ["| run | workers | measured wall (s) | predicted, parts in wall time (s) | measured / "
             "predicted | predicted, parts in CPU time (s) | measured / that | others' CPU "
             "meanwhile (s) | load before | cores the others left us | predicted on those, "
             "parts in CPU time (s) | measured / that | measured CPU (s) | predicted CPU (s) | "
             "measured / predicted |", "|" + " --- |" * 15]
    for c in rows:
        lines.append(
            f"| {c.run} | {c.workers} | {c.wall:.2f} | {c.pred_wall:.2f} | **{c.wall / c.pred_wall:.2f}** | "
            f"{c.pred_idle:.2f} | {c.wall / c.pred_idle:.2f} | "
            f"{'' if c.others is None else f'{c.others:.1f}'} | {c.load:.1f} | {c.free:.2f} | "
            f"{c.pred_free:.2f} | {c.wall / c.pred_free:.2f} | {c.cpu:.2f} | {c.pred_cpu:.2f} | "
            f"**{c.cpu / c.pred_cpu:.2f}** |")
    for w in (1, 2):
        all_ = [c.wall / c.pred_wall for c in rows if c.workers == w]
        quiet = [c.wall / c.pred_wall for c in rows if c.workers == w and c.quiet]
        lines.append(f"\n{w} worker(s): measured / predicted (parts in wall time) median "
                     f"{statistics.median(all_):.2f} over {len(all_)} run(s)"
                     + (f"; {statistics.median(quiet):.2f} over the {len(quiet)} run(s) in which the "
                        "other processes used less than 0.2 core" if quiet else
                        "; no run had the machine to itself (others < 0.2 core)"))
    return "\n".join(lines)


# --------------------------------------------------------------------------- main


def _uptime() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f}, {five:.2f}, {fifteen:.2f} on {os.cpu_count()} cores"


def measure(args, tmp: Path) -> dict[str, Parts]:
    """Measure the parts and print their tables: ``wall`` (this machine as it was, the local
    pool), ``cpu`` (dedicated cores, the local pool), ``cluster`` (as ``cpu`` with Dask's
    dispatch and scheduler when Dask is installed)."""
    from benchmarks.common import load
    from monovo_cli.pipeline.batch_job import track_one
    from monovo_cli.synth.write import synthesize

    sizes = []
    for side in args.sizes:
        sizes.append(measure_size(side, args.frames, tmp))
        print(f"({side}² measured, {load()})", file=sys.stderr)
    # the executors, on 2-frame 256² sequences (seeds 0..k-1)
    one_root, many_root = tmp / "one", tmp / "many"
    for i in range(args.tiny):
        synthesize(many_root / f"s{i:02d}", preset="drive", frames=2, size=(256, 256),
                   noise_var=10.0, seed=i)
    synthesize(one_root / "s00", preset="drive", frames=2, size=(256, 256), noise_var=10.0, seed=0)
    alone = [_timed(track_one, many_root / f"s{i:02d}", tmp / f"tiny_{i}", overwrite=True)[:2]
             for i in range(args.tiny)]
    seq = (statistics.mean(a[0] for a in alone), statistics.mean(a[1] for a in alone))
    local = measure_executor("local", one_root, many_root, args.tiny, seq, tmp)
    execs, dask_ex = [local], None
    have_dask = importlib.util.find_spec("distributed") is not None
    if not have_dask:
        print("Dask is not installed: its costs are not measured; the cluster figures use the "
              "local pool's.\n")
    elif not args.no_dask:
        dask_ex = measure_executor("dask", one_root, many_root, args.tiny, seq, tmp)
        execs.append(dask_ex)
    workers = worker_frame_costs(sizes, tmp, dask=have_dask and not args.no_dask)
    print(f"### Measured parts ({args.frames}-frame and 2-frame drives per size, one core; "
          "wall clock, CPU time of this process in brackets)\n")
    print(parts_table(sizes))
    print("\n### The executors' costs (2-frame 256² sequences, one worker)\n")
    print(executor_table(execs, seq))
    print("\n### A frame's cost inside the workers (one batch per executor over the drives above, "
          "one worker; `summary.csv`'s tracking seconds, the worker's CPU time in brackets)\n")
    print(worker_table(workers, sizes))
    print()
    parts = {"wall": parts_from(sizes, local, cpu=False), "cpu": parts_from(sizes, local, cpu=True),
             "cluster": parts_from(sizes, local, dask_ex, cpu=True)}
    dask_default = [w for w in workers if "default configuration" in w.label]
    if dask_default:  # the same cluster with Dask's per-frame slowdown, as measured here
        factor = {s: dask_default[0].cpu[s] / workers[0].cpu[s] for s in workers[0].cpu}
        cl = parts["cluster"]
        parts["cluster_dask_defaults"] = dataclasses.replace(
            cl, frame_s={s: cl.frame_s[s] * factor[s] for s in cl.frame_s})
    return parts


def report(args, parts: dict[str, Parts], storage: Storage) -> None:
    """The model's parts, the answer and the bottleneck tables."""
    cl = parts["cluster"]
    side = args.side
    if side not in cl.frame_s:
        raise SystemExit(f"--side {side} was not measured (--sizes)")
    print("### The model's parts for a cluster (per frame, per sequence and the workers' start "
          "in CPU time: dedicated cores; the executor's dispatch and scheduler in wall time)\n")
    print("| side | t_frame (ms) | t_seq (s) | b_in (kB) | b_out per frame (B) | b_seq (kB) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for s in sorted(cl.frame_s):
        print(f"| {s}² | {1000 * cl.frame_s[s]:.1f} | {cl.seq_s[s]:.2f} | {cl.in_bytes[s] / 1e3:.0f} | "
              f"{cl.out_frame_bytes[s]:.0f} | {cl.out_seq_bytes[s] / 1e3:.0f} |")
    print(f"\nt_start {cl.start_s:.2f} s per batch; t_task {1000 * cl.task_s:.0f} ms and t_sched "
          f"{1000 * cl.sched_s:.2f} ms per sequence\n")
    print(f"Storage (assumptions): a shared file system of B = {storage.shared_Bps / GB:g} GB/s "
          f"aggregate, b_node = {storage.node_Bps / GB:g} GB/s per node; a worker waits "
          f"{1000 * storage.latency_s:g} ms per file plus its bytes at {storage.stream_Bps / GB:g} "
          "GB/s\n")
    p = predict(cl, frames=args.archive, side=side, seq_len=args.seq_len, nodes=args.nodes,
                cores=args.cores, storage=storage)
    print(f"### The answer: {args.archive:,} frames of {side}² in sequences of {args.seq_len} on "
          f"{args.nodes} nodes x {args.cores} cores\n")
    print(f"**{duration(p.wall)}** ({p.wall:.0f} s), bound by {p.bound}: {p.sequences} sequences "
          f"on {p.slots} workers ({p.busy} busy, {p.waves} round(s) of {p.seq_time:.0f} s); "
          f"compute {duration(p.compute)}, per-sequence overheads {duration(p.overhead)}, waits "
          f"for files {duration(p.fetch)}, read {duration(p.read)}, scheduler {duration(p.sched)}, "
          f"start {duration(p.start)}; {args.archive * cl.frame_s[side] / 3600:.0f} CPU hours "
          "of tracking in all (workers at the local pool's speed per frame: on Dask, with "
          "its nanny's MALLOC_TRIM_THRESHOLD_ unset)\n")
    if "cluster_dask_defaults" in parts:
        d = parts["cluster_dask_defaults"]
        q = predict(d, frames=args.archive, side=side, seq_len=args.seq_len, nodes=args.nodes,
                    cores=args.cores, storage=storage)
        print(f"With Dask's default configuration (its nanny sets MALLOC_TRIM_THRESHOLD_=65536; "
              f"a frame costs {d.frame_s[side] / cl.frame_s[side]:.2f}x as measured above): "
              f"**{duration(q.wall)}**, bound by {q.bound} (one round of {q.seq_time:.0f} s; "
              f"{args.archive * d.frame_s[side] / 3600:.0f} CPU hours)\n")
    nodes = [1, 10, 100, 1000]
    for length in (args.seq_len, max(1, args.seq_len // 10)):
        print(f"#### Where the bottleneck moves: by nodes ({args.cores} cores each, sequences of "
              f"{length})\n")
        print(scale_table(cl, frames=args.archive, side=side, seq_len=length, nodes=nodes,
                          cores=args.cores, storage=storage))
        print()
    print(f"#### {args.nodes} nodes, by the shared file system's bandwidth B (sequences of "
          f"{args.seq_len})\n")
    print("| B (GB/s) | read | wall | bound |")
    print("| --- | --- | --- | --- |")
    for b in (1, 10, 100, 1000):
        q = predict(cl, frames=args.archive, side=side, seq_len=args.seq_len, nodes=args.nodes,
                    cores=args.cores,
                    storage=Storage(b * GB, storage.node_Bps, storage.latency_s, storage.stream_Bps))
        print(f"| {b} | {duration(q.read)} | **{duration(q.wall)}** | {q.bound} |")


@writes_section("throughput", "Throughput model of a cluster", "benchmarks.throughput")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    ap.add_argument("--frames", type=int, default=30, help="frames of the long drive per size")
    ap.add_argument("--tiny", type=int, default=6,
                    help="2-frame sequences for the executors' cost per sequence")
    ap.add_argument("--check", type=int, nargs=3, default=[4, 60, 256],
                    metavar=("SEQUENCES", "FRAMES", "SIDE"),
                    help="benchmarks.batch_speedup's archive for the check")
    ap.add_argument("--check-repeats", type=int, default=2)
    ap.add_argument("--no-check", action="store_true")
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--save", type=Path, help="write the measured parts (JSON) here")
    ap.add_argument("--parts", type=Path, help="use these parts (JSON from --save): no measuring")
    # the question
    ap.add_argument("--archive", type=int, default=1_000_000, help="frames in the archive")
    ap.add_argument("--side", type=int, default=1024)
    ap.add_argument("--seq-len", type=int, default=1000)
    ap.add_argument("--nodes", type=int, default=100)
    ap.add_argument("--cores", type=int, default=32)
    ap.add_argument("--shared-gbps", type=float, default=10.0,
                    help="shared file system, aggregate GB/s (assumption)")
    ap.add_argument("--node-gbps", type=float, default=1.25, help="per node GB/s (10 Gb/s)")
    ap.add_argument("--latency-ms", type=float, default=1.0, help="a worker's wait per file")
    ap.add_argument("--stream-gbps", type=float, default=0.5, help="one worker's read stream, GB/s")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    from benchmarks.common import load, machine, one_core

    one_core()
    print(f"Machine: {machine()}; {load()} at the start; uptime: {_uptime()}\n")
    storage = Storage(args.shared_gbps * GB, args.node_gbps * GB, args.latency_ms / 1000,
                      args.stream_gbps * GB)
    rows = None
    with tempfile.TemporaryDirectory(prefix="monovo-throughput-") as tmp_name:
        tmp = Path(tmp_name)
        if args.parts:
            saved = json.loads(args.parts.read_text())
            parts = {k: Parts.from_json(v) for k, v in saved.items() if k != "measured"}
            print(f"parts from {args.parts} (measured on {saved.get('measured', '?')})\n")
        else:
            parts = measure(args, tmp)
            if args.save:
                args.save.write_text(json.dumps({"measured": machine(),
                                                 **{k: v.to_json() for k, v in parts.items()}},
                                                indent=1) + "\n")
        if not args.no_check:
            s, f, side = args.check
            if side not in parts["wall"].frame_s:
                raise SystemExit(f"--check: side {side} was not measured (--sizes)")
            rows = check(parts["wall"], parts["cpu"], s, f, side, args.check_repeats, tmp)
    report(args, parts, storage)
    if rows:
        s, f, side = args.check
        print(f"\n### The check: `benchmarks.batch_speedup`'s runs ({s} drives of {f} frames, "
              f"{side}², local pool, 1 and 2 workers) against the model on this machine\n")
        print(check_table(rows))
    print(f"\n({load()} at the end; uptime: {_uptime()})")


if __name__ == "__main__":
    main()
