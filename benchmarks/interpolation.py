"""Why the finest level is sampled bicubically: interpolation error at the points.

    python -m benchmarks.interpolation              # 20 noise-free pairs, ~1 min
    python -m benchmarks.interpolation --pairs 50

Noise-free ``synth --preset pairs`` pairs (688x544, seed 1, the paper protocol's geometry).
For each pair the keyframe's finest-level observation points (default budget, and every
pixel above the threshold) are moved with the *true* motion into frame 1 and frame 1 is
sampled there by OpenCV's remap, bilinearly, bicubically (Keys) and with Lanczos-4; what
differs from the point's frame-0 intensity is what the interpolation (and the renderer's
view-dependent pixel filtering) gets wrong -- a model error the estimator cannot tell from
noise. Printed: its RMS per method and point set, and the time per sample. Then each pair is
tracked with each interpolation (default options otherwise) and the mean absolute motion
errors are printed: the noise-free floor.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import AXES, axis_table, machine, motion_errors, one_core
from monovo_cli.core.estimator.estimate import residuals
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import ALL_POINTS, EstimatorOptions, TrackOptions
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.image.sampling import INTERPOLATION
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.write import synthesize


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}\n")
    sets = {"default points": None, "every pixel above the threshold": ALL_POINTS}
    rms = {(s, m): [] for s in sets for m in INTERPOLATION}
    secs = {m: [0.0, 0] for m in INTERPOLATION}
    errs = {m: [] for m in INTERPOLATION}
    counts = {s: 0 for s in sets}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "pairs"
        synthesize(root, preset="pairs", frames=args.pairs, noise_var=0.0, seed=args.seed)
        for pair in sorted(p for p in root.iterdir() if p.name.startswith("pair_")):
            cfg = load_init(pair / "init.yaml")
            frames = [f.image for f in open_frames(pair / "frames")]
            plane = cfg.plane
            _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
            cur_from_key = se3_inv(gt[0])
            for name, cap in sets.items():
                key = build_keyframe(0, frames[0], cfg.camera, plane, cfg.region, np.eye(4),
                                     TrackOptions(max_points=cap))
                level = key.levels[0]
                counts[name] += len(level.points)
                for method, flag in INTERPOLATION.items():
                    t0 = time.perf_counter()
                    r, valid = residuals(level, frames[1], cur_from_key, flag=flag)
                    secs[method][0] += time.perf_counter() - t0
                    secs[method][1] += len(r)
                    rms[(name, method)].append(r[valid].astype(np.float64))
            for method in INTERPOLATION:
                opts = TrackOptions(estimator=EstimatorOptions(interpolation=method))
                res = list(estimate_frames([(i, float(i), f) for i, f in enumerate(frames)], cfg.camera,
                                 plane, cfg.region, opts))
                errs[method].append(motion_errors(res[1].prev_from_cur, gt[0]))
    print(f"{args.pairs} noise-free pairs, 688x544, seed {args.seed}: frame-1 intensity at the "
          "true motion minus the point's frame-0 intensity, RMS over all points (grey levels)\n")
    print("| points | mean points per pair | " + " | ".join(INTERPOLATION) + " |")
    print("| --- | --- |" + " --- |" * len(INTERPOLATION))
    for name in sets:
        cells = [f"{np.sqrt(np.mean(np.concatenate(rms[(name, m)]) ** 2)):.2f}"
                 for m in INTERPOLATION]
        print(f"| {name} | {counts[name] // args.pairs} | " + " | ".join(cells) + " |")
    print("| ns per point (warp + sample + difference) | – | "
          + " | ".join(f"{1e9 * t / n:.1f}" for t, n in secs.values()) + " |")
    print(f"\nTracked (default options but the finest level's interpolation), mean absolute "
          f"error over the {args.pairs} pairs ({', '.join(AXES)}):\n")
    print(axis_table([(m, np.abs(np.array(e)).mean(0)) for m, e in errs.items()]))


if __name__ == "__main__":
    main()
