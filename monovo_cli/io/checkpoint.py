"""The checkpoint of a ``monovo track`` run: what an interrupted run needs to continue.

``OUT/.track-checkpoint.pkl`` is a pickle (written atomically, :mod:`monovo_cli.io.atomic`)
of a :class:`Checkpoint`: the tracking state after a frame (the caller's object), the length
of motion.csv (and of the covariance CSV) at that frame, and the fingerprint of the inputs
and options that produced it. A run that continues from it truncates the streamed CSVs to
those lengths (:func:`continue_stream`) and appends to them.

A pickle runs code when loaded: resume only from output folders you wrote yourself.
"""

from __future__ import annotations

import os
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from monovo_cli.errors import InputError, OutputError
from monovo_cli.io.atomic import DigestingStream, atomic_write_with
from monovo_cli.version import __version__

CHECKPOINT_FILE = ".track-checkpoint.pkl"
FORMAT = "monovo-checkpoint-5"  # 5: keyframe records keep sample points, the tracker the
#                                  model error it hands to the next row (3, 4: the plane
#                                  tracker keeps the ground seen, and whether frame 0's tilt
#                                  was contradicted later; 2: the recorder keeps columns, not a
#                                  row object per frame)


@dataclass(frozen=True)
class Checkpoint:
    """A run's state after frame ``next_frame - 1``.

    ``fingerprint`` a plain dict of the inputs and options (compared, never interpreted);
    ``state`` whatever the tracking run needs to continue; ``motion_bytes`` and
    ``covariance_bytes`` the lengths (bytes) of motion.csv and of the covariance CSV (None:
    none written) after that frame's row; ``seconds`` the run's wall-clock time so far.
    """

    next_frame: int
    fingerprint: dict[str, Any]
    state: Any
    motion_bytes: int
    covariance_bytes: int | None = None
    seconds: float = 0.0


def checkpoint_path(out_dir: Path) -> Path:
    return Path(out_dir) / CHECKPOINT_FILE


def write_checkpoint(out_dir: Path, checkpoint: Checkpoint) -> None:
    """Replace ``out_dir``'s checkpoint with ``checkpoint``, atomically."""
    content = {"format": FORMAT, "monovo": __version__, "checkpoint": checkpoint}
    # streamed into the file: the state is tens of MB, and a bytes object of it at every
    # checkpoint is what made a long run's peak memory grow (docs/benchmarks.md "Memory")
    atomic_write_with(checkpoint_path(out_dir),
                      lambda f: pickle.dump(content, f, protocol=pickle.HIGHEST_PROTOCOL))


def read_checkpoint(out_dir: Path) -> Checkpoint | None:
    """``out_dir``'s checkpoint, or None when it has none.

    InputError when the file cannot be read, is not a checkpoint, or was written by
    another version of monovo (whose state need not continue the same way).
    """
    path = checkpoint_path(out_dir)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the checkpoint ({exc.strerror})") from None
    start_afresh = "start the run afresh: allow overwriting or choose another output"
    try:
        content = pickle.loads(data)  # (our own file, in the run's own folder)
    except Exception as exc:  # a damaged pickle raises any kind of error
        raise InputError(f"{path}: not a readable checkpoint ({type(exc).__name__}); "
                         f"{start_afresh}") from None
    if not isinstance(content, dict) or content.get("format") != FORMAT or \
            not isinstance(content.get("checkpoint"), Checkpoint):
        raise InputError(f"{path}: not a monovo track checkpoint; {start_afresh}")
    if content.get("monovo") != __version__:
        raise InputError(f"{path}: written by monovo {content.get('monovo')}, this is "
                         f"{__version__}; {start_afresh}")
    return content["checkpoint"]


def remove_checkpoint(out_dir: Path) -> None:
    """Delete ``out_dir``'s checkpoint (the run is finished) and any temporary one."""
    checkpoint_path(out_dir).unlink(missing_ok=True)
    for tmp in Path(out_dir).glob(f".{CHECKPOINT_FILE}.*.tmp"):
        tmp.unlink(missing_ok=True)


def continue_stream(path: Path, size: int) -> DigestingStream:
    """``path`` (a CSV streamed row by row) cut to its first ``size`` bytes and opened to
    append to; its digest covers the bytes kept.

    InputError when the file holds fewer than ``size`` bytes (it is not the file the
    checkpoint was taken with).
    """
    path = Path(path)
    try:
        with open(path, "r+b") as f:
            kept = f.read(size)
            if len(kept) < size:
                raise InputError(f"{path}: holds {len(kept)} bytes, fewer than the {size} "
                                 "the checkpoint was taken with; start the run afresh: allow "
                                 "overwriting or choose another output")
            f.truncate(size)
            f.flush()
            os.fsync(f.fileno())
        return DigestingStream(open(path, "a", newline="", encoding="utf-8"), path, prefix=kept)
    except FileNotFoundError:
        raise InputError(f"{path}: missing, but the checkpoint continues it; start the run "
                         "afresh: allow overwriting or choose another output") from None
    except OSError as exc:
        raise OutputError(f"{path}: cannot continue writing it ({exc.strerror})") from None
