"""Long drives that never get lost: the Drives issue's acceptance, measured.

    python -m benchmarks.drives                 # all cases, 1000 frames each (~20 min)
    python -m benchmarks.drives --frames 300 --cases clean faults

Cases, each a `monovo synth --preset drive` at 512x512, noise variance 10, tracked with
default options by `monovo track`'s library call on one thread:
  clean      the plain drive;
  exposure   gain drifting 0.8-1.2 and bias +-15 grey levels (`--exposure`);
  shadow     a dark fixed region (x0.5) over the bottom 15 % of the image (`--shadow 0.15`);
  lowtex     a smooth, low-contrast ground (`--low-texture`);
  faults     the clean drive with 3 blank, 3 duplicated and 3 heavily blurred frames
             injected; each must be flagged -- lost, or tracked with a reported std over 3x
             the typical one (low weight) -- and tracking must resume within 2 frames: the
             first frame after the fault that is not lost and whose position relative to
             frame 0 is within 1 cm of the truth again ("never" if none is).
frames/s is the frame loop's, the figure `monovo track` logs: frame 0's ground model, the
decode and estimate of frames 1 on, the motion.csv rows and the periodic checkpoints; not
frame 0's decode, the smoothing in hindsight or the files written at the end
(`benchmarks.drive` gives both this and the whole call's).
Also `--pairs N` (default 100): the honesty of the reported standard deviations, the
spread (std) of error / reported std per parameter over N `synth pairs`.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.common import final_drift, machine, motion_errors, std_columns  # noqa: E402
from benchmarks.docs_section import writes_section  # noqa: E402
from monovo_cli import iter_track  # noqa: E402
from monovo_cli.core.options import TrackOptions  # noqa: E402
from monovo_cli.io.formats import read_motion_csv, read_tum  # noqa: E402
from monovo_cli.pipeline.track import track_sequence  # noqa: E402
from monovo_cli.synth.write import synthesize  # noqa: E402

RESUMED_M = 0.01  # position error, m: tracking has resumed after a fault within this of the truth
SYNTH = {"clean": {}, "exposure": {"exposure": True}, "shadow": {"shadow": 0.15},
         "lowtex": {"low_texture": True}}


def inject_faults(frames_dir: Path, n_frames: int, seed: int = 0) -> dict[int, str]:
    """Overwrite 9 frames: 3 blank, 3 duplicates of their predecessor, 3 heavily blurred."""
    rng = np.random.default_rng(seed)
    picks = rng.choice(np.arange(20, n_frames - 5, 10), size=9, replace=False)
    kinds = ["blank"] * 3 + ["duplicate"] * 3 + ["blur"] * 3
    paths = sorted(frames_dir.glob("*.png"))
    out = {}
    for k, kind in zip(sorted(picks), kinds):
        if kind == "blank":
            img = np.zeros_like(cv2.imread(str(paths[k]), cv2.IMREAD_GRAYSCALE))
        elif kind == "duplicate":
            img = cv2.imread(str(paths[k - 1]), cv2.IMREAD_GRAYSCALE)
        else:
            img = cv2.GaussianBlur(cv2.imread(str(paths[k]), cv2.IMREAD_GRAYSCALE), (0, 0), 6.0)
        cv2.imwrite(str(paths[k]), img)
        out[int(k)] = kind
    return out


def frames_to_resume(k: int, status: list[str], est: np.ndarray, gt: np.ndarray) -> int | None:
    """Frames after fault frame ``k`` until tracking has resumed, None if it never does
    (``status`` per frame, frame 0 first; ``est`` and ``gt`` the poses T_0_j (N, 4, 4))."""
    # tracking has resumed at frame j when j is not lost and its position relative to frame 0
    # is within RESUMED_M (1 cm) of the truth again
    for j in range(k + 1, len(status)):
        if status[j] != "lost" and np.linalg.norm(est[j][:3, 3] - gt[j][:3, 3]) <= RESUMED_M:
            return j - k
    return None


def run_case(root: Path, name: str, frames: int, seed: int) -> dict:
    seq = root / name
    synthesize(seq, preset="drive", frames=frames, noise_var=10.0, seed=seed,
               **SYNTH.get(name, {}))
    faults = inject_faults(seq / "frames", frames) if name == "faults" else {}
    s = track_sequence(seq, None, root / f"{name}_out", TrackOptions(), threads=1)
    _, est = read_tum(root / f"{name}_out" / "trajectory.tum")
    _, gt = read_tum(seq / "groundtruth.tum")
    err, dist, heading = final_drift(est, gt)
    _, _, status = read_motion_csv(root / f"{name}_out" / "motion.csv")
    status = ["ok"] + status
    std = np.vstack([np.zeros(6), std_columns(root / f"{name}_out" / "motion.csv")])
    typical = np.nanmedian(std[1:], axis=0)
    # flagged: lost, or tracked with a reported std over 3x the typical one (low weight)
    low_weight = [k for k in faults if status[k] != "lost" and np.nanmax(std[k] / typical) > 3.0]
    flagged = sum(status[k] == "lost" for k in faults) + len(low_weight)
    resume = [frames_to_resume(k, status, est, gt) for k in faults]
    lost_outside = sum(1 for k, st in enumerate(status) if st == "lost" and k not in faults)
    shutil.rmtree(seq)
    return {"case": name, "frames": frames, "distance": dist, "error": err,
            "pct": 100 * err / dist, "heading": heading, "lost": lost_outside,
            "faults_flagged": (f"{flagged}/{len(faults)}" + (f" ({len(low_weight)} by std)"
                                                               if low_weight else "")
                               if faults else "-"),
            "resume": ("never" if None in resume else max(resume)) if resume else "-", "fps": s.fps,
            "reanchored": status.count("reanchored")}


def std_honesty(root: Path, n_pairs: int, seed: int) -> np.ndarray:
    """Per parameter: std of (error / reported std) over ``n_pairs`` pairs."""
    synthesize(root / "pairs", preset="pairs", frames=n_pairs, noise_var=10.0, seed=seed)
    z = []
    for pair in sorted((root / "pairs").glob("pair_*")):
        res = list(iter_track(pair))
        _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
        e = motion_errors(res[1].prev_from_cur, gt[0])
        e[3:] = np.radians(e[3:])
        z.append(e / res[1].std)
    return np.array(z)


@writes_section("drives", "Accuracy on long drives", "benchmarks.drives")
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--cases", nargs="+", default=["clean", "exposure", "shadow", "lowtex", "faults"])
    ap.add_argument("--pairs", type=int, default=100)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print(f"machine: {machine()}\n")
    print("| case | frames | distance (m) | final error (m) | % of distance | heading error (deg) "
          "| lost (outside faults) | faults flagged | resumed within (frames) | re-anchored | "
          "frames/s (frame loop) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases:
            r = run_case(Path(tmp), name, args.frames, args.seed)
            print(f"| {r['case']} | {r['frames']} | {r['distance']:.2f} | {r['error']:.4f} | "
                  f"{r['pct']:.3f} | {r['heading']:.3f} | {r['lost']} | {r['faults_flagged']} | "
                  f"{r['resume']} | {r['reanchored']} | {r['fps']:.1f} |", flush=True)
        if args.pairs:
            z = std_honesty(Path(tmp), args.pairs, args.seed)
            print(f"\nHonesty of the reported std over {args.pairs} pairs: std of error/std per "
                  "parameter (1 = exact, acceptance 0.5-2)\n")
            print("| tx | ty | tz | rx | ry | rz |\n| --- | --- | --- | --- | --- | --- |")
            print("| " + " | ".join(f"{v:.2f}" for v in z.std(axis=0)) + " |")


if __name__ == "__main__":
    main()
