"""Where the time goes: ms per frame by part, per image size, against the limit (issue 26).

    python -m benchmarks.profile                       # 100-frame drives at 256², 512², 1024²
    python -m benchmarks.profile --sizes 512 --frames 60

For each size a ``monovo synth --preset drive`` sequence (noise variance 10) is rendered
(not timed), then ``monovo track SEQ -o OUT --threads 1`` runs in this process on one core
(OpenCV, BLAS and OpenMP on one thread, the frames decoded in the frame loop, not ahead on a
reader thread, whose timers would interleave with the parts'; ``pipeline.track.track_sequence``,
as the command runs it) with explicit timers around the library's functions: nothing in
monovo_cli changes, the timers wrap the functions where the callers look them up (module
attributes, class methods). Each part is timed exclusively: a function timed as one part
and called inside another (a level solve inside the acceptance step's plane test, a pyramid
inside a new keyframe) counts for its own part only, so the parts and "other" add up to the
frame loop.

* **decode** -- ``FrameSource.read``: reading and decoding the PNG to float32 grey;
* **pyramid** -- ``build_pyramid`` (the frame's, and a new keyframe's);
* **estimator** -- ``estimate_motion`` and ``coarse_search`` with their level solves
  (``_solve_level``), residual evaluations (the plane's homography over the points and
  OpenCV's remap) and the covariance, wherever they are called from; the rows below it say
  how many level solves and residual evaluations a frame costs and how much of the time is
  the residual evaluations and the remap alone;
* **acceptance** -- ``Odometry._accept``: the checks, re-anchoring (a new keyframe's points),
  the plane tests and the covariance, without the estimator and pyramids it calls;
* **other** -- the rest of the frame loop: the duplicate and constancy checks, the noise
  estimate, the failure checks, recording and streaming motion.csv, checkpoints.

The frame loop runs from the first frame's decode to the last frame's progress call; the
parts are its time divided by the frames. **Start-up** is a fresh ``python -m monovo_cli
track SEQ -o OUT`` up to the first frame's decode (the interpreter, the imports, init.yaml
and the output folder; median of three, the modules' bytecode written as an installed
package has it), **finish** what the call does after the last
frame (smoothing, trajectory files, trajectory.png, report.html).

**The limit** (issue 26): decoding a frame plus one pass over the points, i.e. the decode
plus one residual evaluation at the finest level (the points' warp, the bicubic remap and
the differences), as measured in the same run.
"""

from __future__ import annotations

import argparse
import functools
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks.common import child_env, load, machine, one_core

SIZES = (256, 512, 1024)
#: The exclusive parts of the frame loop, in the table's order ("other" is the rest).
PARTS = ("decode", "pyramid", "estimator", "acceptance")
ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------- timers


@dataclass
class Timers:
    """Seconds (wall and CPU of this process) per part, exclusive of the parts timed inside
    it; calls per part; and the nested measures that do not count as parts of their own
    (``inside``: residual evaluations, remap, finest-level residual evaluations, level
    solves, the acceptance step with what it calls)."""

    wall: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    cpu: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    calls: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    inside_wall: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    inside_cpu: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    inside_calls: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    active: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # calls running
    _stack: list[list[float]] = field(default_factory=list)  # [wall, cpu] of timed children

    def snapshot(self) -> Timers:
        return Timers(dict(self.wall), dict(self.cpu), dict(self.calls), dict(self.inside_wall),
                      dict(self.inside_cpu), dict(self.inside_calls))

    def part(self, name: str, fn):
        """``fn`` timed as part ``name``, exclusive of the parts timed inside it."""

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            self._stack.append([0.0, 0.0])
            self.active[name] += 1
            w0, c0 = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                dw, dc = time.perf_counter() - w0, time.process_time() - c0
                self.active[name] -= 1
                child_w, child_c = self._stack.pop()
                self.wall[name] += dw - child_w
                self.cpu[name] += dc - child_c
                self.calls[name] += 1
                if self._stack:
                    self._stack[-1][0] += dw
                    self._stack[-1][1] += dc

        return timed

    def inside(self, name: str, fn, when=None):
        """``fn`` timed as a measure ``name`` inside the parts (not a part of its own); only
        the calls for which ``when(*args, **kwargs)`` holds, if given."""

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            if when is not None and not when(*args, **kwargs):
                return fn(*args, **kwargs)
            self.active[name] += 1
            w0, c0 = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.active[name] -= 1
                self.inside_wall[name] += time.perf_counter() - w0
                self.inside_cpu[name] += time.process_time() - c0
                self.inside_calls[name] += 1

        return timed


