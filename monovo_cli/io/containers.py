"""Sequences inside one container: a video file (ffmpeg) or a ROS 1 / ROS 2 bag (rosbags).

Both give frames one at a time, in order, with their timestamps (seconds) from the container:

- **video** -- any file ffmpeg reads, decoded by the ffmpeg that ``imageio-ffmpeg`` ships (the
  backend of imageio's ffmpeg plugin). The first video stream is used, every frame as it is
  stored (``-fps_mode passthrough``: no frame is duplicated or dropped to make a constant
  rate). Timestamps are the frames' presentation times (``pts_time``), read once, with the
  frame count, by a first decoding pass. Streams of 8 bits decode to 8-bit grey (ffmpeg's
  luma, i.e. the Y plane of YUV video), deeper streams to 16-bit grey.
- **ROS bag** -- a ROS 1 ``.bag`` file or a ROS 2 bag directory (``metadata.yaml`` with
  ``.db3``/``.mcap`` files), read with the pure-Python ``rosbags`` (an optional extra,
  ``pip install monovo[ros]``). The messages of one ``sensor_msgs/Image`` or
  ``sensor_msgs/CompressedImage`` topic are the frames (``topic``; may be omitted when the bag
  holds exactly one image topic). Timestamps are the messages' ``header.stamp`` when every
  one is set and they increase, else the times the messages were recorded.

A source's :meth:`read` returns what :mod:`monovo_cli.io.frames` turns into grey: an array in
OpenCV's layout (H, W) or (H, W, 3/4 BGR[A]), uint8, uint16 or float32, or the encoded bytes
of a compressed image. Random access works, at the cost of decoding from the start again
(video) or seeking (bag) when a frame before the last one read is asked for.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError

#: File extensions taken for videos when looking for sequences (``monovo batch``); any other
#: file given to ``monovo track`` is tried with ffmpeg as well.
VIDEO_EXTENSIONS = (".mp4", ".m4v", ".mkv", ".avi", ".mov", ".webm", ".mpg", ".mpeg", ".ts",
                    ".mts", ".wmv", ".flv", ".ogv", ".nut", ".y4m")
ROS1_EXTENSION = ".bag"
ROS2_METADATA = "metadata.yaml"
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
_PTS = re.compile(r"\bn:\s*(\d+)\s+pts:\s*(-?\d+)\s+pts_time:\s*(-?[0-9.eE+-]+|nan|NOPTS)")
_DEEP_FORMAT = re.compile(r"(\d+)(le|be)\b")
_ENCODINGS_8 = {"mono8": 1, "8uc1": 1, "bgr8": 3, "rgb8": 3, "8uc3": 3, "bgra8": 4, "rgba8": 4,
                "8uc4": 4}
_ENCODINGS_16 = {"mono16": 1, "16uc1": 1, "bgr16": 3, "rgb16": 3, "bgra16": 4, "rgba16": 4}


def _first_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1][:160] if lines else "no message"


def is_video_name(path: Path) -> bool:
    return not path.name.startswith(".") and path.suffix.lower() in VIDEO_EXTENSIONS


def is_bag(path: Path) -> bool:
    """A ROS 1 bag file (``.bag``) or a ROS 2 bag directory (holding ``metadata.yaml``)."""
    path = Path(path)
    if path.is_dir():
        return (path / ROS2_METADATA).is_file()
    return path.suffix.lower() == ROS1_EXTENSION


def is_container(path: Path) -> bool:
    """A video file (by its extension, :data:`VIDEO_EXTENSIONS`) or a ROS bag."""
    path = Path(path)
    if path.name.startswith("."):
        return False
    return (path.is_file() and (is_video_name(path) or is_bag(path))) or (path.is_dir() and is_bag(path))


def list_containers(directory: Path) -> list[Path]:
    """The videos and ROS bags directly in ``directory`` (unsorted; none if it is unreadable)."""
    try:
        return [p for p in Path(directory).iterdir() if is_container(p)]
    except OSError:
        return []


def bag_root(path: Path) -> Path:
    """The bag a path names: the ``.bag`` file, or the ROS 2 bag directory (also when given
    its ``metadata.yaml`` or one of its storage files)."""
    path = Path(path)
    if path.is_file() and path.suffix.lower() != ROS1_EXTENSION and (path.parent / ROS2_METADATA).is_file():
        return path.parent
    return path


# ----------------------------------------------------------------------------- video


class VideoSource:
    """The frames of a video file (module docstring). ``timestamps`` (N,) s, ``width``,
    ``height`` px, ``bits`` 8 or 16. Raises InputError if ffmpeg cannot decode the file or
    it holds no video frame."""

    def __init__(self, path: Path) -> None:
        import imageio_ffmpeg

        self.path = Path(path)
        self._exe = imageio_ffmpeg.get_ffmpeg_exe()
        self.timestamps, fmt, (self.width, self.height) = self._probe()
        self.bits = 16 if any(int(m.group(1)) > 8 for m in _DEEP_FORMAT.finditer(fmt)) else 8
        self._gen = None
        self._next = 0

    def _probe(self) -> tuple[np.ndarray, str, tuple[int, int]]:
        cmd = [self._exe, "-hide_banner", "-nostdin", "-i", str(self.path), "-map", "0:v:0",
               "-vf", "showinfo", "-fps_mode", "passthrough", "-f", "null", "-"]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, errors="replace")
        except OSError as exc:
            raise InputError(f"{self.path}: cannot run ffmpeg ({exc.strerror or exc})") from None
        if proc.returncode != 0:
            raise InputError(f"{self.path}: not a video ffmpeg can read "
                             f"({_first_line(proc.stderr)})")
        times = []
        for m in _PTS.finditer(proc.stderr):
            value = m.group(3)
            times.append(float("nan") if value in ("nan", "NOPTS") else float(value))
        if not times:
            raise InputError(f"{self.path}: the video has no frames")
        stream = re.search(r"Stream #0:\d+[^:]*: Video: ([^\n]*)", proc.stderr)
        desc = stream.group(1) if stream else ""
        size = re.search(r"\b(\d{1,6})x(\d{1,6})\b", desc)
        if size is None:
            raise InputError(f"{self.path}: ffmpeg reports no frame size for the video stream")
        t = np.array(times, dtype=float)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            # No usable presentation times: frame k at k / rate, else at k.
            rate = re.search(r"([0-9.]+) fps", desc)
            fps = float(rate.group(1)) if rate else 0.0
            t = np.arange(len(times), dtype=float) / (fps if fps > 0 else 1.0)
        fmt = desc.split(",")[1] if "," in desc else ""
        return t, fmt, (int(size.group(1)), int(size.group(2)))

    def __len__(self) -> int:
        return len(self.timestamps)

    def _open(self) -> None:
        import imageio_ffmpeg

        self.close()
        pix_fmt, bpp = ("gray16le", 16) if self.bits == 16 else ("gray", 8)
        self._gen = imageio_ffmpeg.read_frames(
            str(self.path), pix_fmt=pix_fmt, bits_per_pixel=bpp,
            output_params=["-map", "0:v:0", "-fps_mode", "passthrough"])
        meta = next(self._gen)
        w, h = meta["size"]
        if (w, h) != (self.width, self.height):
            self.close()
            raise InputError(f"{self.path}: ffmpeg decodes {w}x{h} frames but reported "
                             f"{self.width}x{self.height}")
        self._next = 0

    def read(self, index: int) -> np.ndarray:
        """Frame ``index`` as (H, W) uint8 (8-bit streams) or uint16 grey."""
        index = int(index)
        if not 0 <= index < len(self):
            raise IndexError(f"frame {index} out of range 0..{len(self) - 1}")
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
            raise InputError(f"{self.path}: frame {index} cannot be decoded "
                             f"({type(exc).__name__}: {exc or 'the video ended early'})") from None
        img = np.frombuffer(raw, dtype=dtype).reshape(self.height, self.width)
        if self._next == len(self):
            self.close()
        return img

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


# ----------------------------------------------------------------------------- ROS bags


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError("reading ROS bags needs the 'rosbags' package: pip install "
                         "'monovo[ros]' (or pip install rosbags)") from None
    return AnyReader, get_typestore(Stores.LATEST)


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:120]}" if text else type(exc).__name__


class BagSource:
    """The image messages of one topic of a ROS 1/ROS 2 bag (module docstring).

    ``topic`` the topic read; ``timestamps`` (N,) s; ``stamp_source`` "header" or "bag".
    Raises InputError if the bag cannot be read, the topic is missing or not an image topic,
    or the bag holds several image topics and none was named.
    """

    def __init__(self, path: Path, topic: str | None = None) -> None:
        self.path = bag_root(Path(path))
        reader_cls, self._typestore = _rosbags()
        try:
            self._reader = reader_cls([self.path], default_typestore=self._typestore)
            self._reader.open()
        except Exception as exc:  # rosbags raises its own error types per storage
            raise InputError(f"{self.path}: cannot read the ROS bag ({_reason(exc)})") from None
        try:
            self.topic, self._connections = self._pick(topic)
            self._bag_ns, self.timestamps, self.stamp_source = self._index()
        except BaseException:
            self.close()
            raise
        self._gen = None
        self._next = 0

    def image_topics(self) -> dict[str, str]:
        """``{topic: message type}`` of the bag's image topics."""
        return {c.topic: c.msgtype for c in self._reader.connections if c.msgtype in IMAGE_TYPES}

    def _pick(self, topic: str | None):
        images = self.image_topics()
        if topic is None:
            if len(images) != 1:
                listed = ", ".join(sorted(images)) or "none"
                raise InputError(f"{self.path}: {len(images)} image topics ({listed}); name one "
                                 "with --topic")
            topic = next(iter(images))
        conns = [c for c in self._reader.connections if c.topic == topic]
        if not conns:
            listed = ", ".join(sorted(images)) or "none"
            raise InputError(f"{self.path}: no topic {topic!r} (image topics: {listed})")
        if any(c.msgtype not in IMAGE_TYPES for c in conns):
            raise InputError(f"{self.path}: topic {topic!r} carries {conns[0].msgtype}, expected "
                             "sensor_msgs/Image or sensor_msgs/CompressedImage")
        return topic, conns

    def _messages(self, start: int | None = None):
        for conn, t_ns, raw in self._reader.messages(connections=self._connections, start=start):
            try:
                msg = self._reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                raise InputError(f"{self.path}: a message of {self.topic} at {t_ns} ns cannot be "
                                 f"decoded ({_reason(exc)})") from None
            yield t_ns, msg

    def _index(self) -> tuple[list[int], np.ndarray, str]:
        bag_ns, header = [], []
        try:
            for t_ns, msg in self._messages():
                bag_ns.append(int(t_ns))
                stamp = getattr(getattr(msg, "header", None), "stamp", None)
                header.append(None if stamp is None else (int(stamp.sec), int(stamp.nanosec)))
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"{self.path}: cannot read the ROS bag ({_reason(exc)})") from None
        if not bag_ns:
            raise InputError(f"{self.path}: topic {self.topic} has no messages")
        if all(h is not None and h != (0, 0) for h in header):
            t = np.array([s + ns * 1e-9 for s, ns in header], dtype=float)
            if np.all(np.diff(t) > 0):
                return bag_ns, t, "header"
        t = np.array(bag_ns, dtype=float) * 1e-9
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0)) + 1
            raise InputError(f"{self.path}: the messages of {self.topic} do not increase in time "
                             f"(message {k} at {bag_ns[k]} ns, after {bag_ns[k - 1]} ns)")
        return bag_ns, t, "bag"

    def __len__(self) -> int:
        return len(self._bag_ns)

    def read(self, index: int) -> np.ndarray | bytes:
        """Frame ``index``: an array in OpenCV layout, or the bytes of a compressed image."""
        index = int(index)
        if not 0 <= index < len(self):
            raise IndexError(f"frame {index} out of range 0..{len(self) - 1}")
        if self._gen is None or index != self._next:
            # Seek: messages from the frame's record time on (earlier ones of the same ns skipped).
            first = self._bag_ns.index(self._bag_ns[index])
            self._gen = self._messages(start=self._bag_ns[index])
            self._next = first
        while True:
            try:
                _, msg = next(self._gen)
            except StopIteration:
                self._gen = None
                raise InputError(f"{self.path}: message {index} of {self.topic} is missing "
                                 "(the bag changed?)") from None
            self._next += 1
            if self._next - 1 == index:
                return self._image(msg, index)

    def _image(self, msg, index: int) -> np.ndarray | bytes:
        where = f"{self.path}: {self.topic} message {index}"
        if hasattr(msg, "format"):  # CompressedImage
            return bytes(np.asarray(msg.data, dtype=np.uint8).tobytes())
        enc = str(msg.encoding).strip().lower()
        h, w, step = int(msg.height), int(msg.width), int(msg.step)
        data = np.asarray(msg.data, dtype=np.uint8)
        if enc in _ENCODINGS_8:
            ch, dtype = _ENCODINGS_8[enc], np.dtype(np.uint8)
        elif enc in _ENCODINGS_16:
            ch = _ENCODINGS_16[enc]
            dtype = np.dtype(">u2" if msg.is_bigendian else "<u2")
        elif enc == "32fc1":
            ch, dtype = 1, np.dtype(">f4" if msg.is_bigendian else "<f4")
        else:
            raise InputError(f"{where}: image encoding {msg.encoding!r} is not supported "
                             "(use mono8/mono16, rgb8/bgr8[a], or a compressed image)")
        row = w * ch * dtype.itemsize
        if h <= 0 or w <= 0 or step < row or data.size < step * (h - 1) + row:
            raise InputError(f"{where}: {data.size} bytes do not hold a {w}x{h} {enc} image "
                             f"with step {step}")
        rows = np.lib.stride_tricks.as_strided(data, shape=(h, row), strides=(step, 1))
        img = np.ascontiguousarray(rows).view(dtype).reshape(h, w, ch)
        img = img.astype(dtype.newbyteorder("=")) if dtype.byteorder == ">" else img
        if ch == 1:
            return img[:, :, 0]
        if enc.startswith("rgb"):
            img = img[:, :, [2, 1, 0, 3][:ch]]  # OpenCV's BGR(A)
        return np.ascontiguousarray(img)

    def close(self) -> None:
        """Close the bag."""
        self._gen = None
        reader = getattr(self, "_reader", None)
        if reader is not None:
            self._reader = None
            try:
                reader.close()
            except Exception:
                pass

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass
