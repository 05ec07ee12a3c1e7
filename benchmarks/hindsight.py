"""The trajectory in hindsight, measured: what re-scaling the keyframes' segments does.

    python -m benchmarks.hindsight                      # 4 terrain drives + a plane drive, 300 frames
    python -m benchmarks.hindsight --frames 150 --seed 1 --cases flat plane
    python -m benchmarks.hindsight --frames 1000 --seed 7 --cases plane shadow lowtex

Each drive is tracked once, with default options (``monovo_cli.track_frames``), and its
poses written four ways (docs/algorithm.md, "The trajectory in hindsight"):

  streamed    motion.csv's motions composed (``track --no-smooth``);
  keyframes   re-scaled with the keyframe distances solved over the chain with the mounting
              prior at the keyframes alone, as the filter had it (close to the plain backward
              pass of the smoother);
  segments    the mounting prior on the mean over each keyframe's segment, translations
              re-scaled only;
  written     what trajectory.csv holds: the segments' distances, and where the drive's
              ground was seen as a plane the motions re-read against the smoothed tilts too;

and on the plane drives a fifth, the written way with the keyframes' **true planes** (init.yaml's,
carried by the true poses) in place of the smoothed ones: what the re-reading itself leaves,
apart from the smoother's error.

Cases: ``flat``, ``rolling``, ``slope``, ``rocks`` (``monovo synth --preset drive --terrain
KIND``: the rover bobs, frame 0 at a crest, init.yaml the nominal plane), ``plane``
(``--preset drive`` without terrain: an exact init.yaml) and the plane drive with the cases of
``benchmarks.drives``: ``exposure``, ``shadow``, ``lowtex`` (a smooth, low-contrast ground).
Reported: the final position error (% of the distance) and the position error's RMS over
the whole drive (mm) of each, and where the true keyframe distance is defined (flat: the
camera's height above the ground; plane and its variants: the init plane carried by the true
poses) keyframe 0's distance error (mm) and the RMS over the keyframes (mm), filtered (as
anchored) and solved in hindsight.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.common import final_drift, load, machine, one_core
from benchmarks.drives import SYNTH as DRIVE_CASES
from monovo_cli import track_frames
from monovo_cli.geometry.lie import se3_inv
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.mapping.smoothing import (
    segment_log_distance_ratios,
    smooth_drive,
    smoothed_distances,
    smoothed_poses,
)
from monovo_cli.synth.write import synthesize

CASES = ("flat", "rolling", "slope", "rocks", "plane", "exposure", "shadow", "lowtex")
#: The plane drive and its variants: ``benchmarks.drives``' cases, its "clean" named "plane".
PLANE_CASES = {"plane": DRIVE_CASES["clean"],
               **{k: DRIVE_CASES[k] for k in ("exposure", "shadow", "lowtex")}}


def render(root: Path, kind: str, frames: int, seed: int) -> Path:
    seq = root / f"{kind}_{frames}_{seed}"
    if not (seq / "groundtruth.tum").exists():
        extra = PLANE_CASES.get(kind, {"terrain": kind})
        synthesize(seq, preset="drive", frames=frames, size=(512, 512), noise_var=10.0,
                   seed=seed, **extra)
    return seq


def run_case(seq: Path, kind: str) -> dict:
    run = track_frames(seq)
    index, W = list(run.index), run.world_from_cam
    chain = [(k.index, k) for k in run.keyframes]
    _, gt = read_tum(seq / "groundtruth.tum")
    ways = {"streamed": W, "keyframes": smoothed_poses(index, W, chain, segments=False),
            "segments": smoothed_poses(index, W, chain), "written": run.trajectory}
    if kind in PLANE_CASES:  # the written way with the true planes: the re-reading's own error
        ways["true planes"] = smooth_drive(index, W, chain, tilts=True,
                                           planes=true_planes(seq, chain, gt)).world_from_cam
    row = {"kind": kind, "frames": run.frames, "keys": len(chain)}
    for name, P in ways.items():
        err, dist, _ = final_drift(P, gt)
        rms = float(np.sqrt(np.mean(np.sum((P[:, :3, 3] - gt[:, :3, 3]) ** 2, axis=1))))
        row[name] = (100 * err / dist, 1000 * rms)
    true = true_distances(seq, kind, chain, gt)
    if true is not None:
        anchored = [k for _, k in chain]
        filtered = np.array([k.plane.distance for k in anchored])
        solved = smoothed_distances(anchored, segment_log_distance_ratios(index, W, chain))
        row["distances"] = [(1000 * abs(d[0] - true[0]), 1000 * float(np.sqrt(np.mean((d - true) ** 2))))
                            for d in (filtered, solved)]
    return row


def true_distances(seq: Path, kind: str, chain, gt: np.ndarray) -> np.ndarray | None:
    """The true distance (m) of each keyframe's camera to the ground, where it is a plane."""
    if kind == "flat":  # the ground is z = 0 of the terrain's frame
        g_from_cam = np.load(seq / "terrain.npz")["g_from_cam"]
        return np.array([g_from_cam[i][2, 3] for i, _ in chain])
    if kind in PLANE_CASES:
        return np.array([p.distance for p in true_planes(seq, chain, gt)])
    return None


def true_planes(seq: Path, chain, gt: np.ndarray) -> list:
    """Each keyframe's true plane in its camera on a plane drive: init.yaml is exact there,
    frame 0's plane, carried by the true poses."""
    plane0 = load_init(seq / "init.yaml").plane
    return [plane0.in_frame(se3_inv(gt[i]) @ gt[0]) for i, _ in chain]


def table(rows: list[dict]) -> str:
    lines = ["| drive | frames / keyframes | final error (%): streamed / keyframes / segments / "
             "written | position RMS (mm): streamed / keyframes / segments / written | "
             "written with the true planes: final error (%), position RMS (mm) | "
             "keyframe 0's distance error "
             "(mm): filtered / solved | keyframe distances' RMS error (mm): filtered / solved |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        ways = ("streamed", "keyframes", "segments", "written")
        pct = " / ".join(f"{r[w][0]:.3f}" for w in ways)
        rms = " / ".join(f"{r[w][1]:.2f}" for w in ways)
        d = r.get("distances")
        d0 = f"{d[0][0]:.1f} / {d[1][0]:.1f}" if d else "—"
        drms = f"{d[0][1]:.1f} / {d[1][1]:.1f}" if d else "—"
        tp = r.get("true planes")
        oracle = f"{tp[0]:.3f}, {tp[1]:.2f}" if tp else "—"
        lines.append(f"| {r['kind']} | {r['frames']} / {r['keys']} | {pct} | {rms} | {oracle} | "
                     f"{d0} | {drms} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    ap.add_argument("--renders", type=Path, default=None,
                    help="keep (and reuse) the rendered drives in this folder")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    with tempfile.TemporaryDirectory() as tmp:
        root = args.renders or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        rows = []
        for kind in args.cases:
            rows.append(run_case(render(root, kind, args.frames, args.seed), kind))
            print(f"({kind} done)", flush=True)
    print(f"\nDrives of {args.frames} frames, seed {args.seed}, 512x512, noise variance 10, "
          "default options, one core.\n")
    print(table(rows))
    print(f"\n({load()} at the end.)")


if __name__ == "__main__":
    main()
