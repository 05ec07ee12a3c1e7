"""Image and video writers: H.264 MP4, GIF, a directory of PNGs, one PNG (atomic).

The output kind follows the path: ``.mp4`` (H.264, yuv420p, ``+faststart`` so browsers
play it while it loads), ``.gif`` (a palette per frame), or a directory of PNGs (a path
without an extension, or one ending in ``/``). Videos go through imageio's ffmpeg backend
(``imageio-ffmpeg``, whose wheel carries its own ffmpeg binary, so it works offline).

Every sink streams: a frame is encoded when it is written and never kept. Results are
written under a temporary name beside the target and renamed into place by
:meth:`FrameSink.close`, so a failed or interrupted run leaves no half-written video under
the final name; :meth:`FrameSink.abort` removes the partial output.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np

from monovo_cli.errors import InputError, OutputError
from monovo_cli.io.atomic import atomic_write_bytes, created_mode
from monovo_cli.io.report_html import png_bytes

VIDEO_EXTENSIONS = (".mp4", ".gif")
# Browser-safe H.264: 4:2:0 chroma, moov atom first; crf 20 is visually lossless here.
_MP4_PARAMS = ["-crf", "20", "-preset", "medium", "-movflags", "+faststart"]
# One palette per frame: palettegen/paletteuse per frame keeps ffmpeg streaming too.
_GIF_PARAMS = ["-vf", "split[a][b];[a]palettegen=stats_mode=single[p];[b][p]paletteuse=new=1",
               "-loop", "0"]


def output_kind(out: str | Path) -> str:
    """``"mp4"``, ``"gif"`` or ``"png"`` (a directory of PNGs) for an output path.

    A path ending in a separator or without an extension is a directory; any other
    extension raises InputError.
    """
    text = str(out)
    path = Path(text)
    if text.endswith(("/", os.sep)) or path.is_dir() or path.suffix == "":
        return "png"
    suffix = path.suffix.lower()
    if suffix in VIDEO_EXTENSIONS:
        return suffix[1:]
    raise InputError(f"{out}: unknown output type {path.suffix!r}; expected .mp4, .gif, "
                     "or a directory (no extension) for PNG frames")


def pad_to_even(image: np.ndarray) -> np.ndarray:
    """``image`` (H, W, 3) with a black row / column added where H or W is odd (H.264 4:2:0)."""
    h, w = image.shape[:2]
    ph, pw = h % 2, w % 2
    if not (ph or pw):
        return image
    return cv2.copyMakeBorder(image, 0, ph, 0, pw, cv2.BORDER_CONSTANT, value=(0, 0, 0))


def _check_target(path: Path, overwrite: bool) -> None:
    if path.exists() and not overwrite:
        if not (path.is_dir() and not any(path.iterdir())):
            raise OutputError(f"{path}: already exists; allow overwriting or choose another output")
    parent = path.parent
    if not parent.is_dir():
        raise OutputError(f"{parent}: no such directory")
    if not os.access(parent, os.W_OK):
        raise OutputError(f"{parent}: not writable")


class FrameSink:
    """Writes BGR uint8 frames (H, W, 3) of one size to ``path`` as they come.

    Use :func:`open_sink`; call :meth:`write` per frame, then :meth:`close` (or
    :meth:`abort` on failure). ``frames`` counts the frames written.
    """

    def __init__(self, path: Path, kind: str, fps: float, overwrite: bool) -> None:
        self.path, self.kind, self.fps, self.overwrite = Path(path), kind, float(fps), overwrite
        self.frames = 0
        self._size: tuple[int, int] | None = None
        self._gen = None
        name = self.path.name
        if kind == "png":
            self._tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".partial",
                                              dir=self.path.parent))
        else:
            fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=f".partial.{kind}",
                                       dir=self.path.parent)
            os.close(fd)
            self._tmp = Path(tmp)

    def _start_video(self, w: int, h: int) -> None:
        import imageio_ffmpeg

        common = dict(fps=self.fps, quality=None, macro_block_size=1, pix_fmt_in="bgr24",
                      ffmpeg_log_level="error")
        if self.kind == "mp4":
            self._gen = imageio_ffmpeg.write_frames(str(self._tmp), (w, h), codec="libx264",
                                                    pix_fmt_out="yuv420p",
                                                    output_params=list(_MP4_PARAMS), **common)
        else:
            self._gen = imageio_ffmpeg.write_frames(str(self._tmp), (w, h), codec="gif",
                                                    pix_fmt_out="pal8",
                                                    output_params=list(_GIF_PARAMS), **common)
        self._gen.send(None)  # starts the ffmpeg process

    def write(self, frame_bgr: np.ndarray) -> None:
        """Append one frame, (H, W, 3) uint8 BGR; H.264 frames are padded to even sizes."""
        if frame_bgr.ndim != 3 or frame_bgr.shape[2] != 3 or frame_bgr.dtype != np.uint8:
            raise ValueError(f"expected a (H, W, 3) uint8 frame, got {frame_bgr.shape} "
                             f"{frame_bgr.dtype}")
        if self.kind == "mp4":
            frame_bgr = pad_to_even(frame_bgr)
        h, w = frame_bgr.shape[:2]
        if self._size is None:
            self._size = (w, h)
            if self.kind != "png":
                self._start_video(w, h)
        elif self._size != (w, h):
            raise ValueError(f"frame {self.frames} is {w}x{h}, the first was "
                             f"{self._size[0]}x{self._size[1]}")
        if self.kind == "png":
            target = self._tmp / f"frame_{self.frames:06d}.png"
            if not cv2.imwrite(str(target), frame_bgr):
                raise OutputError(f"{target}: cannot write PNG")
        else:
            try:
                self._gen.send(np.ascontiguousarray(frame_bgr))
            except (OSError, RuntimeError) as exc:
                raise OutputError(f"{self.path}: video encoder failed ({exc})") from None
        self.frames += 1

    def close(self) -> None:
        """Finish the file and move it to its final name."""
        if self._gen is not None:
            try:
                self._gen.close()
            except (OSError, RuntimeError) as exc:
                self.abort()
                raise OutputError(f"{self.path}: video encoder failed ({exc})") from None
            self._gen = None
        if self.path.exists() and self.overwrite:
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
            else:
                self.path.unlink()
        elif self.path.is_dir():  # an empty directory given as the target
            self.path.rmdir()
        os.chmod(self._tmp, created_mode(directory=self.kind == "png"))
        os.replace(self._tmp, self.path)

    def abort(self) -> None:
        """Stop the encoder and remove the partial output."""
        if self._gen is not None:
            try:
                self._gen.close()
            except (OSError, RuntimeError):
                pass
            self._gen = None
        if self._tmp.is_dir():
            shutil.rmtree(self._tmp, ignore_errors=True)
        else:
            self._tmp.unlink(missing_ok=True)


def open_sink(out: str | Path, *, fps: float = 10.0, overwrite: bool = False) -> FrameSink:
    """A :class:`FrameSink` for ``out`` (kind by :func:`output_kind`); checks it can be written.

    Raises OutputError when ``out`` exists (and is not an empty directory) without
    ``overwrite``, or its directory is missing or read-only.
    """
    kind = output_kind(out)
    path = Path(str(out).rstrip("/" + os.sep) or ".")
    _check_target(path, overwrite)
    if not fps > 0:
        raise InputError(f"fps must be > 0, got {fps}")
    try:
        return FrameSink(path, kind, fps, overwrite)
    except OSError as exc:
        raise OutputError(f"{path.parent}: cannot write here ({exc.strerror})") from None


def write_png_atomic(path: Path, image: np.ndarray) -> bytes:
    """Write ``image`` (H, W[, 3]) uint8 as a PNG through a temporary file + rename; returns
    the PNG's bytes."""
    path = Path(path)
    try:
        data = png_bytes(image)
    except OutputError:
        raise OutputError(f"{path}: cannot encode PNG") from None
    atomic_write_bytes(path, data)
    return data
