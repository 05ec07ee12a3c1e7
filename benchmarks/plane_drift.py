"""The keyframe planes' tilt against the true ground, with and without the motion's share in
the carried plane's covariance (issue 24; docs/algorithm.md section 4).

    python -m benchmarks.plane_drift                 # mer-1024: 1024², 40 frames, ~3 min
    python -m benchmarks.plane_drift --size 256 --frames 30 --seed 5

A MER-spacing drive (``monovo synth --preset mer``: 0.6-0.75 m steps, turns in place, flat
ground, so the plane model is exact; noise variance 10) is tracked twice with default options,
on one core:

* **with S** -- as monovo runs: the plane carried to a new keyframe errs by
  ``(J_plane + J_motion S) dx`` (``carrying_jacobian``);
* **without S** -- ``carrying_jacobian`` told to ignore the sensitivity for the duration of
  the run (the plane's and the motion's errors taken as independent, as before 2026-11-25).

For each, every keyframe's plane normal is compared with the true ground's in that camera
(``terrain.npz``'s ``g_from_cam``): the angle between them (deg), at the worst keyframe and at
the last, and the final error of the trajectory written (% of the path). The default drive is
``benchmarks.integrity``'s mer-1024 (seed 14, frames 12 and 25 blanked).
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

import monovo_cli.core.plane.belief as belief
import monovo_cli.core.plane.tracker as tracker
from benchmarks.common import keyframe_tilt_errors, load, machine, one_core
from benchmarks.integrity import blank, final_pct, table
from monovo_cli import track_frames
from monovo_cli.io.formats import read_tum
from monovo_cli.synth.write import synthesize


@contextlib.contextmanager
def without_sensitivity() -> Iterator[None]:
    """``carrying_jacobian`` ignores its sensitivity (in belief and tracker) inside."""
    original = belief.carrying_jacobian

    def plane_block_only(J: np.ndarray, sensitivity: np.ndarray | None) -> np.ndarray:
        return original(J, None)

    belief.carrying_jacobian = tracker.carrying_jacobian = plane_block_only
    try:
        yield
    finally:
        belief.carrying_jacobian = tracker.carrying_jacobian = original


def tilt_errors(seq: Path) -> tuple[list[float], float]:
    """(each keyframe's tilt error, deg; the final error, % of the path) of ``seq`` tracked."""
    run = track_frames(seq)
    _, gt = read_tum(seq / "groundtruth.tum")
    return list(keyframe_tilt_errors(run, seq).values()), final_pct(run.trajectory, gt)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=1024, help="image side, px (default 1024)")
    ap.add_argument("--frames", type=int, default=40, help="frames (default 40)")
    ap.add_argument("--seed", type=int, default=14, help="the drive's seed (default 14)")
    ap.add_argument("--blank", type=int, nargs="*", default=[12, 25],
                    help="frames to blank (default 12 25)")
    args = ap.parse_args()
    one_core()
    print(f"Machine: {machine()}; {load()} at the start\n")
    with tempfile.TemporaryDirectory() as tmp:
        seq = Path(tmp) / "mer"
        synthesize(seq, preset="mer", frames=args.frames, size=(args.size, args.size),
                   noise_var=10.0, seed=args.seed)
        blank(seq, tuple(k for k in args.blank if k < args.frames))
        rows = []
        for name, context in (("with S", contextlib.nullcontext()),
                              ("without S", without_sensitivity())):
            with context:
                errors, final = tilt_errors(seq)
            rows.append([name, str(len(errors)), f"{max(errors):.4f}", f"{errors[-1]:.4f}",
                         f"{final:.2f}"])
    print(f"MER drive, {args.size}², {args.frames} frames, seed {args.seed}, blank frames "
          f"{' '.join(map(str, args.blank)) or 'none'}\n")
    print(table("| carried plane | keyframes | worst keyframe's tilt error (deg) | last "
                "keyframe's (deg) | final error (% of path) |", rows) + "\n")
    print(f"({load()} at the end.)")


if __name__ == "__main__":
    main()
