"""The ``track --resume`` checkpoint: size and write time, the pickle monovo wrote before
format 6 against the data-only .npz it writes now, on the same tracking state.

    python -m benchmarks.checkpoint                      # a 512x512 drive at frame 200, ~2 min
    python -m benchmarks.checkpoint --seq DIR --frames 200 --repeats 15
    python -m benchmarks.checkpoint --terrain-out        # the terrain map kept too

A ``monovo synth --preset drive`` sequence (512x512, seed 0; not timed) is tracked in
memory (:class:`~monovo_cli.pipeline.tracking.Tracking`) up to ``--frames``, as ``monovo
track -o DIR`` tracks it (keyframe thumbnails for the report kept, the terrain map with
``--terrain-out``). Its state, in a :class:`~monovo_cli.io.checkpoint.Checkpoint`, is then
written ``--repeats`` times in each format into a temporary folder beside the sequence,
alternating, each write as the run makes it: a temporary file, fsync, rename
(:func:`~monovo_cli.io.atomic.atomic_write_with`). The old format is rebuilt here as it was
(``pickle.dump`` of ``{"format", "monovo", "checkpoint"}`` streamed into the temporary file,
its SHA-256 taken on the way; monovo_cli no longer imports pickle). The new format is timed
twice: as :func:`~monovo_cli.io.checkpoint.write_checkpoint` writes it (no SHA-256: no
record lists the checkpoint) and with the SHA-256 taken as the pickle's was, to show what
the format itself costs. Reported: the file's size, the median (min-max) write time, and
the read time (the new format's checks included; the pickle's load beside it).
"""

from __future__ import annotations

import argparse
import pickle
import statistics
import tempfile
import time
from pathlib import Path

from benchmarks.common import load, machine, one_core
from benchmarks.docs_section import write_section
from monovo_cli.core.options import TrackOptions
from monovo_cli.io.atomic import atomic_write_with
from monovo_cli.io.checkpoint import (
    CHECKPOINT_FILE,
    Checkpoint,
    _write_npz,
    checkpoint_path,
    read_checkpoint,
    write_checkpoint,
)
from monovo_cli.io.state_codec import encode
from monovo_cli.pipeline.report import THUMBNAIL_SIDE, THUMBNAILS
from monovo_cli.pipeline.tracking import Tracking, TrackingState, open_sequence, state_types
from monovo_cli.synth.write import synthesize
from monovo_cli.version import __version__

OLD_FILE = ".track-checkpoint.pkl"


def write_old(out_dir: Path, checkpoint: Checkpoint) -> None:
    """The checkpoint as monovo wrote it before format 6."""
    content = {"format": "monovo-checkpoint-5", "monovo": __version__, "checkpoint": checkpoint}
    atomic_write_with(out_dir / OLD_FILE,
                      lambda f: pickle.dump(content, f, protocol=pickle.HIGHEST_PROTOCOL))


def write_new_hashed(out_dir: Path, checkpoint: Checkpoint, types) -> None:
    """The new format with the SHA-256 of its bytes taken as the pickle's was (write_checkpoint
    no longer takes it: no record lists the checkpoint)."""
    tree, arrays = encode(checkpoint, types)
    atomic_write_with(checkpoint_path(out_dir), lambda f: _write_npz(f, tree, arrays))


def read_old(out_dir: Path) -> Checkpoint:
    return pickle.loads((out_dir / OLD_FILE).read_bytes())["checkpoint"]  # (our own file)


def tracked_state(seq: Path, frames: int, terrain: bool) -> Checkpoint:
    tracking = Tracking(open_sequence(seq), TrackOptions(), terrain=terrain,
                        thumbnails=THUMBNAILS, thumbnail_side=THUMBNAIL_SIDE)
    for _ in tracking:
        if tracking.done >= frames:
            break
    fingerprint = {"monovo": __version__, "command": "track", "inputs": {"sequence": str(seq)}}
    return Checkpoint(tracking.done, fingerprint, tracking.state(), 12345, None, 1.5)


def timed(write, repeats: int) -> list[float]:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        write()
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", type=Path, help="a drive to track (default: render one)")
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--size", default="512x512", help="WxH of the rendered drive")
    ap.add_argument("--repeats", type=int, default=11)
    ap.add_argument("--terrain-out", action="store_true", help="keep the terrain map too")
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite this benchmark's section of docs/benchmarks.md")
    args = ap.parse_args()
    one_core()
    start_load = load()
    print(f"Machine: {machine()}; {start_load} at the start\n")
    with tempfile.TemporaryDirectory(prefix="monovo-checkpoint-") as tmp:
        seq = args.seq
        if seq is None:
            seq = Path(tmp) / "drive"
            w, h = (int(v) for v in args.size.split("x"))
            synthesize(seq, preset="drive", frames=args.frames, size=(w, h), seed=0)
        checkpoint = tracked_state(seq, args.frames, args.terrain_out)
        types = state_types()
        out = Path(tmp) / "out"
        out.mkdir()
        old, new, hashed = [], [], []
        for _ in range(args.repeats):  # alternating: the machine's drift hits all alike
            old += timed(lambda: write_old(out, checkpoint), 1)
            new += timed(lambda: write_checkpoint(out, checkpoint, types), 1)
            hashed += timed(lambda: write_new_hashed(out, checkpoint, types), 1)
        old_size = (out / OLD_FILE).stat().st_size
        new_size = (out / CHECKPOINT_FILE).stat().st_size
        read_new = timed(lambda: read_checkpoint(out, types, TrackingState), 3)
        read_pkl = timed(lambda: read_old(out), 3)
    lines = [f"State after frame {checkpoint.next_frame - 1} of {seq.name} "
             f"({args.size if args.seq is None else 'as given'}"
             f"{', terrain map kept' if args.terrain_out else ''}); "
             f"{args.repeats} writes of each, alternating.", "",
             "| format | size (MB) | write median (ms) | min-max | read median (ms) |",
             "| --- | --- | --- | --- | --- |"]
    for name, size, t, r in (("pickle (before format 6), SHA-256 taken", old_size, old, read_pkl),
                             (".npz + JSON (format 6)", new_size, new, read_new),
                             (".npz + JSON, SHA-256 taken as before", new_size, hashed, None)):
        read = "-" if r is None else f"{1e3 * statistics.median(r):.1f}"
        lines.append(f"| {name} | {size / 1e6:.2f} | {1e3 * statistics.median(t):.1f} | "
                     f"{1e3 * min(t):.1f}-{1e3 * max(t):.1f} | {read} |")
    lines += ["", f"new / old: size {new_size / old_size:.3f}, write time "
              f"{statistics.median(new) / statistics.median(old):.3f} "
              f"({statistics.median(hashed) / statistics.median(old):.3f} with the SHA-256; medians)"]
    text = "\n".join(lines)
    print(text)
    if args.write_docs:
        write_section("checkpoint", "The checkpoint without pickle (issue 43)",
                      f"`python -m benchmarks.checkpoint`\n\n{machine()}; {start_load} at the "
                      f"start, {load()} at the end\n\n{text}\n")
    print(f"\n({load()} at the end.)")


if __name__ == "__main__":
    main()
