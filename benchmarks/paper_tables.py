"""The paper's protocol (section 10.3): synthetic 688x544 pairs, per-axis absolute errors.

    python -m benchmarks.paper_tables                     # 100 pairs, noise variances 0 10 50 100
    python -m benchmarks.paper_tables --pairs 1000 --noise-var 10   # the paper's full protocol
    python -m benchmarks.paper_tables --noisy-frame0                # noise on both frames

Renders ``--pairs`` pairs with ``monovo synth --preset pairs`` (rotations uniform in +-5 deg
per axis, translations uniform in +-10 m per axis, ground 100 m from the camera, optical axis
25 deg off the ground normal plus a random +-5 deg tilt; the header printed states the values
read from ``monovo_cli.synth``), tracks each with default options on one core and prints
Tables 10.1/10.2 beside the paper's figures for every ``--noise-var``, then one summary row
per noise variance. The same seed gives the same geometry (poses, texture) at every noise
variance; only the noise differs. As in the paper, whose ground texture is "exactly
known", frame 0 is noise-free by default (only frame 1 carries the noise); ``--noisy-frame0``
puts the noise on both frames, the harder case of real image pairs. A pair counts as
converged when its rotation error is below 0.05 deg and its translation error below 0.05 m on
every axis; the tables are over the converged pairs. ~30 s per 100 pairs and noise level.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import (
    add_frame0_option,
    add_points_option,
    axis_table,
    machine,
    motion_errors,
    one_core,
    options_note,
    track_options,
)
from benchmarks.docs_section import writes_section
from monovo_cli.core.odometry import estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.motion import PAIR_DISTANCE, PAIR_EXTRA_TILT_DEG, PAIR_MAX_TRANSLATION, PAIR_TILT_DEG
from monovo_cli.synth.render import default_camera
from monovo_cli.synth.write import synthesize

PAPER_MEAN = np.array([0.00203, 0.00065, 0.01027, 0.00537, 0.00324, 0.00150])
PAPER_STD = np.array([0.00124, 0.00033, 0.00177, 0.00316, 0.00234, 0.00042])
AXES = ["tx (m)", "ty (m)", "tz (m)", "rx (deg)", "ry (deg)", "rz (deg)"]


def run_pairs(root: Path, n_pairs: int, noise_var: float, seed: int, options: TrackOptions,
              clean_frame0: bool = True, *, texture=None, psf: float = 0.0):
    """Errors (n, 6), converged flags (n,), wall and CPU seconds per pair (n,) (n,).
    ``texture`` and ``psf`` are synth's (default: the procedural texture, no optical blur)."""
    synthesize(root, preset="pairs", frames=n_pairs, noise_var=noise_var, seed=seed,
               clean_frame0=clean_frame0, texture=texture, psf=psf)
    errs, _, secs, cpu = track_pairs(root, options)
    ok = (np.abs(errs[:, :3]).max(1) < 0.05) & (np.abs(errs[:, 3:]).max(1) < 0.05)
    return errs, ok, secs, cpu


def track_pairs(root: Path, options: TrackOptions):
    """Track every ``pair_NNNN`` of a folder written by ``synthesize(preset="pairs")``, frames
    decoded beforehand: errors (n, 6) (m, deg), frame 1's results (n ``FrameResult``: status,
    reason), wall and CPU seconds per pair (n,) (n,) (tracking incl. the frame-0 model)."""
    errs, results, secs, cpu = [], [], [], []
    for pair in sorted(p for p in root.iterdir() if p.name.startswith("pair_")):
        frames = open_frames(pair / "frames")
        cfg = load_init(pair / "init.yaml")
        imgs = [(f.index, f.timestamp, f.image) for f in frames]
        plane = cfg.plane
        t0, c0 = time.perf_counter(), time.process_time()
        res = list(estimate_frames(imgs, cfg.camera, plane, cfg.region, options))
        secs.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
        errs.append(motion_errors(res[1].prev_from_cur, gt[0]))
        results.append(res[1])
    return np.array(errs), results, np.array(secs), np.array(cpu)


