"""Honesty of the reported std on the sample drives: std(error / reported std) per axis.

    python -m benchmarks.honesty                       # every drive below (~10 min)
    python -m benchmarks.honesty --drives flat-512 mer-512 --renders /tmp/honesty
    python -m benchmarks.honesty --write-docs          # + its section of docs/benchmarks.md

Each drive is a `monovo synth` sequence tracked end to end with the default options on one
thread. Over the `ok` and `reanchored` rows, per axis, the spread (std) of error / reported std
(1 = honest; issue 40 asks for 0.5-2 on every axis: below 0.5 the std is too large, above 2 too
small), its RMS (which counts an error the rows share, the keyframe plane's, that the spread
does not), and the rows more than 4 std off on some axis. The errors are `monovo eval`'s per-frame
relative motion errors (benchmarks.common.motion_errors), in the units of the std columns.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from benchmarks.common import machine, motion_errors, std_columns  # noqa: E402
from benchmarks.docs_section import write_section  # noqa: E402
from monovo_cli.core.options import TrackOptions  # noqa: E402
from monovo_cli.io.formats import read_motion_csv  # noqa: E402
from monovo_cli.pipeline.track import track_sequence  # noqa: E402
from monovo_cli.synth.write import synthesize  # noqa: E402

#: name -> `synthesize` arguments; every drive at noise variance 10, seed 31 (none of the seeds
#: the tests or the other benchmarks use, so nothing here was tuned on them)
DRIVES = {
    "flat-256": dict(preset="drive", frames=100, size=(256, 256)),
    "flat-512": dict(preset="drive", frames=100, size=(512, 512)),
    "gravel-512": dict(preset="drive", frames=100, size=(512, 512), texture="gravel", psf=0.5),
    "rolling-512": dict(preset="drive", frames=100, size=(512, 512), terrain="rolling"),
    "rocks-512": dict(preset="drive", frames=100, size=(512, 512), terrain="rocks"),
    "mer-512": dict(preset="mer", frames=100, size=(512, 512)),
    "mer-1024": dict(preset="mer", frames=60, size=(1024, 1024)),
}
SEED = 31
SECTION = "honesty"


def drive_honesty(seq: Path, out: Path, options: TrackOptions | None = None
                  ) -> tuple[np.ndarray, np.ndarray, int, int]:
    """``(std and RMS of error / std per axis (6,) each, rows counted, rows beyond 4 std)`` of
    monovo on ``seq`` (tracked into ``out``), over its ``ok`` and ``reanchored`` rows."""
    track_sequence(seq, None, out, options or TrackOptions(), threads=1, overwrite=True)
    _, est, status = read_motion_csv(out / "motion.csv")
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    std = std_columns(out / "motion.csv")
    keep = np.array([s in ("ok", "reanchored") for s in status])
    errors = np.array([motion_errors(e, g) for e, g in zip(est, gt)])[keep]
    z = errors / std[keep]
    return (np.std(z, axis=0), np.sqrt(np.mean(z ** 2, axis=0)), int(keep.sum()),
            int(np.sum(np.any(np.abs(z) > 4.0, axis=1))))


def table(rows: list[tuple[str, np.ndarray, np.ndarray, int, int]]) -> str:
    head = ("| drive | rows | tx | ty | tz | rx | ry | rz | RMS of error / std, tx .. rz "
            "| rows beyond 4 std |")
    lines = [head, "|" + " --- |" * 10]
    for name, h, rms, n, beyond in rows:
        cells = " | ".join(("**%.2f**" if not 0.5 <= v <= 2.0 else "%.2f") % v for v in h)
        spread = " ".join(f"{v:.2f}" for v in rms)
        lines.append(f"| {name} | {n} | {cells} | {spread} | {beyond} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", nargs="+", choices=sorted(DRIVES), default=list(DRIVES))
    ap.add_argument("--renders", type=Path, help="keep (and reuse) the rendered drives here")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        renders = args.renders or Path(tmp)
        for name in args.drives:
            seq = renders / f"{name}_{SEED}"
            if not (seq / "groundtruth.tum").exists():
                synthesize(seq, noise_var=10.0, seed=SEED, **DRIVES[name])
            h, rms, n, beyond = drive_honesty(seq, Path(tmp) / f"{name}_out")
            rows.append((name, h, rms, n, beyond))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    text = (f"`python -m benchmarks.honesty --drives {' '.join(args.drives)}`: std(error / reported std)"
            f" per axis over the `ok` and `reanchored` rows (1 = honest, 0.5-2 asked; bold: outside)."
            f"\n\n{machine()}\n\n{table(rows)}\n")
    print(text)
    if args.write_docs:
        write_section(SECTION, "Honesty of the reported std", text)


if __name__ == "__main__":
    main()
