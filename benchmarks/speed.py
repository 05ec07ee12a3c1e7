"""Speed and memory: frames/s end to end and estimator-only, a per-stage profile, peak RSS.

    python -m benchmarks.speed                         # 200-frame drives at 4 sizes, ~6 min
    python -m benchmarks.speed --sizes 512x512 --frames 100
    python -m benchmarks.speed --memory                # only peak RSS over 500 and 5000 frames
                                                       # (renders 5000 frames once: ~10 min;
                                                       # --renders DIR keeps them for next time)
    python -m benchmarks.speed --threads 2 --no-profile  # both on two threads
    python -m benchmarks.speed --sizes 512x512 --frames 100 --no-profile --repeats 5
    python -m benchmarks.speed ... --write-docs        # + its section of docs/benchmarks.md
    python -m benchmarks.speed --against c65b42c --repeats 5   # this tree against a commit

For each size a ``monovo synth --preset drive`` sequence (noise variance 10, seed 0) is
rendered (not timed), then, on one core (OpenCV, BLAS and OpenMP on one thread):

* **end to end** -- ``runner.track_sequence`` into a temporary directory, as ``monovo track``
  runs it: PNG decoding, tracking, motion.csv streaming, trajectory files and plot. Frames/s
  over the whole call, and per frame between the first and the last frame (without the
  fixed start-up and final writing);
* **estimator only** -- the frames decoded into memory first, then ``odometry.estimate_frames``;
* **ECC peer** -- ``benchmarks.peers.EccPeer`` frame to frame on the same PNGs, decoding
  included, for the speed ratio: at OpenCV's own default stop (1e-3), what a user who picks
  ECC gets, and (a second column) at the peers tables' strict stop (1e-6);
* **stages** -- a cProfile of the end-to-end run, each function's own time attributed to the
  nearest enclosing stage: decode (``frames.read_gray``/``decode_gray``), pyramid
  (``pyramid.build_pyramid``), warp+sample (``estimate.residuals``, ``sample_at``,
  ``warp_grid``, ``_probe_move``: the points' homography and OpenCV's remap), normal equations
  (the rest of ``estimate._solve_level``: the weighted products O^T W O, O^T W r, the solve),
  robust weights (``robust_weights``, ``_rho*``), keyframes (``odometry.build_keyframe``:
  point selection at re-anchoring) and other. Profiling slows Python-heavy code more than
  numpy/OpenCV calls, so shares are approximate; ms/frame are the shares times the
  unprofiled end-to-end time.

``--threads N``: both methods on the same N threads instead: OpenCV's thread count for
monovo and ECC alike (the process runs both), and ``monovo track --threads N`` (frames
decoded ahead on a thread of their own from 2 on). BLAS stays on one thread (monovo pins it
while tracking; ECC's small matrices do not use it). On one core (the default) both run on
one thread: monovo as ``monovo track --threads 1``, decoding its frames in the frame loop as
ECC does (``monovo track`` itself decodes ahead on a second thread by default: timed that way
it would have a core more than ECC).

``--repeats K``: the measurement of each size K times over, monovo and ECC alternating (a
row each), then the ratios' median and range per size: on a shared machine whose speed
drifts within minutes, one pair says little.

``--against REV``: instead of ECC, monovo as it was at commit ``REV`` (its ``monovo_cli``
unpacked by ``git archive`` into a temporary folder) is the peer: ``python -m monovo_cli track
SEQ -o OUT --threads 1 -q`` run as a child process from this tree and from that one (BLAS,
OpenMP and OpenCV on one thread, ``benchmarks.common.child_env``), whole
process (start-up included, after an untimed run of each that writes its bytecode),
alternating which goes first, ``--repeats`` pairs per size (at least 3). Per size: the
median frames/s of each, the ratio pair by pair (median and range, wall and CPU; above 1
this tree is faster), and whether the two wrote the same motion.csv. Its table is a section
of its own.

``--memory``: peak resident memory (the child's own VmHWM, read at its exit) of a
``monovo track SEQ -o OUT -q`` subprocess over the first 500 and all 5000 frames of one
512x512 drive (the 500-frame sequence is a folder of symlinks to the first frames).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

from benchmarks.common import Stopwatch, child_env, final_drift, load, machine, one_core
from benchmarks.docs_section import printed_section
from benchmarks.peers import ECC_EPS_OPENCV, EccPeer, peer_on_drive
from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.synth.write import synthesize

ROOT = Path(__file__).resolve().parents[1]
SIZES = ("256x256", "512x512", "688x544", "1024x1024")
TARGET_FPS = {"256x256": 150.0, "512x512": 50.0, "1024x1024": 12.0}  # issue 5, end to end

# Stage of a monovo function (by name); functions not named here take the stage of their caller.
STAGES = {
    "read_gray": "decode", "decode_gray": "decode",
    "build_pyramid": "pyramid",
    "residuals": "warp+sample", "sample_at": "warp+sample", "warp_grid": "warp+sample",
    "_probe_move": "warp+sample",
    "_solve_level": "normal equations",
    "robust_weights": "robust weights", "_rho_sum": "robust weights", "mad_scale": "robust weights",
    "build_keyframe": "keyframes",
}
STAGE_ORDER = ("decode", "pyramid", "warp+sample", "normal equations", "robust weights",
               "keyframes", "other")


# --------------------------------------------------------------------------- timing


def end_to_end(seq: Path, out: Path, threads: int | None = 1) -> dict:
    """``runner.track_sequence`` timed as a whole and per frame (first to last frame done);
    ``threads`` its ``threads`` (1: one core, ECC's budget; None: all cores, as ``monovo
    track``)."""
    stamps: list[float] = []
    with Stopwatch() as watch:
        s = track_sequence(seq, None, out, TrackOptions(), overwrite=True, threads=threads,
                           progress=lambda done, total: stamps.append(time.perf_counter()))
    _, est = read_tum(out / "trajectory.tum")
    _, gt = read_tum(seq / "groundtruth.tum")
    err, dist, _ = final_drift(est, gt)
    return {"frames": s.frames, "fps": s.frames / watch.wall, "fps_cpu": s.frames / watch.cpu,
            "fps_steady": (len(stamps) - 1) / (stamps[-1] - stamps[0]),
            "lost": s.lost, "reanchored": s.reanchored, "drift_pct": 100 * err / dist}


def estimator_only(seq: Path) -> tuple[float, float]:
    """Frames/s (wall, CPU) of ``odometry.estimate_frames`` over frames decoded beforehand."""
    frames = open_frames(seq)
    cfg = load_init(seq / "init.yaml")
    imgs = [(f.index, f.timestamp, f.image) for f in frames]
    plane = cfg.plane
    with Stopwatch() as watch:
        n = sum(1 for _ in estimate_frames(imgs, cfg.camera, plane, cfg.region, TrackOptions()))
    return n / watch.wall, n / watch.cpu


# --------------------------------------------------------------------------- profile


def stage_shares(stats: pstats.Stats) -> dict[str, float]:
    """Seconds per stage: each function's own time goes to its stage, or is split over its
    callers (in proportion to the time it spent under each) and so up to the nearest staged
    ancestor; time that reaches no staged function is "other"."""
    table = stats.stats  # func -> (cc, nc, tottime, cumtime, callers{caller: (cc, nc, tt, ct)})
    memo: dict[tuple, dict[str, float]] = {}

    def own_stage(func: tuple) -> str | None:
        filename, _, name = func
        return STAGES.get(name) if "monovo_cli" in filename else None

    def distribution(func: tuple, active: frozenset) -> dict[str, float]:
        """Shares (sum 1) of the stages a unit of time spent in ``func`` belongs to."""
        stage = own_stage(func)
        if stage is not None:
            return {stage: 1.0}
        if func in memo:
            return memo[func]
        callers = table.get(func, (0, 0, 0.0, 0.0, {}))[4]
        weights = {c: v[3] for c, v in callers.items() if c not in active}
        total = sum(weights.values())
        if total <= 0.0:
            return {"other": 1.0}
        out: dict[str, float] = {}
        for c, w in weights.items():
            for st, share in distribution(c, active | {func}).items():
                out[st] = out.get(st, 0.0) + share * w / total
        memo[func] = out
        return out

    seconds = dict.fromkeys(STAGE_ORDER, 0.0)
    for func, (_, _, tottime, _, _) in table.items():
        for st, share in distribution(func, frozenset()).items():
            seconds[st] += tottime * share
    return seconds


def profile_stages(seq: Path, out: Path) -> tuple[dict[str, float], list[tuple[str, float]]]:
    """Stage shares (fractions) of a profiled end-to-end run, and the top functions by own time."""
    prof = cProfile.Profile()
    prof.enable()
    track_sequence(seq, None, out, TrackOptions(), overwrite=True, threads=1)
    prof.disable()
    stats = pstats.Stats(prof)
    seconds = stage_shares(stats)
    total = sum(seconds.values())
    top = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:8]
    top_share = [(f"{Path(f[0]).name}:{f[2]}" if f[0] != "~" else f[2], v[2] / total) for f, v in top]
    return {k: v / total for k, v in seconds.items()}, top_share


# --------------------------------------------------------------------------- memory


# Runs ``monovo`` in the child and, at its exit, writes the child's own peak RSS (VmHWM of
# /proc/self/status, kB) to the file named by argv[1]. ru_maxrss cannot be used: Linux carries
# the parent's high-water mark over fork/exec into the child's (and this parent is large).
_CHILD = """
import atexit, runpy, sys
report = sys.argv[1]
def _peak():
    with open("/proc/self/status") as f:
        kb = next(line.split()[1] for line in f if line.startswith("VmHWM:"))
    with open(report, "w") as f:
        f.write(kb)
