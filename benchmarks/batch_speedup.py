"""monovo batch: wall time of 1 vs 2 local workers, and Dask-vs-local byte identity.

    python -m benchmarks.batch_speedup --sequences 8 --frames 200 --size 256x256 --repeats 3

Synthesizes ``--sequences`` drives once (``monovo synth --preset drive``, different seeds),
then tracks the archive with ``monovo batch``'s library call (:func:`run_batch`) on the
local process pool with 1 and with 2 workers, interleaved ``--repeats`` times so both see
the same load; then on Dask with 2 single-threaded worker processes, once with ``--dask``
(a LocalCluster started and stopped inside the batch) and once on a LocalCluster already
running (``--scheduler``). Wall times include starting the pool (and the ``--dask``
cluster). Prints a markdown table -- wall time, the ratio to the 1-worker run before it
(acceptance: <= 0.6 for 2 workers on 2 cores), the workers' CPU time, the load average
before each run -- then whether every sequence's motion.csv, trajectory.csv,
trajectory.tum and trajectory.png are byte-identical between the executors.
"""

from __future__ import annotations

import argparse
import atexit
import os
import resource
import shutil
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def _code_snapshot() -> None:
    """Import monovo_cli from a copy taken now, here and in every worker (sys.path, which
    spawned processes inherit, and PYTHONPATH): in a working tree others edit, code changed
    during the run would reach the workers started later and void the identity check."""
    snap = Path(tempfile.mkdtemp(prefix="monovo-code-"))
    atexit.register(shutil.rmtree, snap, True)
    shutil.copytree(Path(__file__).resolve().parent.parent / "monovo_cli", snap / "monovo_cli",
                    ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, str(snap))
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(snap), os.environ.get("PYTHONPATH"))
                                               if p)


if __name__ == "__main__":  # not in spawned workers (__mp_main__): they get the parent's path
    _code_snapshot()

from benchmarks.common import machine  # noqa: E402
from benchmarks.docs_section import writes_section  # noqa: E402
from monovo_cli.pipeline.batch import run_batch  # noqa: E402
from monovo_cli.synth.write import synthesize  # noqa: E402

COMPARED = ("motion.csv", "trajectory.csv", "trajectory.tum", "trajectory.png")


def _synth(args: tuple[Path, int, tuple[int, int], int]) -> None:
    out, frames, size, seed = args
    synthesize(out, preset="drive", frames=frames, size=size, seed=seed)


def make_archive(root: Path, sequences: int, frames: int, size: tuple[int, int]) -> None:
    """``sequences`` drives of ``frames`` frames in ``root/drive_NN`` (seeds 0, 1, ...)."""
    jobs = [(root / f"drive_{i:02d}", frames, size, i) for i in range(sequences)
            if not (root / f"drive_{i:02d}" / "groundtruth.tum").is_file()]
    with ProcessPoolExecutor(max_workers=os.cpu_count()) as ex:
        list(ex.map(_synth, jobs))


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _machine_busy_cpu() -> float | None:
    """CPU seconds all processes of the machine have used since boot (/proc/stat), or None."""
    try:
        v = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    except (OSError, ValueError):
        return None
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")  # all but idle and iowait


def timed_batch(root: Path, out: Path, **kw) -> dict:
    """One batch into ``out``: ``wall`` s; ``cpu`` s of this process and its finished
    children (the pool's workers, a --dask cluster's); ``others`` CPU s the rest of the
    machine used meanwhile (the competition: ~0 on an idle machine; None where the
    workers are not our children, i.e. on a cluster already up); ``load`` before."""
    shutil.rmtree(out, ignore_errors=True)
    load = os.getloadavg()[0]
    busy0, cpu0 = _machine_busy_cpu(), _children_cpu() + time.process_time()
    t0 = time.perf_counter()
    s = run_batch(root, out, **kw)
    wall = time.perf_counter() - t0
    cpu = _children_cpu() + time.process_time() - cpu0
    busy1 = _machine_busy_cpu()
    bad = [r["sequence"] for r in s.results if r["status"] != "ok"]
    if bad:
        raise SystemExit(f"sequences failed: {bad}")
    others = None
    if busy0 is not None and busy1 is not None and "scheduler" not in kw:
        others = max(0.0, busy1 - busy0 - cpu)
    return {"wall": wall, "cpu": cpu if "scheduler" not in kw else None, "others": others,
            "load": load}


