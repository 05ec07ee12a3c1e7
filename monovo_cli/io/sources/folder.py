"""Sources whose frames are files of one directory: their order and their times.txt.

The frames are in natural-sort order of their names (:func:`natural_key`). ``times.txt``
(one timestamp in seconds per line, one line per frame, increasing; blank lines and ``#``
comments skipped) gives their times; it may sit in the directory or, for a ``frames/``
directory, beside it in the sequence folder -- both only if they agree. Without one, each
kind of folder says (:meth:`FolderSource._default_times`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.sources.base import FrameSource

TIMES_FILE = "times.txt"
FRAMES_SUBDIR = "frames"

_DIGITS = re.compile(r"([0-9]+)")


def natural_key(name: str) -> tuple:
    """Sort key putting ``frame2.png`` before ``frame10.png`` (case-insensitive, then exact)."""
    parts = _DIGITS.split(name)
    # split() alternates text, number, text, ...: positions always hold the same type.
    key = tuple(int(p) if i % 2 else p.casefold() for i, p in enumerate(parts))
    return (key, name)


def read_times(path: Path, n_frames: int) -> np.ndarray:
    """The (n_frames,) timestamps (s) of a times.txt; InputError naming the file and line
    for text that is not one finite, increasing number per line, or another count."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        raise InputError(f"{path}: cannot read timestamps ({reason})") from None
    values: list[float] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        shown = s if len(s) <= 40 else s[:37] + "..."
        try:
            t = float(s)
        except ValueError:
            raise InputError(f"{path}: line {lineno}: expected one timestamp in seconds, "
                             f"got {shown!r}") from None
        if not math.isfinite(t):
            raise InputError(f"{path}: line {lineno}: timestamp must be finite, got {shown!r}")
        if values and t <= values[-1]:
            raise InputError(f"{path}: line {lineno}: timestamps must increase, "
                             f"{t!r} follows {values[-1]!r}")
        values.append(t)
    if len(values) != n_frames:
        raise InputError(f"{path}: {len(values)} timestamps for {n_frames} frames "
                         "(need one line per frame)")
    return np.array(values, dtype=float)


def folder_times(directory: Path, n_frames: int) -> tuple[Path, np.ndarray] | None:
    """``(times.txt, its timestamps)`` for a directory of frames: the one in it or, for a
    ``frames/`` directory, the one beside it; both may exist only if they agree. None
    without one."""
    candidates = [directory / TIMES_FILE]
    if directory.name == FRAMES_SUBDIR:
        candidates.append(directory.parent / TIMES_FILE)
    found = [(p, read_times(p, n_frames)) for p in candidates if p.is_file()]
    if len(found) == 2 and not np.array_equal(found[0][1], found[1][1]):
        (a, ta), (b, tb) = found
        k = int(np.argmax(ta != tb))
        raise InputError(f"{a} and {b} differ (frame {k}: {float(ta[k])!r} s and "
                         f"{float(tb[k])!r} s); "
                         "keep one times.txt")
    return found[0] if found else None


class FolderSource(FrameSource):
    """Frames that are the files ``paths`` of ``directory`` (sorted here by
    :func:`natural_key` of their names), timed by times.txt or else by
    :meth:`_default_times`. ``paths`` must not be empty."""

    one_file_per_frame = True

    def __init__(self, directory: Path, paths: Sequence[Path]) -> None:
        super().__init__(directory)
        self.paths = sorted(paths, key=lambda p: natural_key(p.name))
        if not self.paths:
            raise ValueError(f"{directory}: a folder source needs at least one frame file")
        found = folder_times(self.dir, len(self.paths))
        if found is not None:
            self.times_path, self.timestamps = found
        else:
            self.timestamps = self._default_times()

    def _default_times(self) -> np.ndarray:
        """The timestamps without a times.txt: frame k at k s."""
        return np.arange(len(self.paths), dtype=float)
