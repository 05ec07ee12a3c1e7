"""Regenerate the figures of docs/ from the bundled sample drive.

    python docs/make_figures.py            # from the repo root, with monovo installed

Runs the same commands as docs/guide.md on ``sample_sequences/navcam_drive`` (``monovo
track --groundtruth``, ``monovo overlay --points``, into a temporary directory) and writes

* ``docs/img/overlay.png`` -- the glued triangle in the first frame and in frame
  ``--frame``, side by side like the paper's Figs. 10.4-10.7 (a) and (b);
* ``docs/img/trajectory.png`` -- the ``trajectory.png`` that ``monovo track`` wrote;
* ``docs/img/report.png`` -- the top of the ``report.html`` it wrote (with ``--terrain-out``),
  as headless Chromium shows it at 1100 px wide, scaled to 800 px; skipped with a note when
  no ``chromium`` is on the PATH (Debian: ``apt-get install chromium``).
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
        monovo("track", str(SEQ), "-o", str(out), "--groundtruth", str(SEQ / "groundtruth.tum"),
               "--terrain-out")
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
        report_screenshot(out / "report.html", Path(tmp) / "shot.png")


def report_screenshot(report: Path, shot: Path, *, width: int = 1100, height: int = 1720,
                      scaled: int = 800, keep: int = 1180) -> None:
    """docs/img/report.png: ``report`` in headless Chromium, ``width`` x ``height`` px,
    scaled to ``scaled`` px wide and its top ``keep`` px kept."""
    browser = next((b for b in ("chromium", "chromium-browser", "google-chrome")
                    if shutil.which(b)), None)
    if browser is None:
        print("no chromium on the PATH: docs/img/report.png left as it is")
        return
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu",
                    "--disable-background-networking", "--hide-scrollbars",
                    f"--screenshot={shot}", f"--window-size={width},{height}",
                    report.as_uri()], check=True, capture_output=True)
    img = cv2.imread(str(shot))
    img = cv2.resize(img, (scaled, round(img.shape[0] * scaled / img.shape[1])),
                     interpolation=cv2.INTER_AREA)[:keep]
    cv2.imwrite(str(IMG / "report.png"), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {IMG / 'report.png'}")


if __name__ == "__main__":
    main()