atexit.register(_peak)
sys.argv = ["monovo"] + sys.argv[2:]
runpy.run_module("monovo_cli", run_name="__main__")
"""


def peak_rss_mb(seq: Path, out: Path) -> tuple[float, float]:
    """(peak RSS MB, seconds) of ``monovo track SEQ -o OUT`` in a child process, one core."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    report = out.with_name(out.name + ".vmhwm")
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", _CHILD, str(report), "track", str(seq), "-o", str(out),
                    "-q", "--overwrite"], env=env, check=True)
    secs = time.perf_counter() - t0
    return int(report.read_text()) / 1024.0, secs


def prefix_sequence(full: Path, dest: Path, n: int) -> Path:
    """A sequence folder whose frames are symlinks to the first ``n`` frames of ``full``."""
    (dest / "frames").mkdir(parents=True)
    (dest / "init.yaml").symlink_to(full / "init.yaml")
    for p in sorted((full / "frames").glob("*.png"))[:n]:
        (dest / "frames" / p.name).symlink_to(p)
    return dest


def memory(tmp: Path, counts: list[int], seed: int,
           renders: Path | None = None) -> list[tuple[int, float, float]]:
    """Peak RSS and seconds of ``monovo track`` over the first ``counts`` frames of one
    512² drive, rendered into ``renders`` (kept, and used again when it holds the drive
    whole) or ``tmp``."""
    full = (renders or tmp) / f"mem_drive_{max(counts)}_seed{seed}"
    frames = full / "frames"
    if renders is not None and frames.is_dir() and len(list(frames.glob("*.png"))) == max(counts) \
            and (full / "groundtruth.tum").is_file():
        print(f"(the {max(counts)} frames rendered before in {full})\n", file=sys.stderr)
    else:
        t0 = time.perf_counter()
        synthesize(full, preset="drive", frames=max(counts), size=(512, 512), noise_var=10.0,
                   seed=seed)
        print(f"(rendered {max(counts)} frames in {time.perf_counter() - t0:.0f} s)\n",
              file=sys.stderr)
    rows = []
    for n in sorted(counts):
        seq = full if n == max(counts) else prefix_sequence(full, tmp / f"mem_{n}", n)
        rss, secs = peak_rss_mb(seq, tmp / f"mem_out_{n}")
        rows.append((n, rss, secs))
    return rows