def table(errs: np.ndarray, ok: np.ndarray) -> str:
    a = np.abs(errs[ok])
    lines = ["| axis | monovo mean | monovo std | paper mean | paper std | ratio mean |",
             "| --- | --- | --- | --- | --- | --- |"]
    for i, name in enumerate(AXES):
        m, s = a[:, i].mean(), a[:, i].std()
        lines.append(f"| {name} | {m:.5f} | {s:.5f} | {PAPER_MEAN[i]:.5f} | {PAPER_STD[i]:.5f} | "
                     f"{m / PAPER_MEAN[i]:.2f} |")
    for name, sl in (("translation average (m)", slice(0, 3)), ("rotation average (deg)", slice(3, 6))):
        lines.append(f"| {name} | {a[:, sl].mean():.5f} | {a[:, sl].std(0).mean():.5f} | "
                     f"{PAPER_MEAN[sl].mean():.5f} | {PAPER_STD[sl].mean():.5f} | "
                     f"{a[:, sl].mean() / PAPER_MEAN[sl].mean():.2f} |")
    return "\n".join(lines)


def scene_header(n_pairs: int, seed: int, note: str = "default options",
                 clean_frame0: bool = True) -> str:
    """The scene geometry of the pairs preset, from the values synth actually uses."""
    cam = default_camera(688, 544)
    return (f"Scene (`monovo synth --preset pairs`, seed {seed}): {n_pairs} pairs, 688x544 px, "
            f"f = {cam.fx:.1f} px, principal point at the image centre; camera 0 "
            f"{PAIR_DISTANCE:g} m from the ground plane, optical axis {PAIR_TILT_DEG:g} deg off "
            f"the plane normal plus a random tilt uniform in +-{PAIR_EXTRA_TILT_DEG:g} deg about "
            f"camera x and y, random azimuth; motion T_0_1 with translation uniform in "
            f"+-{PAIR_MAX_TRANSLATION:g} m and rotation vector uniform in +-5 deg per axis, "
            "redrawn until frame 1 sees only ground. Gaussian noise of the stated variance on "
            + ("frame 1 only (frame 0 noise-free, `synth --clean-frame0`: the paper's ground "
               "texture is exactly known)" if clean_frame0 else "both frames")
            + f", then rounding to 8 bit. Tracked with {note}, one core.")


@writes_section("paper-tables", "The paper's pairs", "benchmarks.paper_tables")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_points_option(ap)
    add_frame0_option(ap)
    ap.add_argument("--pairs", type=int, default=100, help="pairs per noise level (paper: 1000)")
    ap.add_argument("--noise-var", type=float, nargs="+", default=[0.0, 10.0, 50.0, 100.0],
                    help="noise variances (grey levels^2), one table each")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}\n")
    print(scene_header(args.pairs, args.seed, options_note(args), not args.noisy_frame0) + "\n")
    summary = []
    for nv in args.noise_var:
        with tempfile.TemporaryDirectory() as tmp:
            errs, ok, secs, cpu = run_pairs(Path(tmp) / "pairs", args.pairs, nv, args.seed,
                                            track_options(args), not args.noisy_frame0)
        print(f"### {args.pairs} pairs, 688x544, noise variance {nv:g}: "
              f"{ok.sum()}/{len(ok)} converged ({100 * ok.mean():.1f} %), "
              f"{1000 * np.median(secs):.0f} ms median per pair wall, {1000 * np.median(cpu):.0f} ms "
              "CPU (tracking incl. frame-0 model)\n")
        print(table(errs, ok))
        print()
        summary.append((f"noise var {nv:g} ({ok.sum()}/{len(ok)} conv.)", np.abs(errs[ok]).mean(0)))
    summary.append(("paper, noise var 10", PAPER_MEAN))
    print("### Mean absolute error per axis over the converged pairs, by noise variance\n")
    print(axis_table(summary))


if __name__ == "__main__":
    main()
