"""What every frame source is: :class:`FrameSource`, the interface the pipeline reads frames
through, and :class:`Frame`, one decoded frame.

A source is listed and checked when it is opened (its frame count and timestamps known, its
files found) and decoded one frame at a time, so a long sequence costs one frame of memory.
Its :meth:`~FrameSource.fingerprint` identifies the input without decoding it; run.yaml
records it and resuming a batch compares it (:meth:`~FrameSource.digest`).
"""

from __future__ import annotations

import hashlib
import json
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.digest import file_fingerprint, sha256_file

#: What the fingerprint's ``list_sha256`` covers, recorded beside it.
LIST_COVERS = "name, size and mtime of every input file (contents not hashed)"


@dataclass(frozen=True)
class Frame:
    """One decoded frame: its position in the sequence, time (s), name and grey image.

    ``path`` is the frame's file, or ``FILE[index]`` for a frame inside a video or bag (what
    messages call it: :meth:`FrameSource.frame_name`).
    """

    index: int
    timestamp: float
    path: Path
    image: np.ndarray  # (H, W) float32 grey, 0..255


class FrameSource(ABC):
    """The frames of one input, listed when opened, decoded one at a time.

    Every source has:

    - ``dir`` (Path): the input itself -- the directory of frame files, the video file, the
      bag (a ``.bag`` file or a ROS 2 bag directory);
    - ``paths`` (list of Path): the input files, one per frame when
      :attr:`one_file_per_frame`, else the container's file(s);
    - ``timestamps`` ((N,) float, seconds, increasing) and ``times_path`` (the times.txt
      they were read from, or None);
    - ``kind`` (str): what run.yaml records the input as ("images", "pds", "video", "bag").

    The frame size is that of frame 0, decoded once on first use; every frame read must
    have it. Subclasses decode a frame in :meth:`_decode`; they may hold an open container,
    released by :meth:`close` (reading again reopens it). A source is a context manager
    that closes on exit.
    """

    kind: ClassVar[str]
    #: True when each frame is a file of its own (``paths[k]`` is frame k).
    one_file_per_frame: ClassVar[bool] = False

    def __init__(self, path: Path) -> None:
        self.dir: Path = Path(path)
        self.paths: list[Path] = []
        self.timestamps: np.ndarray = np.zeros(0)
        self.times_path: Path | None = None
        self._size: tuple[int, int] | None = None  # (width, height) of frame 0

    @abstractmethod
    def _decode(self, index: int) -> np.ndarray:
        """Frame ``index`` (in range) as (H, W) float32 grey 0..255; InputError naming
        :meth:`frame_name` if it cannot be decoded."""

    # ------------------------------------------------------------------ naming and size

    def frame_name(self, index: int) -> Path:
        """What messages call frame ``index``: its file, or ``FILE[index]`` in a container."""
        if self.one_file_per_frame:
            return self.paths[index]
        return Path(f"{self.dir}[{index}]")

    @property
    def names(self) -> list[Path]:
        """:meth:`frame_name` of every frame, in order."""
        return [self.frame_name(i) for i in range(len(self))]

    def __len__(self) -> int:
        return len(self.timestamps)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({str(self.dir)!r}, {len(self)} frames)"

    def _first_size(self) -> tuple[int, int]:
        if self._size is None:
            img = self._decode(0)
            self._size = (img.shape[1], img.shape[0])
        return self._size

    @property
    def width(self) -> int:
        """Frame width (px), that of frame 0."""
        return self._first_size()[0]

    @property
    def height(self) -> int:
        """Frame height (px), that of frame 0."""
        return self._first_size()[1]

    # ------------------------------------------------------------------ reading

    def read(self, index: int) -> Frame:
        """Decode frame ``index`` (0-based); IndexError out of range, InputError if it is
        unreadable or of another size than frame 0."""
        index = int(index)
        if not 0 <= index < len(self):
            raise IndexError(f"frame {index} out of range 0..{len(self) - 1}")
        path = self.frame_name(index)
        img = self._decode(index)
        h, w = img.shape
        if self._size is None and index == 0:
            self._size = (w, h)
        W, H = self._first_size()
        if (w, h) != (W, H):
            raise InputError(f"{path}: frame is {w}x{h} but {self.frame_name(0).name} is {W}x{H} "
                             "(all frames must have one size)")
        return Frame(index=index, timestamp=float(self.timestamps[index]), path=path, image=img)

    def __iter__(self) -> Iterator[Frame]:
        """The frames in order, decoded one at a time (constant memory)."""
        for i in range(len(self)):
            yield self.read(i)

    def close(self) -> None:  # noqa: B027 (not abstract: most sources hold nothing open)
        """Release what the source holds open (a decoder, a bag); reading again reopens it."""

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ fingerprint

    def fingerprint(self) -> dict[str, Any]:
        """A plain dict identifying the input, read from the file system without decoding
        a frame: ``source`` (``dir``, absolute), ``kind``, ``count`` (frames),
        ``list_sha256`` (SHA-256 of one line per input file: its name, size in bytes and
        modification time in ns; -1 for a file that cannot be stat'ed), ``list_covers``
        (what that list holds), ``frame0_sha256`` (SHA-256 of frame 0's file when each
        frame is a file of its own -- it carries the ground model -- else None) and
        ``times`` (times.txt's ``{path, bytes, sha256}``, or None)."""
        h = hashlib.sha256()
        for p in self.paths:
            try:
                st = p.stat()
                size, mtime = st.st_size, st.st_mtime_ns
            except OSError:  # e.g. a dangling link: reading reports the frame when it gets there
                size, mtime = -1, -1
            h.update(f"{p.name}\0{size}\0{mtime}\n".encode())
        return {
            "source": str(self.dir.resolve()),
            "kind": self.kind,
            "count": len(self),
            "list_sha256": h.hexdigest(),
            "list_covers": LIST_COVERS,
            "frame0_sha256": sha256_file(self.paths[0]) if self.one_file_per_frame else None,
            "times": file_fingerprint(self.times_path),
        }

    def digest(self) -> str:
        """SHA-256 (hex) of :meth:`fingerprint` without where the input lies (``source`` and
        times.txt's ``path``): equal for the same files moved or mounted elsewhere with
        their modification times, different when a file is added, removed, renamed, resized
        or rewritten (a new mtime), frame 0 or times.txt changes."""
        content = self.fingerprint()
        del content["source"]
        if content["times"] is not None:
            content["times"] = {k: v for k, v in content["times"].items() if k != "path"}
        return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()
