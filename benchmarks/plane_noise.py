"""The keyframe plane's tilt process noise: the sweep behind ``TILT_CHANGE_DEG``.

    python -m benchmarks.plane_noise                         # 0, 0.5 and 1 deg (~45 min)
    python -m benchmarks.plane_noise --tilts 0 0.5 --cases rolling --frames 100

For each value of :data:`monovo_cli.core.plane.belief.TILT_CHANGE_DEG` (the std of each tilt
angle's process noise per keyframe, see docs/algorithm.md "The new keyframe's plane"), every
sequence is tracked with default options otherwise as ``monovo track`` tracks it (the whole
``pipeline.track.track_sequence`` call, one core; nothing is timed): the real sequences of
``../shared/real`` (``--real DIR`` elsewhere; skipped, with a line saying so, when absent)
and the terrain drives of :mod:`benchmarks.terrain` (rendered once into ``--renders``).
Printed: the final position error as % of the ground-truth path and the final heading error
per sequence and value.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import monovo_cli.core.plane.tracker as plane_tracker
from benchmarks.common import machine, one_core
from benchmarks.peers import monovo_on_drive
from benchmarks.real import REAL, SEQUENCES
from benchmarks.terrain import NOISE_VAR, SIZE
from monovo_cli.synth.terrain import TERRAINS
from monovo_cli.synth.write import synthesize


def sequences(real: Path, renders: Path, cases: list[str], frames: int) -> list[Path]:
    """The sequence folders to track: the real ones present, then the terrain drives."""
    found = [real / name for name in SEQUENCES if (real / name / "init.yaml").exists()]
    if not found:
        print(f"({real} is absent: the real sequences are skipped)")
    for kind in cases:
        seq = renders / f"{kind}_{frames}_0"
        if not (seq / "groundtruth.tum").exists():
            synthesize(seq, preset="drive", terrain=kind, frames=frames, size=SIZE,
                       noise_var=NOISE_VAR, seed=0)
        found.append(seq)
    return found


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tilts", nargs="+", type=float, default=[0.0, 0.5, 1.0],
                    help="values of TILT_CHANGE_DEG to try [0 0.5 1]")
    ap.add_argument("--cases", nargs="+", default=list(TERRAINS), choices=TERRAINS)
    ap.add_argument("--frames", type=int, default=300, help="frames per terrain drive [300]")
    ap.add_argument("--real", type=Path, default=REAL, help="the shared real sequences")
    ap.add_argument("--renders", type=Path, default=Path(tempfile.gettempdir()) / "monovo-terrain",
                    help="where the terrain drives are rendered (reused when present)")
    args = ap.parse_args()
    one_core()
    print(machine())
    seqs = sequences(args.real, args.renders, args.cases, args.frames)
    print("\n| TILT_CHANGE_DEG | " + " | ".join(s.name for s in seqs) + " |")
    print("| --- |" + " --- |" * len(seqs))
    default = plane_tracker.TILT_CHANGE_DEG
    with tempfile.TemporaryDirectory() as tmp:
        for tilt in args.tilts:
            plane_tracker.TILT_CHANGE_DEG = tilt
            cells = []
            for seq in seqs:
                r = monovo_on_drive(seq, Path(tmp) / seq.name, overwrite=True)
                err, dist, heading = r.drift
                cells.append(f"{100 * err / dist:.2f} % / {heading:.2f}°")
            mark = " (default)" if tilt == default else ""
            print(f"| {tilt:g}°{mark} | " + " | ".join(cells) + " |", flush=True)
    plane_tracker.TILT_CHANGE_DEG = default
    print("\n(cells: final position error, % of the path / final heading error)")


if __name__ == "__main__":
    main()
