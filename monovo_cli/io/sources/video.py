"""A video file as frames, decoded by ffmpeg.

Any file ffmpeg reads, decoded by the ffmpeg that ``imageio-ffmpeg`` ships (the backend of
imageio's ffmpeg plugin). The first video stream is used, every frame as it is stored
(``-fps_mode passthrough``: no frame is duplicated or dropped to make a constant rate).
Timestamps are the frames' presentation times (``pts_time``), read once, with the frame
count, by a first decoding pass; without usable ones frame k is at k / rate (or k) s.
Streams of 8 bits decode to 8-bit grey (ffmpeg's luma, i.e. the Y plane of YUV video),
deeper streams to 16-bit grey, then to monovo's 0..255 scale (:mod:`monovo_cli.io.grey`).
Frame k is called ``FILE[k]`` in messages. Random access works, at the cost of decoding
from the start again when a frame before the last one read is asked for.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.grey import grey_from_pixels
from monovo_cli.io.sources.base import FrameSource

#: File extensions taken for videos when looking for sequences (``monovo batch``); any other
#: file given to ``monovo track`` is tried with ffmpeg as well.
VIDEO_EXTENSIONS = (".mp4", ".m4v", ".mkv", ".avi", ".mov", ".webm", ".mpg", ".mpeg", ".ts",
                    ".mts", ".wmv", ".flv", ".ogv", ".nut", ".y4m")
_PTS = re.compile(r"\bn:\s*(\d+)\s+pts:\s*(-?\d+)\s+pts_time:\s*(-?[0-9.eE+-]+|nan|NOPTS)")
_DEEP_FORMAT = re.compile(r"(\d+)(le|be)\b")


def is_video_name(path: Path) -> bool:
    """A file name taken for a video: not hidden, with one of :data:`VIDEO_EXTENSIONS`."""
    return not path.name.startswith(".") and path.suffix.lower() in VIDEO_EXTENSIONS


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1][:160] if lines else "no message"


class VideoFile(FrameSource):
    """The frames of the video file ``path`` (module docstring); ``paths`` is ``[path]``,
    ``bits`` 8 or 16 the depth decoded. Raises InputError if ffmpeg cannot decode the file
    or it holds no video frame."""

    kind = "video"

    def __init__(self, path: Path) -> None:
        import imageio_ffmpeg

        super().__init__(path)
        self.paths = [self.dir]
        self._exe = imageio_ffmpeg.get_ffmpeg_exe()
        self.timestamps, fmt, self._probed = self._probe()
        self.bits = 16 if any(int(m.group(1)) > 8 for m in _DEEP_FORMAT.finditer(fmt)) else 8
        self._gen = None
        self._next = 0

    def _probe(self) -> tuple[np.ndarray, str, tuple[int, int]]:
        """(timestamps (N,) s, the stream's pixel format, (width, height)) by one decoding pass."""
        cmd = [self._exe, "-hide_banner", "-nostdin", "-i", str(self.dir), "-map", "0:v:0",
               "-vf", "showinfo", "-fps_mode", "passthrough", "-f", "null", "-"]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, errors="replace")
        except OSError as exc:
            raise InputError(f"{self.dir}: cannot run ffmpeg ({exc.strerror or exc})") from None
        if proc.returncode != 0:
            raise InputError(f"{self.dir}: not a video ffmpeg can read "
                             f"({_last_line(proc.stderr)})")
        times = []
        for m in _PTS.finditer(proc.stderr):
            value = m.group(3)
            times.append(float("nan") if value in ("nan", "NOPTS") else float(value))
        if not times:
            raise InputError(f"{self.dir}: the video has no frames")
        stream = re.search(r"Stream #0:\d+[^:]*: Video: ([^\n]*)", proc.stderr)
        desc = stream.group(1) if stream else ""
        size = re.search(r"\b(\d{1,6})x(\d{1,6})\b", desc)
        if size is None:
            raise InputError(f"{self.dir}: ffmpeg reports no frame size for the video stream")
        t = np.array(times, dtype=float)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            # No usable presentation times: frame k at k / rate, else at k.
            rate = re.search(r"([0-9.]+) fps", desc)
            fps = float(rate.group(1)) if rate else 0.0
            t = np.arange(len(times), dtype=float) / (fps if fps > 0 else 1.0)
        fmt = desc.split(",")[1] if "," in desc else ""
        return t, fmt, (int(size.group(1)), int(size.group(2)))

    def _open(self) -> None:
        import imageio_ffmpeg

        self.close()
        pix_fmt, bpp = ("gray16le", 16) if self.bits == 16 else ("gray", 8)
        self._gen = imageio_ffmpeg.read_frames(
            str(self.dir), pix_fmt=pix_fmt, bits_per_pixel=bpp,
            output_params=["-map", "0:v:0", "-fps_mode", "passthrough"])
        meta = next(self._gen)
        w, h = meta["size"]
        if (w, h) != self._probed:
            self.close()
            raise InputError(f"{self.dir}: ffmpeg decodes {w}x{h} frames but reported "
                             f"{self._probed[0]}x{self._probed[1]}")
        self._next = 0

    def _raw(self, index: int) -> np.ndarray:
        """Frame ``index`` as (H, W) uint8 (8-bit streams) or uint16 grey."""
        if self._gen is None or index < self._next:
            self._open()
        dtype = np.uint16 if self.bits == 16 else np.uint8
        try:
            while True:
                raw = next(self._gen)
                self._next += 1
                if self._next - 1 == index:
                    break
        except (StopIteration, RuntimeError, OSError) as exc:
            self.close()
            raise InputError(f"{self.dir}: frame {index} cannot be decoded "
                             f"({type(exc).__name__}: {exc or 'the video ended early'})") from None
        w, h = self._probed
        img = np.frombuffer(raw, dtype=dtype).reshape(h, w)
        if self._next == len(self):
            self.close()
        return img

    def _decode(self, index: int) -> np.ndarray:
        return grey_from_pixels(self._raw(index), self.frame_name(index))

    def close(self) -> None:
        """Stop the decoding ffmpeg process, if one runs."""
        if self._gen is not None:
            gen, self._gen = self._gen, None
            gen.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass
