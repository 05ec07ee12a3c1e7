"""A synthetic rover drive tracked by ``monovo track``'s library call: drift and frames/s.

    python benchmarks/drive.py --frames 300 --size 512x512 --noise-var 10

Renders ``monovo synth --preset drive``, runs ``monovo track``'s library call
(``pipeline.track.track_sequence``) on one core (OpenCV and BLAS limited to one thread) and
prints the final position error as % of the distance travelled, the final heading error,
lost/re-anchored frames and frames/s twice:

* **frame loop** -- the figure ``monovo track`` logs: frame 0's ground model, the decode and
  estimate of frames 1 on, the motion.csv rows and the periodic checkpoints; not frame 0's
  decode (done when the sequence is opened), nor the smoothing in hindsight and the files
  written at the end;
* **whole call** -- everything ``track_sequence`` does: reading init.yaml and frame 0, the frame
  loop, the smoothing in hindsight and every file (motion.csv, trajectory.csv and .tum,
  trajectory.png, report.html, run.yaml); not Python's start-up and imports.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


from benchmarks.common import Stopwatch, drive_arguments, final_drift, machine  # noqa: E402
from monovo_cli.core.options import TrackOptions  # noqa: E402
from monovo_cli.io.formats import read_motion_csv, read_tum  # noqa: E402
from monovo_cli.pipeline.track import track_sequence  # noqa: E402
from monovo_cli.synth.write import synthesize  # noqa: E402


def run_drive(root: Path, frames: int, size: tuple[int, int], noise_var: float, seed: int,
              options: TrackOptions | None = None, **synth_kw) -> dict:
    synthesize(root / "seq", preset="drive", frames=frames, size=size, noise_var=noise_var,
               seed=seed, **synth_kw)
    with Stopwatch() as watch:
        s = track_sequence(root / "seq", None, root / "out", options or TrackOptions(), threads=1)
    _, est = read_tum(root / "out" / "trajectory.tum")
    _, gt = read_tum(root / "seq" / "groundtruth.tum")
    err, dist, heading = final_drift(est, gt)
    _, _, status = read_motion_csv(root / "out" / "motion.csv")
    return {"frames": frames, "size": f"{size[0]}x{size[1]}", "distance_m": dist, "error_m": err,
            "error_pct": 100 * err / dist, "heading_deg": heading, "fps": s.fps,
            "fps_call": frames / watch.wall,
            "lost": status.count("lost"), "reanchored": status.count("reanchored"),
            "mean_msd": s.mean_msd}


def main() -> None:
    args, (w, h) = drive_arguments(__doc__)
    print(f"machine: {machine()}\n")
    with tempfile.TemporaryDirectory() as tmp:
        r = run_drive(Path(tmp), args.frames, (w, h), args.noise_var, args.seed)
    print("| frames | size | distance (m) | final error (m) | error (% of distance) | heading error (deg) "
          "| lost | re-anchored | mean msd | frames/s, frame loop (1 core) | frames/s, whole call "
          "(1 core) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    print(f"| {r['frames']} | {r['size']} | {r['distance_m']:.2f} | {r['error_m']:.4f} | "
          f"{r['error_pct']:.3f} | {r['heading_deg']:.3f} | {r['lost']} | {r['reanchored']} | "
          f"{r['mean_msd']:.2f} | {r['fps']:.1f} | {r['fps_call']:.1f} |")


if __name__ == "__main__":
    main()