def identical(a: Path, b: Path, names: list[str]) -> list[str]:
    """The ``seq/file`` paths whose bytes differ between output roots ``a`` and ``b``."""
    return [f"{n}/{f}" for n in names for f in COMPARED
            if (a / n / f).read_bytes() != (b / n / f).read_bytes()]


@writes_section("batch", "Batch throughput: `monovo batch`, 1 and 2 workers", "benchmarks.batch_speedup")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sequences", type=int, default=8)
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-dask", action="store_true", help="Skip the Dask LocalCluster run.")
    ap.add_argument("--keep", type=Path, default=None,
                    help="Keep the synthesized archive here (reused when it is there).")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    import monovo_cli

    print(f"machine: {machine()}")
    print(f"code: a copy of monovo_cli/ taken at the start ({Path(monovo_cli.__file__).parent})\n")
    tmp = Path(tempfile.mkdtemp(prefix="monovo-batch-bench-"))
    root = args.keep or tmp / "archive"
    try:
        t0 = time.perf_counter()
        make_archive(root, args.sequences, args.frames, (w, h))
        print(f"archive: {args.sequences} drives of {args.frames} frames, {w}x{h}, in {root} "
              f"(synthesized in {time.perf_counter() - t0:.0f} s)\n")
        names = [f"drive_{i:02d}" for i in range(args.sequences)]
        rows = []  # (run, executor, workers, timed_batch's dict, ratio to 1 worker)
        for r in range(1, args.repeats + 1):
            one = timed_batch(root, tmp / "local1", workers=1)
            two = timed_batch(root, tmp / "local2", workers=2)
            rows += [(r, "local", 1, one, None), (r, "local", 2, two, two["wall"] / one["wall"])]
        diffs = {"local 1 vs 2 workers": identical(tmp / "local1", tmp / "local2", names)}
        if not args.no_dask:
            from distributed import LocalCluster

            one_wall = rows[-2][3]["wall"]
            # --dask: a LocalCluster started and stopped inside the batch
            dask = timed_batch(root, tmp / "dask2", workers=2, dask=True)
            rows.append((args.repeats, "dask, --dask (cluster start included)", 2, dask,
                         dask["wall"] / one_wall))
            # a cluster already running, as with --scheduler
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
                up = timed_batch(root, tmp / "dask2up", scheduler=cluster.scheduler_address)
            rows.append((args.repeats, "dask, --scheduler (cluster already up)", 2, up,
                         up["wall"] / one_wall))
            diffs["dask vs local"] = (identical(tmp / "local2", tmp / "dask2", names)
                                      + identical(tmp / "local2", tmp / "dask2up", names))

        def num(x, spec):
            return "" if x is None else format(x, spec)

        print("| run | executor | workers | wall (s) | ratio to 1 worker | our CPU (s) | "
              "others' CPU meanwhile (s) | load before |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for run, ex, n, t, ratio in rows:
            print(f"| {run} | {ex} | {n} | {t['wall']:.1f} | {num(ratio, '.2f')} | "
                  f"{num(t['cpu'], '.1f')} | {num(t['others'], '.1f')} | {t['load']:.1f} |")
        walls = {n: [t["wall"] for _, ex, w, t, _ in rows if ex == "local" and w == n]
                 for n in (1, 2)}
        ratios = [ratio for _, ex, w, _, ratio in rows if ex == "local" and w == 2]
        print(f"\nbest of {args.repeats}: 1 worker {min(walls[1]):.1f} s, 2 workers "
              f"{min(walls[2]):.1f} s, ratio {min(walls[2]) / min(walls[1]):.2f}; median of the "
              f"paired ratios {statistics.median(ratios):.2f}\n")
        for what, bad in diffs.items():
            files = len(names) * len(COMPARED) * (2 if what.startswith("dask") else 1)
            print(f"{what}: {files - len(bad)}/{files} files byte-identical "
                  f"({', '.join(COMPARED)})" + (f"; differ: {', '.join(bad)}" if bad else ""))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