def measure(seq: Path, out: Path, threads: int | None = 1
            ) -> tuple[dict, tuple[float, float], tuple[float, float]]:
    """One drive's speed figures: :func:`end_to_end` (into ``out``, with ``threads``),
    :func:`estimator_only` frames/s (wall, CPU) and the ECC peer's frames/s (wall, CPU; then
    the same at OpenCV's default stop, ``ECC_EPS_OPENCV``) on the same PNGs."""
    e2e = end_to_end(seq, out, threads)
    est_fps = estimator_only(seq)
    ecc = peer_on_drive(EccPeer(), seq)
    quick = peer_on_drive(EccPeer(ECC_EPS_OPENCV), seq)
    return e2e, est_fps, (ecc.count / ecc.seconds, ecc.count / ecc.cpu,
                          quick.count / quick.seconds, quick.count / quick.cpu)


SPEED_HEAD = ("| size | end to end, whole call | end to end, per frame (wall) | estimator only | "
              "ms/frame end to end | target end to end | ECC at OpenCV's default stop (1e-3), "
              "end to end | monovo / ECC | ECC at the strict stop (1e-6), end to end | monovo / that | "
              "lost | re-anchored | final error (% of distance) |")


def speed_row(size: str, e: dict, est_fps: tuple[float, float], ecc_fps: tuple[float, float],
              target: float | None = None) -> str:
    """One row of ``SPEED_HEAD`` from :func:`measure`'s figures (``target``: frames/s end to
    end; default ``TARGET_FPS`` of the size): ECC at OpenCV's default stop first, the peer a
    user who picks ECC gets, then at the peers tables' strict stop."""
    (est, est_cpu), (strict, strict_cpu, ecc, ecc_cpu) = est_fps, ecc_fps
    target = TARGET_FPS.get(size) if target is None else target
    return (f"| {size} | {e['fps']:.1f} ({e['fps_cpu']:.1f}) | {e['fps_steady']:.1f} | "
            f"{est:.1f} ({est_cpu:.1f}) | {1000 / e['fps']:.1f} ({1000 / e['fps_cpu']:.1f}) | "
            f"{'–' if target is None else f'≥ {target:g}'} | {ecc:.1f} ({ecc_cpu:.1f}) | "
            f"{e['fps'] / ecc:.2f} ({e['fps_cpu'] / ecc_cpu:.2f}) | {strict:.1f} ({strict_cpu:.1f}) | "
            f"{e['fps'] / strict:.2f} ({e['fps_cpu'] / strict_cpu:.2f}) | {e['lost']} | "
            f"{e['reanchored']} | {e['drift_pct']:.3f} |")


