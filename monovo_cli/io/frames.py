"""Input sequences (docs/guide.md "File formats"): where file paths stop and grey images start.

A sequence is a directory of image files (``IMAGE_EXTENSIONS``, case-insensitive) in
natural-sort order, plus an optional ``times.txt`` (one timestamp in seconds per line,
one line per frame) in it or, for a ``frames/`` directory, beside it. Other files, and
hidden files such as macOS ``._frame.png`` companions, are ignored. Frames are decoded one
at a time into float32 grey images on a 0..255 scale, whatever their depth (8/16 bit,
float), colour layout (grey, BGR, BGRA, palette) or format. Every problem is an
:class:`~monovo_cli.errors.InputError` with one line naming the file.

A directory without images may hold PDS3/PDS4 products instead (:mod:`monovo_cli.io.pds`:
``.IMG`` with attached or detached ``.LBL`` label, PDS4 ``.xml`` labels; 12-bit samples
divided by 16), timed by their labels unless ``times.txt`` is there. A sequence may also
be one container (:mod:`monovo_cli.io.containers`): a video file, or a ROS 1/ROS 2 bag
whose image ``topic`` is named; frame k of a container is called ``FILE[k]`` in messages.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.containers import (
    VIDEO_EXTENSIONS,
    BagSource,
    VideoSource,
    bag_root,
    is_bag,
    list_containers,
)
from monovo_cli.io.grey import decode_gray, grey_from_pixels, read_gray
from monovo_cli.io.pds import PDS_EXTENSIONS, label_times, list_products

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm", ".bmp")
TIMES_FILE = "times.txt"
FRAMES_SUBDIR = "frames"
INIT_FILE = "init.yaml"

_DIGITS = re.compile(r"([0-9]+)")


@dataclass(frozen=True)
class Frame:
    """One decoded frame: its position in the sequence, time (s), file and grey image."""

    index: int
    timestamp: float
    path: Path
    image: np.ndarray  # (H, W) float32 grey, 0..255


def natural_key(name: str) -> tuple:
    """Sort key putting ``frame2.png`` before ``frame10.png`` (case-insensitive, then exact)."""
    parts = _DIGITS.split(name)
    # split() alternates text, number, text, ...: positions always hold the same type.
    key = tuple(int(p) if i % 2 else p.casefold() for i, p in enumerate(parts))
    return (key, name)


def _is_image_name(name: str) -> bool:
    return not name.startswith(".") and name.lower().endswith(IMAGE_EXTENSIONS)


def _list_images(directory: Path) -> list[Path]:
    try:
        entries = list(directory.iterdir())
    except OSError as exc:
        raise InputError(f"{directory}: cannot list the directory ({exc.strerror or exc})") from None
    # A dangling symlink named like a frame is a frame that cannot be read, not a
    # non-frame: skipping it silently would shift every later frame's timestamp.
    files = [p for p in entries if _is_image_name(p.name)
             and (p.is_file() or (p.is_symlink() and not p.exists()))]
    return sorted(files, key=lambda p: natural_key(p.name))


def resolve_sequence(path: Path) -> Path:
    """The source of the frames: ``path`` itself (a directory of frames or PDS products, a
    video file, a ROS bag), ``path/frames`` when ``path`` is a sequence folder as written by
    ``monovo synth`` (no images of its own), or the one video or bag in a folder that holds
    no frames of its own."""
    path = Path(path)
    if not path.exists():
        what = "file" if path.suffix.lower() in VIDEO_EXTENSIONS + (".bag",) else "directory"
        raise InputError(f"{path}: no such {what} (expected a directory of frames, a video, "
                         f"a ROS bag, or a folder holding {FRAMES_SUBDIR}/)")
    if path.is_file():
        if path.name.lower().endswith(IMAGE_EXTENSIONS + PDS_EXTENSIONS):
            raise InputError(f"{path}: is a file, expected a directory of frames "
                             f"(or a folder holding {FRAMES_SUBDIR}/, a video or a ROS bag)")
        return bag_root(path)  # a video or a bag (given by one of a ROS 2 bag's files)
    if is_bag(path) or _list_images(path):
        return path
    sub = path / FRAMES_SUBDIR
    if sub.is_dir():
        return sub
    if not list_products(path):
        containers = list_containers(path)
        if len(containers) == 1:
            return containers[0]
    return path


def find_init_yaml(seq: Path) -> Path | None:
    """``init.yaml`` in ``seq``, else in its parent when ``seq`` is a ``frames/`` directory,
    a video or a ROS bag."""
    seq = Path(seq)
    candidates = [seq / INIT_FILE]
    if seq.name == FRAMES_SUBDIR or seq.is_file() or is_bag(seq):
        candidates.append(seq.parent / INIT_FILE)
    for c in candidates:
        if c.is_file():
            return c
    return None


def _read_times(path: Path, n_frames: int) -> np.ndarray:
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


class FrameSequence:
    """The frames of a sequence, listed and checked eagerly, decoded one at a time.

    ``seq_dir`` may be the frames directory, a folder holding ``frames/``, a directory of PDS
    products, a video or a ROS bag (:func:`resolve_sequence`); ``topic`` names a bag's image
    topic (other sources ignore it). ``kind`` says which: "images", "pds", "video" or "bag".
    ``paths`` are the input files: one per frame for a directory, the container's files
    otherwise. The frame size is that of the first frame, read once on first use; every
    frame read must have it.
    """

    def __init__(self, seq_dir: Path, *, topic: str | None = None) -> None:
        self.dir: Path = resolve_sequence(Path(seq_dir))
        self.times_path: Path | None = None
        self._container: VideoSource | BagSource | None = None
        self._size: tuple[int, int] | None = None  # (width, height)
        if self.dir.is_file() or is_bag(self.dir):
            if is_bag(self.dir):
                self.kind = "bag"
                self._container = BagSource(self.dir, topic)
                self.paths: list[Path] = ([self.dir] if self.dir.is_file() else
                                          sorted(p for p in self.dir.iterdir() if p.is_file()))
            else:
                self.kind = "video"
                self._container = VideoSource(self.dir)
                self.paths = [self.dir]
            self.timestamps: np.ndarray = np.asarray(self._container.timestamps, dtype=float)
            return
        self.kind = "images"
        self.paths = _list_images(self.dir)
        if not self.paths:
            self.kind = "pds"
            self.paths = sorted(list_products(self.dir), key=lambda p: natural_key(p.name))
        if not self.paths:
            raise InputError(f"{self.dir}: no image files (accepted: "
                             f"{' '.join(IMAGE_EXTENSIONS)}, any case; or PDS products "
                             ".IMG .LBL .xml; or a video or a ROS bag)")
        self.times_path = None
        from_labels = None
        times = self._times()
        if times is not None:
            self.times_path, self.timestamps = times
        elif self.kind == "pds":
            from_labels = label_times(self.paths, TIMES_FILE)
        if self.times_path is None:
            self.timestamps = (from_labels if from_labels is not None
                               else np.arange(len(self.paths), dtype=float))

    def _times(self) -> tuple[Path, np.ndarray] | None:
        """``(times.txt, its timestamps)`` of a directory of frames: the one in it or, for a
        ``frames/`` directory, the one beside it (in the sequence folder); both may exist
        only if they agree. None without one."""
        candidates = [self.dir / TIMES_FILE]
        if self.dir.name == FRAMES_SUBDIR:
            candidates.append(self.dir.parent / TIMES_FILE)
        found = [(p, _read_times(p, len(self.paths))) for p in candidates if p.is_file()]
        if len(found) == 2 and not np.array_equal(found[0][1], found[1][1]):
            (a, ta), (b, tb) = found
            k = int(np.argmax(ta != tb))
            raise InputError(f"{a} and {b} differ (frame {k}: {float(ta[k])!r} s and "
                             f"{float(tb[k])!r} s); "
                             "keep one times.txt")
        return found[0] if found else None

    def __len__(self) -> int:
        return len(self.timestamps)

    def __repr__(self) -> str:
        return f"FrameSequence({str(self.dir)!r}, {len(self)} frames)"

    def frame_name(self, index: int) -> Path:
        """The file of frame ``index``, or ``FILE[index]`` for a frame of a container."""
        if self._container is None:
            return self.paths[index]
        return Path(f"{self.dir}[{index}]")

    def _decode(self, index: int) -> np.ndarray:
        path = self.frame_name(index)
        if self.kind == "images":
            return read_gray(path)
        if self.kind == "pds":
            from monovo_cli.io.pds import read_product

            return read_product(path).image
        raw = self._container.read(index)
        if isinstance(raw, (bytes, bytearray)):
            return decode_gray(raw, path)
        return grey_from_pixels(raw, path)

    def _first_size(self) -> tuple[int, int]:
        if self._size is None:
            img = self._decode(0)
            self._size = (img.shape[1], img.shape[0])
        return self._size

    @property
    def width(self) -> int:
        return self._first_size()[0]

    @property
    def height(self) -> int:
        return self._first_size()[1]

    def read(self, index: int) -> Frame:
        """Decode frame ``index`` (0-based); InputError if it is unreadable or of another size."""
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

    def close(self) -> None:
        """Release a container (the ffmpeg process of a video, the open bag); reading again
        reopens it."""
        if isinstance(self._container, VideoSource):
            self._container.close()