def _replace_everywhere(original, wrapper, patches: list) -> None:
    """Point every loaded monovo_cli module's global bound to ``original`` at ``wrapper``
    (the module that defines it and those that imported it by name); the undo goes to
    ``patches``."""
    for name, module in list(sys.modules.items()):
        if not name.startswith("monovo_cli") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if value is original:
                patches.append((module, attr, value))
                setattr(module, attr, wrapper)


def install(timers: Timers) -> list:
    """Wrap the library's functions with ``timers``; returns the undo list for :func:`uninstall`."""
    import monovo_cli.pipeline.track  # noqa: F401 (every module a run uses, loaded before patching)
    from monovo_cli.core.estimator import estimate
    from monovo_cli.core.odometry import Odometry
    from monovo_cli.image import pyramid, sampling
    from monovo_cli.io.sources.base import FrameSource

    patches: list = []
    for cls, attr, part in ((FrameSource, "read", "decode"), (Odometry, "_accept", "acceptance")):
        original = cls.__dict__[attr]
        patches.append((cls, attr, original))
        setattr(cls, attr, timers.part(part, original))
    for original, part in ((pyramid.build_pyramid, "pyramid"),
                           (estimate.estimate_motion, "estimator"),
                           (estimate.coarse_search, "estimator"),
                           (estimate._solve_level, "estimator")):
        _replace_everywhere(original, timers.part(part, original), patches)
    # nested measures: the level solves; the estimator's residual evaluations and their
    # remap; any residual evaluation at the finest level (the limit's pass over the points)
    solve = estimate._solve_level
    _replace_everywhere(solve, timers.inside("level solves", solve), patches)
    residuals = estimate.residuals
    finest = timers.inside("finest residual evaluation", residuals,
                           when=lambda level, *a, **k: level.points.level == 0)
    _replace_everywhere(residuals, timers.inside(
        "residual evaluations", finest, when=lambda *a, **k: timers.active["estimator"] > 0),
        patches)
    _replace_everywhere(sampling.sample_at, timers.inside(
        "remap", sampling.sample_at,
        when=lambda *a, **k: timers.active["residual evaluations"] > 0), patches)
    accept = Odometry.__dict__["_accept"]
    patches.append((Odometry, "_accept", accept))
    Odometry._accept = timers.inside("acceptance, with what it calls", accept)
    return patches


def uninstall(patches: list) -> None:
    for owner, attr, original in reversed(patches):
        setattr(owner, attr, original)


# --------------------------------------------------------------------------- one drive


@dataclass
class Profile:
    """One drive's profile. Seconds: ``call`` the whole track_sequence call, ``before`` its
    time before the first frame's decode (in this process: the imports are done), ``loop``
    the frame loop, ``finish`` after the last frame. ``parts`` (wall) and ``parts_cpu``:
    seconds per part over the loop, "other" included; ``inside``: the nested measures
    (seconds, calls); ``points`` the median observation points a frame used, ``reanchored``
    and ``lost`` the frames so marked."""

    frames: int
    call: float
    before: float
    loop: float
    loop_cpu: float
    finish: float
    parts: dict[str, float]
    parts_cpu: dict[str, float]
    calls: dict[str, int]
    inside: dict[str, tuple[float, float, int]]
    points: int = 0
    reanchored: int = 0
    lost: int = 0

    def ms_per_frame(self, part: str, cpu: bool = False) -> float:
        return 1000.0 * (self.parts_cpu if cpu else self.parts)[part] / self.frames

    @property
    def limit_ms(self) -> float:
        """Decode plus one finest-level residual evaluation, ms (wall)."""
        wall, _, n = self.inside.get("finest residual evaluation", (0.0, 0.0, 0))
        return self.ms_per_frame("decode") + (1000.0 * wall / n if n else float("nan"))

    @property
    def limit_ms_cpu(self) -> float:
        _, cpu, n = self.inside.get("finest residual evaluation", (0.0, 0.0, 0))
        return self.ms_per_frame("decode", cpu=True) + (1000.0 * cpu / n if n else float("nan"))