# --------------------------------------------------------------------------- against a commit


def package_at(rev: str, dest: Path) -> Path:
    """``monovo_cli`` as it was at commit ``rev``, unpacked into ``dest`` (returned: the folder
    to put on PYTHONPATH); a clear exit when git does not know ``rev``."""
    got = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "monovo_cli"],
                         capture_output=True)
    if got.returncode != 0:
        raise SystemExit(f"error: git archive {rev}: {got.stderr.decode().strip()}")
    dest.mkdir(parents=True)
    safe = {"filter": "data"} if hasattr(tarfile, "data_filter") else {}  # (Python 3.9.17+)
    with tarfile.open(fileobj=io.BytesIO(got.stdout)) as tar:
        tar.extractall(dest, **safe)
    return dest


def _child_env(tree: Path) -> dict[str, str]:
    """The environment of a child that imports ``monovo_cli`` from ``tree``
    (:func:`~benchmarks.common.child_env`; checked: children run in ``tree``'s parent, not
    here, where the working directory's package would come first)."""
    env = child_env(tree)
    where = subprocess.run([sys.executable, "-c", "import monovo_cli; print(monovo_cli.__file__)"],
                           env=env, capture_output=True, text=True, check=True,
                           cwd=tree.parent).stdout.strip()
    if not Path(where).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"error: PYTHONPATH={tree} imports monovo_cli from {where}")
    return env


