"""How many passes over the finest level's points a frame costs, and what stopping sooner gives
up (issue 26): the Gauss-Newton steps' relaxation and step tolerance, chosen on one drive and
reported on another.

    python -m benchmarks.convergence                    # 512² drives, seeds 0 (choose) and 1 (report)
    python -m benchmarks.convergence --size 256 --frames 60 --seeds 2

The finest level's steps shrink by a steady factor: the constant observation matrix (the
keyframe's B-spline gradients, without the parallax of the frame's baseline) is steeper than
the frame as the bicubic kernel samples it, so every step falls short, by 8-27 % depending on
the direction (``python -m benchmarks.convergence`` measures it). A step stretched by
``relaxation`` (on steps that move the points less than ``REWEIGHT_PX``, where the problem is
linear) falls short by less; the iteration's fixed point, ``O^T W FD = 0``, is the same.

For each drive (``monovo synth --preset drive``, noise variance 10) and each setting
(relaxation, finest step tolerance in px) the frames are decoded first, then tracked on one
core (``odometry.estimate_frames``). Per setting: the finest level's residual evaluations per
frame (every one, the plane tests' included), the frames/s of the tracking, the final error
of the streamed trajectory, and how far each frame's motion row lies from the same row solved
to the fixed point (relaxation 1, step tolerance 1e-5 px, up to 100 iterations): the
difference per axis in units of the row's stated std, median and largest over the rows and
axes (rows of the same frame and keyframe only).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.common import final_drift, load, machine, one_core
from benchmarks.profile import Timers, install, uninstall
from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.geometry.lie import se3_inv, se3_log
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.write import synthesize

SETTINGS = ((1.0, 3e-3), (1.0, 5e-3), (1.1, 5e-3), (1.15, 4e-3), (1.15, 5e-3), (1.2, 5e-3),
            (1.15, 6e-3))
FIXED_POINT = EstimatorOptions(relaxation=1.0, step_tolerance_px=1e-5, max_iterations=100)


def track(seq: Path, estimator: EstimatorOptions) -> tuple[list, float, int]:
    """(frame results, tracking seconds, finest-level residual evaluations) of ``seq``."""
    cfg = load_init(seq / "init.yaml")
    frames = [(f.index, f.timestamp, f.image) for f in open_frames(seq / "frames")]
    timers = Timers()
    patches = install(timers)
    try:
        t0 = time.perf_counter()
        res = list(estimate_frames(frames, cfg.camera, cfg.plane, cfg.region,
                                   replace(TrackOptions(), estimator=estimator)))
        seconds = time.perf_counter() - t0
    finally:
        uninstall(patches)
    return res, seconds, timers.inside_calls.get("finest residual evaluation", 0)


def row_offsets(res: list, ref: list) -> np.ndarray:
    """|row - fixed point's row| / stated std, per axis, over the rows that share their
    keyframe with the reference run's (N, 6)."""
    out = []
    for a, b in zip(res[1:], ref[1:]):
        if a.keyframe != b.keyframe or not np.all(np.isfinite(b.std)) or np.any(b.std <= 0):
            continue
        x = se3_log(se3_inv(b.prev_from_cur) @ a.prev_from_cur)
        out.append(np.abs(x) / b.std)
    return np.array(out).reshape(-1, 6)


def drive_rows(seq: Path, label: str) -> list[str]:
    _, gt = read_tum(seq / "groundtruth.tum")
    ref, _, _ = track(seq, FIXED_POINT)
    rows = []
    for relax, tol in SETTINGS:
        res, seconds, evals = track(seq, EstimatorOptions(relaxation=relax, step_tolerance_px=tol))
        est = np.array([r.world_from_cam for r in res])
        err, dist, _ = final_drift(est, gt)
        off = row_offsets(res, ref)
        rows.append(f"| {label} | {relax:g} | {tol:g} | {evals / len(res):.2f} | "
                    f"{len(res) / seconds:.1f} | {100 * err / dist:.4f} | "
                    f"{np.median(off):.3f} | {off.max():.3f} | {len(off)} |")
    ref_est = np.array([r.world_from_cam for r in ref])
    err, dist, _ = final_drift(ref_est, gt)
    rows.append(f"| {label} | fixed point | 1e-05 | – | – | {100 * err / dist:.4f} | 0 | 0 | – |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1],
                    help="drives: the first chose the default, the others report")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    print(f"### Finest-level passes and the distance to the fixed point ({args.size}², "
          f"{args.frames} frames, noise variance 10, one core)\n")
    print("| drive | relaxation | step tolerance (px) | finest residual evaluations / frame | "
          "frames/s | final error (% of distance) | row off the fixed point, median (std) | "
          "largest (std) | rows compared |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        for i, seed in enumerate(args.seeds):
            seq = Path(tmp) / f"drive_{seed}"
            synthesize(seq, preset="drive", frames=args.frames, size=(args.size, args.size),
                       noise_var=10.0, seed=seed)
            label = f"seed {seed} ({'chose' if i == 0 else 'held out'})"
            for row in drive_rows(seq, label):
                print(row, flush=True)
    print(f"\n({load()} at the end.)")


if __name__ == "__main__":
    main()
