"""Regenerate the figures of docs/ from the bundled sample drive.

    python docs/make_figures.py            # from the repo root, with monovo installed

Runs the same commands as docs/guide.md on ``sample_sequences/navcam_drive`` (``monovo
track --groundtruth``, ``monovo overlay --points``, into a temporary directory) and writes

* ``docs/img/overlay.png`` -- the glued triangle in the first frame and in frame
  ``--frame``, side by side like the paper's Figs. 10.4-10.7 (a) and (b);
* ``docs/img/trajectory.png`` -- the ``trajectory.png`` that ``monovo track`` wrote.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SEQ = ROOT / "sample_sequences" / "navcam_drive"
IMG = ROOT / "docs" / "img"


def monovo(*args: str) -> None:
    cmd = [sys.executable, "-m", "monovo_cli", *args, "-q"]
    print("$ monovo " + " ".join(str(a) for a in args))
    subprocess.run(cmd, check=True, cwd=ROOT)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frame", type=int, default=22, help="the second frame shown")
    args = ap.parse_args()
    IMG.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "navcam_drive"  # the plot title names the output directory
        monovo("track", str(SEQ), "-o", str(out), "--groundtruth", str(SEQ / "groundtruth.tum"))
        frames = Path(tmp) / "overlay"
        monovo("overlay", str(SEQ), "-t", str(out / "trajectory.csv"), "-o", str(frames) + "/",
               "--points")
        first = cv2.imread(str(frames / "frame_000000.png"))
        later = cv2.imread(str(frames / f"frame_{args.frame:06d}.png"))
        gap = np.full((first.shape[0], 8, 3), 255, np.uint8)
        pair = np.concatenate([first, gap, later], axis=1)
        cv2.imwrite(str(IMG / "overlay.png"), pair)
        shutil.copyfile(out / "trajectory.png", IMG / "trajectory.png")
    print(f"wrote {IMG / 'overlay.png'} and {IMG / 'trajectory.png'}")


if __name__ == "__main__":
    main()