def cli_seconds(env: dict[str, str], seq: Path, out: Path) -> tuple[float, float]:
    """(wall, CPU) seconds of ``python -m monovo_cli track SEQ -o OUT --threads 1 -q`` as a
    child process with ``env`` (:func:`_child_env`)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "monovo_cli", "track", str(seq), "-o", str(out),
                    "--threads", "1", "-q", "--overwrite"], env=env, check=True,
                   cwd=Path(env["PYTHONPATH"]).parent)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def against_commit(args: argparse.Namespace, tmp: Path) -> list[tuple]:
    """Per size of ``args.sizes``: this tree's ``monovo track`` and commit ``args.against``'s,
    timed in alternation over ``args.repeats`` pairs: (size, frames, [(wall, cpu) of this tree],
    [(wall, cpu) of the commit], same motion.csv)."""
    envs = {"this": _child_env(ROOT), "base": _child_env(package_at(args.against, tmp / "base"))}
    rows = []
    for size in args.sizes:
        w, h = (int(v) for v in size.split("x"))
        seq = tmp / f"drive_{size}"
        synthesize(seq, preset="drive", frames=args.frames, size=(w, h), noise_var=10.0,
                   seed=args.seed)
        times: dict[str, list] = {"this": [], "base": []}
        for who in times:  # (untimed: each tree's bytecode written before its first timed run)
            cli_seconds(envs[who], seq, tmp / f"out_{who}_{size}")
        for k in range(max(3, args.repeats)):
            for who in (("this", "base") if k % 2 == 0 else ("base", "this")):
                times[who].append(cli_seconds(envs[who], seq, tmp / f"out_{who}_{size}"))
        same = ((tmp / f"out_this_{size}" / "motion.csv").read_bytes()
                == (tmp / f"out_base_{size}" / "motion.csv").read_bytes())
        rows.append((size, args.frames, times["this"], times["base"], same))
        print(f"({size} done)", file=sys.stderr)
    return rows


def print_against(args: argparse.Namespace, rows: list[tuple]) -> None:
    rev = args.against
    print(f"### This tree against commit {rev}: `monovo track --threads 1` as a child process, "
          f"whole process, alternating ({args.frames}-frame drives, noise variance 10, seed "
          f"{args.seed})\n")
    print(f"| size | pairs | this tree, frames/s (median, wall) | {rev}, frames/s | this / {rev}, "
          "wall: median (range) | CPU: median (range) | the same motion.csv |")
    print("|" + " --- |" * 7)
    for size, frames, this, base, same in rows:
        wall = [b[0] / a[0] for a, b in zip(this, base)]
        cpu = [b[1] / a[1] for a, b in zip(this, base)]
        print(f"| {size} | {len(wall)} | {frames / statistics.median(a for a, _ in this):.1f} | "
              f"{frames / statistics.median(b for b, _ in base):.1f} | "
              f"{statistics.median(wall):.3f} ({min(wall):.3f}-{max(wall):.3f}) | "
              f"{statistics.median(cpu):.3f} ({min(cpu):.3f}-{max(cpu):.3f}) | "
              f"{'yes' if same else 'no'} |")
    print(f"\nRatios above 1: this tree is faster. ({load()} at the end.)")


# --------------------------------------------------------------------------- main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", nargs="+", default=list(SIZES), help="WxH drives")
    ap.add_argument("--frames", type=int, default=200, help="frames per drive")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-profile", action="store_true", help="skip the per-stage profile")
    ap.add_argument("--memory", action="store_true",
                    help="only the peak RSS over --memory-frames frames (no speed tables)")
    ap.add_argument("--memory-frames", type=int, nargs="+", default=[500, 5000])
    ap.add_argument("--renders", type=Path, default=None,
                    help="--memory: keep the rendered drive in this folder and use it again "
                         "(its render takes about 15 min)")
    ap.add_argument("--repeats", type=int, default=1,
                    help="measure each size this many times, alternating (default 1)")
    ap.add_argument("--threads", type=int, default=None,
                    help="both methods on N threads (OpenCV's, and monovo's --threads N); "
                         "default: one core")
    ap.add_argument("--against", metavar="REV", default=None,
                    help="time this tree against commit REV instead of ECC (its own section)")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the speed section of docs/benchmarks.md (with --memory: the "
                         "memory section)")
    args = ap.parse_args()
    section = (("memory", "Memory over long drives") if args.memory
               else ("speed-against", "Speed against an earlier commit") if args.against
               else ("speed", "Speed against ECC, one thread each"))
    with printed_section(*section, "benchmarks.speed", args.write_docs):
        run(args)


def run(args: argparse.Namespace) -> None:
    """The measurements :func:`main` parsed the options of, printed."""
    if args.threads is None:
        one_core()
    else:
        import cv2

        cv2.setNumThreads(args.threads)
    print(f"Machine: {machine()}; {load()} at the start\n")
    if args.against:
        with tempfile.TemporaryDirectory() as tmp_name:
            print_against(args, against_commit(args, Path(tmp_name)))
        return
    speed_rows, stage_cols = [], []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for size in ([] if args.memory else args.sizes):
            w, h = (int(v) for v in size.split("x"))
            seq = tmp / f"drive_{size}"
            synthesize(seq, preset="drive", frames=args.frames, size=(w, h), noise_var=10.0,
                       seed=args.seed)
            for _ in range(max(1, args.repeats)):
                e2e, est_fps, ecc_fps = measure(seq, tmp / f"out_{size}",
                                                1 if args.threads is None else args.threads)
                speed_rows.append((size, e2e, est_fps, ecc_fps))
            if not args.no_profile:
                shares, top = profile_stages(seq, tmp / f"out_{size}")
                stage_cols.append((size, shares, top, 1000.0 / e2e["fps"]))
            print(f"({size} done)", file=sys.stderr)
        mem_rows = memory(tmp, args.memory_frames, args.seed, args.renders) if args.memory else None

    if speed_rows:
        print_speed(args, speed_rows, stage_cols)
    if mem_rows is not None:
        print_memory(mem_rows)


def print_speed(args, speed_rows, stage_cols) -> None:
    where = "one core" if args.threads is None else f"{args.threads} threads each"
    print(f"### Frames/s on {where} ({args.frames}-frame drives, noise variance 10, seed "
          f"{args.seed}); wall clock, CPU time of this process in brackets\n")
    print(SPEED_HEAD)
    print("|" + " --- |" * 13)
    for row in speed_rows:
        print(speed_row(*row))
    if args.repeats > 1:
        print()
        for size in dict.fromkeys(size for size, *_ in speed_rows):
            for label, at in (("ECC at OpenCV's default stop", 2), ("ECC at the strict stop", 0)):
                wall = [e["fps"] / ecc[at] for s, e, _, ecc in speed_rows if s == size]
                cpu = [e["fps_cpu"] / ecc[at + 1] for s, e, _, ecc in speed_rows if s == size]
                print(f"{size}: monovo / {label} over {len(wall)} pairs, median "
                      f"{statistics.median(wall):.2f}x wall ({min(wall):.2f}-{max(wall):.2f}), "
                      f"{statistics.median(cpu):.2f}x CPU ({min(cpu):.2f}-{max(cpu):.2f})")
    print(f"\n({load()} at the end.)")
    if stage_cols:
        print("\n### Time per frame by stage (cProfile of the end-to-end run; % of the profiled "
              "time, and ms/frame = share × unprofiled end-to-end time)\n")
        print("| stage | " + " | ".join(s for s, _, _, _ in stage_cols) + " |")
        print("|" + " --- |" * (len(stage_cols) + 1))
        for st in STAGE_ORDER:
            cells = [f"{100 * sh[st]:.1f} % ({sh[st] * ms:.2f} ms)" for _, sh, _, ms in stage_cols]
            print(f"| {st} | " + " | ".join(cells) + " |")
        for size, _, top, _ in stage_cols:
            print(f"\nTop functions by own time at {size}: "
                  + ", ".join(f"{name} {100 * s:.1f} %" for name, s in top))


def print_memory(mem_rows) -> None:
    print("\n### Peak memory of `monovo track` (512x512, one core, child process)\n")
    print("| frames | peak RSS (MB) | wall time (s) | frames/s |")
    print("| --- | --- | --- | --- |")
    for n, rss, secs in mem_rows:
        print(f"| {n} | {rss:.1f} | {secs:.1f} | {n / secs:.1f} |")
    growth = 100 * (mem_rows[-1][1] / mem_rows[0][1] - 1)
    print(f"\nPeak RSS over {mem_rows[-1][0]} frames vs {mem_rows[0][0]}: {growth:+.1f} %")

if __name__ == "__main__":
    main()