def profile_drive(seq: Path, out: Path, options=None) -> Profile:
    """``track_sequence(seq, out)`` with the timers in: its :class:`Profile`."""
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.track import track_sequence

    timers = Timers()
    stamps: list[tuple[float, float, Timers]] = []
    first_read: list[tuple[float, float]] = []

    def progress(done: int, total: int) -> None:  # noqa: ARG001
        stamps.append((time.perf_counter(), time.process_time(), timers.snapshot()))

    patches = install(timers)
    from monovo_cli.io.sources.base import FrameSource

    timed_read = FrameSource.read

    def read(self, index):
        if not first_read:
            first_read.append((time.perf_counter(), time.process_time()))
        return timed_read(self, index)

    FrameSource.read = read
    patches.append((FrameSource, "read", timed_read))
    try:
        w0 = time.perf_counter()
        run = track_sequence(seq, None, out, options or TrackOptions(), overwrite=True,
                             progress=progress, threads=1)
        w1 = time.perf_counter()
    finally:
        uninstall(patches)
    (end_w, end_c, at_end), (start_w, start_c) = stamps[-1], first_read[0]
    loop, loop_cpu = end_w - start_w, end_c - start_c
    parts = {p: at_end.wall.get(p, 0.0) for p in PARTS}
    parts_cpu = {p: at_end.cpu.get(p, 0.0) for p in PARTS}
    parts["other"] = loop - sum(parts.values())
    parts_cpu["other"] = loop_cpu - sum(parts_cpu.values())
    inside = {k: (at_end.inside_wall[k], at_end.inside_cpu[k], at_end.inside_calls[k])
              for k in at_end.inside_calls}
    return Profile(run.frames, w1 - w0, start_w - w0, loop, loop_cpu, w1 - end_w, parts,
                   parts_cpu, dict(at_end.calls), inside,
                   int(statistics.median(run.points[1:])) if run.frames > 1 else 0,
                   run.reanchored, run.lost)


# --------------------------------------------------------------------------- start-up

# In a fresh interpreter: the time at its first statement, after the imports of the command
# line and of `monovo track`, and at the first frame's decode (monotonic clock, shared by
# the processes), then exit.
_STARTUP = """
import time
t_start = time.monotonic()
import os, runpy, sys
import monovo_cli.cli, monovo_cli.pipeline.track
t_imported = time.monotonic()
from monovo_cli.io.sources.base import FrameSource

def first_read(self, index):
    print(t_start, t_imported, time.monotonic(), flush=True)
    os._exit(0)

FrameSource.read = first_read
sys.argv = ["monovo", "track", sys.argv[1], "-o", sys.argv[2], "-q", "--overwrite"]
runpy.run_module("monovo_cli", run_name="__main__")
"""


def startup(seq: Path, out: Path, repeats: int = 3) -> tuple[float, float, float]:
    """Median seconds of a fresh ``monovo track SEQ -o OUT`` from its start to the first
    frame's decode: (in all, the interpreter's own start, the imports). With the modules'
    bytecode, as ``pip install`` leaves a package: the children may write it (an environment
    with PYTHONDONTWRITEBYTECODE would compile every module in every run, doubling monovo's
    own import time), and a first, untimed run writes it."""
    env = child_env(ROOT)
    rows = []
    for i in range(-1, repeats):
        t0 = time.monotonic()
        run = subprocess.run([sys.executable, "-c", _STARTUP, str(seq), str(out) + f"_{i}"],
                             env=env, cwd=ROOT, capture_output=True, text=True, check=True)
        t_start, t_imported, t_read = (float(v) for v in run.stdout.split())
        if i >= 0:
            rows.append((t_read - t0, t_start - t0, t_imported - t_start))
    return tuple(statistics.median(r[k] for r in rows) for k in range(3))


# --------------------------------------------------------------------------- table


