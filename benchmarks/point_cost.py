"""What the speed targets of issue 26 would cost: observation points against speed and accuracy.

    python -m benchmarks.point_cost                        # 256² and 512², ~10 min
    python -m benchmarks.point_cost --sizes 512 --frames 100 --shares 1 0.5
    python -m benchmarks.point_cost --sections information   # seconds

The one setting that scales the frame loop's per-point work (every residual evaluation,
every weighted normal matrix, the keyframes' rows) is the number of observation points. Issue 26 asks for
≥ 6x the ECC peer at 512² and ≥ 5x at 256² "without giving back accuracy"; this script says
what the first would cost in the second, so that the trade is a decision made on figures.

For each size, on two 100-frame ``monovo synth --preset drive`` sequences (noise variance 10,
seed 0), the built-in procedural texture the constants were chosen on and ``gravel``, which
they were not, and for each share of monovo's default point budget (one point per 2 pixels:
``--max-points`` = share x width x height / 2):

* **speed** -- monovo end to end on one thread (``peers.monovo_on_drive``: the whole
  ``track_sequence`` call, from reading init.yaml and frame 0 to the last file written,
  report.html and trajectory.png included) against the ECC peer (``peers.EccPeer``, its 1e-6
  stop; its whole loop: decode, estimate, decomposition, no file written) on the same PNGs,
  one thread each: ECC, then every share once, then ECC again, ``--repeats`` times; each monovo
  run against the mean of the ECC runs either side of it; the median ratio of the repeats
  and their range (wall clock; CPU time in brackets);
* **accuracy** -- the final position error (% of the path), the RMS over the frames of the
  per-frame translation (mm) and rotation (mdeg) errors against groundtruth_motion.csv, and
  the median reported std of tx (mm) and rz (mdeg) of motion.csv: the noise's share of the
  error, which grows as points are dropped.

**information** -- issue 26 suggests dropping "points where they carry no information (their
Fisher information is known)". On frame 0's keyframe of each drive (the finest level's rows
o_i, the brightness columns included, as the estimator solves them), the noise-only std of
each motion axis from a subset of the points against that from all of them, sqrt of the
diagonal of (O_S^T O_S)^-1 over (O^T O)^-1, for subsets of a given share kept by three rules:
the strongest gradients (what ``--max-points`` keeps at full resolution), the largest
leverage o_i^T (O^T O)^-1 o_i (each point's share of the information, the best a rule can
do point by point), and at random (seed 0). 1.00 = nothing lost; with points of equal
information a share s gives 1/sqrt(s).

With ``../shared/real`` present (``--real DIR`` elsewhere; said when absent), the real
sequences desk_b and kitti_ramp are tracked at each share too (final error % of the path,
frames/s of the whole ``track_sequence`` call), since fewer points could matter less where
the model's error, not the noise, dominates. Their default budget does not bind (fewer
pixels than that pass the gradient threshold in their regions), so there a share is of the
median points a frame used at the default. One core (OpenCV, BLAS), fixed seeds.
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.common import Stopwatch, load, machine, one_core, std_columns
from benchmarks.integrity import final_pct
from benchmarks.peers import EccPeer, monovo_on_drive, peer_on_drive
from benchmarks.real import REAL, real_sequences
from monovo_cli.core.odometry import Odometry
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.formats import read_tum
from monovo_cli.pipeline.track import track_sequence
from monovo_cli.pipeline.tracking import open_sequence
from monovo_cli.synth.write import synthesize

SHARES = (1.0, 0.75, 0.5, 0.35)
INFO_SHARES = (0.9, 0.75, 0.5)
SECTIONS = ("information", "drives", "real")
TEXTURES = ("procedural", "gravel")
#: issue 26's end-to-end targets against the ECC peer, by size
TARGETS = {256: 5.0, 512: 6.0}


def cap(share: float, width: int, height: int) -> int:
    """``--max-points`` for ``share`` of the default budget (one point per 2 pixels)."""
    per = TrackOptions().pixels_per_point
    return int(round(share * width * height / per))


def median_points(out: Path) -> int:
    """The median observation points a frame used in a run (motion.csv's ``points``)."""
    with open(out / "motion.csv", newline="") as f:
        return int(np.median([int(r["points"]) for r in csv.DictReader(f) if r["points"]]))


def drive_row(size: int, texture: str, share: float, mono, ratios: list[tuple[float, float]],
              out: Path) -> str:
    """One table row: speed against ECC (``ratios``, (wall, CPU) per repeat) and accuracy of
    one monovo run (``mono``, a ``peers.MethodResult``; ``out`` its output folder)."""
    err, dist, _ = mono.drift
    e = mono.errors
    ok = ~np.isnan(e[:, 0])
    t_rms = 1000 * np.sqrt(np.mean(np.sum(e[ok, :3] ** 2, axis=1)))
    r_rms = 1000 * np.sqrt(np.mean(np.sum(e[ok, 3:] ** 2, axis=1)))
    std = std_columns(out / "motion.csv")
    wall, cpu = np.array(ratios).T
    return (f"| {size}² | {texture} | {share:g} | {cap(share, size, size)} | "
            f"{np.median(wall):.2f} ({np.median(cpu):.2f}); {wall.min():.2f}-{wall.max():.2f} | "
            f"{median_points(out)} | {100 * err / dist:.3f} | {t_rms:.3f} | {r_rms:.2f} | "
            f"{1000 * np.nanmedian(std[:, 0]):.3f} | {1000 * np.nanmedian(std[:, 5]):.2f} | "
            f"{mono.failed} |")


def drives(sizes: list[int], shares: list[float], frames: int, repeats: int,
           root: Path) -> list[str]:
    """The drive rows. Per drive, ECC and monovo's runs alternate: ECC, every share, ECC, every
    share, ... ECC; a share's ratio in a repeat is against the mean of the ECC runs either side
    of it (the machine's speed drifts within minutes)."""
    rows = []
    for size in sizes:
        for texture in TEXTURES:
            seq = render(root, size, texture, frames)
            ecc = [peer_on_drive(EccPeer(), seq)]
            runs: dict[float, list] = {share: [] for share in shares}
            for _ in range(repeats):
                for share in shares:
                    out = root / f"o{size}_{texture}_{share:g}"
                    opts = TrackOptions(max_points=cap(share, size, size))
                    runs[share].append(monovo_on_drive(seq, out, opts, overwrite=True))
                ecc.append(peer_on_drive(EccPeer(), seq))
            for share in shares:
                ratios = [(0.5 * (a.seconds + b.seconds) / m.seconds, 0.5 * (a.cpu + b.cpu) / m.cpu)
                          for a, b, m in zip(ecc, ecc[1:], runs[share])]
                out = root / f"o{size}_{texture}_{share:g}"
                rows.append(drive_row(size, texture, share, runs[share][-1], ratios, out))
            print(f"({size}² {texture} done, {load()})", file=sys.stderr)
    return rows


def render(root: Path, size: int, texture: str, frames: int) -> Path:
    """The drive of ``size`` and ``texture`` under ``root`` (rendered once)."""
    seq = root / f"d{size}_{texture}"
    if not (seq / "init.yaml").is_file():
        synthesize(seq, preset="drive", frames=frames, size=(size, size), noise_var=10.0,
                   seed=0, texture=None if texture == "procedural" else texture)
    return seq


def noise_std(J: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The noise-only std (6,) of the motion from the rows ``J[index]`` (unit noise)."""
    return np.sqrt(np.diag(np.linalg.inv(J[index].T @ J[index]))[:6])


def information_rows(sizes: list[int], frames: int, root: Path) -> list[str]:
    """The information section's rows (frame 0's keyframe of each drive)."""
    rng = np.random.default_rng(0)
    rows = []
    for size in sizes:
        for texture in TEXTURES:
            seq = open_sequence(render(root, size, texture, frames))
            cfg = seq.config
            odometry = Odometry(cfg.camera, cfg.plane, cfg.region, TrackOptions(),
                                mounting=cfg.mounting)
            odometry.start(0, 0.0, seq.first.image)
            level = odometry.keyframe.levels[0]
            J = level.rows.astype(np.float64)
            n = len(J)
            full = noise_std(J, np.arange(n))
            leverage = np.einsum("ij,jk,ik->i", J, np.linalg.inv(J.T @ J), J)
            gradient = np.sum(level.points.grad.astype(np.float64) ** 2, axis=1)
            for share in INFO_SHARES:
                k = int(share * n)
                for rule, index in (("strongest gradients", np.argsort(-gradient)[:k]),
                                    ("largest leverage", np.argsort(-leverage)[:k]),
                                    ("random", rng.choice(n, k, replace=False))):
                    ratio = noise_std(J, index) / full
                    rows.append(f"| {size}² | {texture} | {n} | {share:g} | {rule} | "
                                + " | ".join(f"{x:.3f}" for x in ratio) + " |")
    return rows


def real_rows(shares: list[float], real: Path, root: Path) -> list[str] | None:
    if 1.0 not in shares:  # (the others are shares of what share 1 used)
        raise SystemExit("--shares must include 1 for the real sequences")
    seqs = real_sequences(real)
    if seqs is None:
        return None
    rows = []
    for seq in seqs:
        used = None  # the median points a frame used at the default budget
        for share in sorted(shares, reverse=True):
            out = root / f"{seq.name}_{share:g}"
            opts = TrackOptions() if used is None else TrackOptions(max_points=int(share * used))
            with Stopwatch() as watch:
                track_sequence(seq.directory, None, out, opts, overwrite=True, threads=1)
            _, traj = read_tum(out / "trajectory.tum")
            if used is None:
                used = median_points(out)
            rows.append(f"| {seq.name} | {share:g} | {opts.max_points or 'default'} | "
                        f"{median_points(out)} | {final_pct(traj, seq.gt_world_from_cam):.2f} | "
                        f"{len(traj) / watch.wall:.1f} ({len(traj) / watch.cpu:.1f}) |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--shares", type=float, nargs="+", default=list(SHARES))
    ap.add_argument("--repeats", type=int, default=3,
                    help="monovo runs per share and drive, between ECC runs [default: 3]")
    ap.add_argument("--real", type=Path, default=REAL)
    ap.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    with tempfile.TemporaryDirectory() as tmp:
        if "information" in args.sections:
            print("### The information of the points: noise-only std of a subset of frame 0's "
                  "points over all of them's (no unit)\n")
            print("| size | texture | points | share kept | kept by | tx | ty | tz | rx | ry | rz |")
            print("| --- " * 11 + "|")
            print("\n".join(information_rows(args.sizes, args.frames, Path(tmp))) + "\n")
        if "drives" in args.sections:
            rows = drives(args.sizes, args.shares, args.frames, args.repeats, Path(tmp))
            print(f"### Observation points against speed and accuracy ({args.frames}-frame drives, "
                  "noise variance 10, seed 0; one thread each)\n")
            print("| size | texture | share of the default points | `--max-points` | monovo / ECC, "
                  "wall (CPU), median of the repeats; range | points a frame used (median) "
                  "| final error (% of path) "
                  "| per-frame translation error, RMS (mm) | per-frame rotation error, RMS (mdeg) "
                  "| median std tx (mm) | median std rz (mdeg) | lost |")
            print("| --- " * 12 + "|")
            print("\n".join(rows) + "\n")
            print("Issue 26's targets against the ECC peer: "
                  + ", ".join(f"{s}² ≥ {TARGETS[s]:g}x" for s in args.sizes if s in TARGETS) + ".\n")
        if "real" in args.sections:
            real = real_rows(args.shares, args.real, Path(tmp))
            if real is not None:
                print("### The real sequences at the same shares (`monovo track --threads 1`, "
                      "default options but `--max-points`)\n")
                print("| sequence | share of the default's points | `--max-points` | points a "
                      "frame used (median) | final error (% of path) | frames/s wall (CPU), whole call |")
                print("| --- " * 6 + "|")
                print("\n".join(real) + "\n")
    print(f"({load()} at the end.)")


if __name__ == "__main__":
    main()
