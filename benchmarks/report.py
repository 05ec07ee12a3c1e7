"""What report.html costs a ``monovo track`` run: wall time and size.

    python -m benchmarks.report --frames 60 --size 256x256 --repeats 5

Synthesizes one drive (``monovo synth --preset drive``), then tracks it with
``track_sequence`` into an output folder with and without the report (``report=False``),
interleaved ``--repeats`` times so both see the same load, with ``--terrain-out`` and the
ground truth so every section is drawn. Prints a markdown table: the median wall time of
each, their difference, and the report's size; then the median time of the report alone
(``write_report`` on the finished run, thumbnails included, the two figures passed as PNG
bytes as ``track`` passes them).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from benchmarks.common import machine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--size", default="256x256")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))

    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.report import write_report
    from monovo_cli.pipeline.track import track_sequence
    from monovo_cli.pipeline.tracking import Tracking, open_sequence
    from monovo_cli.synth.write import synthesize

    with tempfile.TemporaryDirectory() as tmp:
        seq = Path(tmp) / "seq"
        synthesize(seq, preset="drive", frames=args.frames, size=(w, h), seed=1)
        gt = seq / "groundtruth.tum"
        times: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(args.repeats):
            for report in (False, True):
                t0 = time.perf_counter()
                track_sequence(seq, None, Path(tmp) / f"out{report}", TrackOptions(),
                               overwrite=True, terrain_out=True, groundtruth=gt, report=report)
                times[report].append(time.perf_counter() - t0)
        size = (Path(tmp) / "outTrue" / "report.html").stat().st_size

        opened = open_sequence(seq)
        tracking = Tracking(opened, thumbnails=16, thumbnail_side=200)
        for _ in tracking:
            pass
        run = tracking.result()
        alone = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            write_report(Path(tmp), run, opened.config, {"options": {}, "inputs": {}},
                         title="seq", trajectory_image=_image(), heightmap_image=_image(),
                         thumbnails=tracking.thumbnails, groundtruth=gt)
            alone.append(time.perf_counter() - t0)

    off, on = statistics.median(times[False]), statistics.median(times[True])
    print(f"{machine()}\n")
    print(f"{args.frames} frames of {w}x{h}, --terrain-out and --groundtruth, median of "
          f"{args.repeats}\n")
    print("| | without report | with report | difference | report.html |")
    print("| --- | ---: | ---: | ---: | ---: |")
    print(f"| track_sequence | {off:.2f} s | {on:.2f} s | {on - off:+.2f} s "
          f"({100 * (on - off) / off:+.1f} %) | {size / 1024:.0f} KiB |")
    print(f"\nwrite_report alone: {statistics.median(alone):.3f} s")


def _image() -> bytes:
    """An 800 x 800 PNG, as trajectory.png is."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(0)
    img = np.full((800, 800, 3), 255, np.uint8)
    img[::40] = rng.integers(0, 255, (20, 800, 3), dtype=np.uint8)
    return cv2.imencode(".png", img)[1].tobytes()


if __name__ == "__main__":
    main()