def table(columns: list[tuple[int, Profile, tuple[float, float, float]]]) -> str:
    """The markdown table: ms/frame wall (CPU) per part and size, then the limit and the
    fixed costs."""
    head = "| part | " + " | ".join(f"{s}² ms/frame | %" for s, _, _ in columns) + " |"
    lines = [head, "|" + " --- |" * (1 + 2 * len(columns))]

    def row(label: str, cells: list[tuple[str, str]]) -> None:
        lines.append(f"| {label} | " + " | ".join(f"{a} | {b}" for a, b in cells) + " |")

    def frame_ms(p: Profile, part: str) -> tuple[str, str]:
        ms, cpu = p.ms_per_frame(part), p.ms_per_frame(part, cpu=True)
        return f"{ms:.2f} ({cpu:.2f})", f"{100 * p.parts[part] / p.loop:.0f} %"

    def nested_ms(p: Profile, name: str) -> tuple[str, str]:
        wall, cpu, n = p.inside.get(name, (0.0, 0.0, 0))
        return (f"{1000 * wall / p.frames:.2f} ({1000 * cpu / p.frames:.2f})",
                f"{100 * wall / p.loop:.0f} %")

    words = {"decode": "decode (PNG read)", "pyramid": "pyramid build",
             "estimator": "estimator: level solves, residual evaluations, covariance",
             "acceptance": "acceptance (`Odometry._accept`: checks, re-anchoring, plane tests, "
                           "covariance; without the estimator it calls)",
             "other": "other"}
    for part in (*PARTS, "other"):
        row(words[part], [frame_ms(p, part) for _, p, _ in columns])
        if part == "estimator":
            row("&nbsp;&nbsp;level solves, residual evaluations per frame",
                [(f"{p.inside.get('level solves', (0, 0, 0))[2] / p.frames:.1f}, "
                  f"{p.inside.get('residual evaluations', (0, 0, 0))[2] / p.frames:.1f}", "")
                 for _, p, _ in columns])
            row("&nbsp;&nbsp;of which residual evaluations (warp + remap)",
                [nested_ms(p, "residual evaluations") for _, p, _ in columns])
            row("&nbsp;&nbsp;of which remap", [nested_ms(p, "remap") for _, p, _ in columns])
        if part == "acceptance":
            row("&nbsp;&nbsp;acceptance with the estimator and pyramids it calls",
                [nested_ms(p, "acceptance, with what it calls") for _, p, _ in columns])
    row("**frame loop, per frame**",
        [(f"**{1000 * p.loop / p.frames:.2f}** ({1000 * p.loop_cpu / p.frames:.2f})", "100 %")
         for _, p, _ in columns])
    row("**the limit**: decode + one residual evaluation at the finest level",
        [(f"**{p.limit_ms:.2f}** ({p.limit_ms_cpu:.2f})", "") for _, p, _ in columns])
    row("frame loop / the limit",
        [(f"{1000 * p.loop / p.frames / p.limit_ms:.1f}x "
          f"({1000 * p.loop_cpu / p.frames / p.limit_ms_cpu:.1f}x)", "") for _, p, _ in columns])
    row("start-up: fresh `monovo track` to the first decode, s (interpreter; imports)",
        [(f"{s[0]:.2f} ({s[1]:.2f}; {s[2]:.2f})", "") for _, _, s in columns])
    row("finish: after the last frame (smoothing, trajectory files and plot, report.html), s",
        [(f"{p.finish:.2f}", "") for _, p, _ in columns])
    row("observation points a frame used (median); re-anchored, lost frames",
        [(f"{p.points}; {p.reanchored}, {p.lost}", "") for _, p, _ in columns])
    return "\n".join(lines)


# --------------------------------------------------------------------------- main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES),
                    help="square drives of these sides, px")
    ap.add_argument("--frames", type=int, default=100, help="frames per drive")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    one_core()
    from monovo_cli.synth.write import synthesize

    print(f"Machine: {machine()}; {load()} at the start\n")
    columns = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for side in args.sizes:
            seq = tmp / f"drive_{side}"
            synthesize(seq, preset="drive", frames=args.frames, size=(side, side),
                       noise_var=10.0, seed=args.seed)
            prof = profile_drive(seq, tmp / f"out_{side}")
            columns.append((side, prof, startup(seq, tmp / f"startup_{side}")))
            print(f"({side}² done, {load()})", file=sys.stderr)
    print(f"### ms per frame by part, one core ({args.frames}-frame drives, noise variance 10, "
          f"seed {args.seed}); wall clock, CPU time of this process in brackets\n")
    print(table(columns))
    print(f"\n({load()} at the end.)")


if __name__ == "__main__":
    main()
