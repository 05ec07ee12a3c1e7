"""Frames decoded on a thread of their own while the tracker estimates the one before.

Decoding a frame (PNG, JPEG, a video's or a bag's next image) costs a tenth of a frame's
time and more at large sizes, and OpenCV's decoders release the GIL: one reader thread that
decodes the frames in order, a few ahead, hides it behind the estimation. Only that thread
touches the frame source while it runs (a video or a bag is read in order), and what it
hands over is the same image the tracker would have read itself, so the outputs do not
change with it.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator

from monovo_cli.errors import InputError
from monovo_cli.io.sources import Frame, FrameSource

AHEAD = 2  # frames decoded ahead of the tracker


def read_frames(frames: FrameSource, start: int, threads: int = 1
                ) -> Iterator[tuple[int, Frame | None, InputError | None]]:
    """``(index, frame, None)`` for frames ``start..`` of ``frames`` in order, or ``(index,
    None, error)`` for one that cannot be read. With ``threads`` of 2 or more a reader thread
    decodes up to AHEAD frames ahead; any other exception of the reader is raised here, at
    its frame. Closing the iterator stops the reader."""
    if threads <= 1:
        for index in range(start, len(frames)):
            try:
                yield index, frames.read(index), None
            except InputError as exc:
                yield index, None, exc
        return
    box: queue.Queue = queue.Queue(maxsize=AHEAD)
    stop = threading.Event()

    def put(item) -> None:
        while not stop.is_set():
            try:
                box.put(item, timeout=0.05)
                return
            except queue.Full:
                continue

    def work() -> None:
        for index in range(start, len(frames)):
            if stop.is_set():
                return
            try:
                put((index, frames.read(index), None))
            except InputError as exc:
                put((index, None, exc))
            except BaseException as exc:  # raised in the tracker's thread, at this frame
                put((index, None, exc))
                return

    reader = threading.Thread(target=work, name="monovo-frame-reader", daemon=True)
    reader.start()
    try:
        for _ in range(start, len(frames)):
            index, frame, exc = box.get()
            if exc is not None and not isinstance(exc, InputError):
                raise exc
            yield index, frame, exc
    finally:
        stop.set()
        reader.join()
