"""A ROS 1 / ROS 2 bag's image topic as frames, read with ``rosbags``.

A ROS 1 ``.bag`` file or a ROS 2 bag directory (``metadata.yaml`` with ``.db3``/``.mcap``
files), read with the pure-Python ``rosbags`` (an optional extra, ``pip install
monovo[ros]``). The messages of one ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage``
topic are the frames (``topic``; may be omitted when the bag holds exactly one image topic).
Timestamps are the messages' ``header.stamp`` when every one is set and they increase, else
the times the messages were recorded. Raw images (mono8/16, rgb8/bgr8[a], 32FC1, either byte
order) and compressed ones become grey as image files do (:mod:`monovo_cli.io.grey`).
Frame k is called ``BAG[k]`` in messages. Random access works by seeking to the frame's
record time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.grey import decode_gray, grey_from_pixels
from monovo_cli.io.sources.base import FrameSource

ROS1_EXTENSION = ".bag"
ROS2_METADATA = "metadata.yaml"
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
_ENCODINGS_8 = {"mono8": 1, "8uc1": 1, "bgr8": 3, "rgb8": 3, "8uc3": 3, "bgra8": 4, "rgba8": 4,
                "8uc4": 4}
_ENCODINGS_16 = {"mono16": 1, "16uc1": 1, "bgr16": 3, "rgb16": 3, "bgra16": 4, "rgba16": 4}


def is_bag(path: Path) -> bool:
    """A ROS 1 bag file (``.bag``) or a ROS 2 bag directory (holding ``metadata.yaml``)."""
    path = Path(path)
    if path.is_dir():
        return (path / ROS2_METADATA).is_file()
    return path.suffix.lower() == ROS1_EXTENSION


def bag_root(path: Path) -> Path:
    """The bag a path names: the ``.bag`` file, or the ROS 2 bag directory (also when given
    its ``metadata.yaml`` or one of its storage files); any other path as it is."""
    path = Path(path)
    if path.is_file() and path.suffix.lower() != ROS1_EXTENSION and (path.parent / ROS2_METADATA).is_file():
        return path.parent
    return path


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


class RosBag(FrameSource):
    """The image messages of one topic of the bag ``path`` (module docstring).

    ``topic`` the topic read; ``stamp_source`` "header" or "bag" (where the timestamps came
    from); ``paths`` the bag's file(s). Raises InputError if the bag cannot be read, the
    topic is missing or not an image topic, or the bag holds several image topics and none
    was named.
    """

    kind = "bag"

    def __init__(self, path: Path, topic: str | None = None) -> None:
        super().__init__(bag_root(Path(path)))
        self._reader, self._gen, self._next = None, None, 0
        self._open_reader()
        try:
            self.topic, self._connections = self._pick(topic)
            self._bag_ns, self.timestamps, self.stamp_source = self._index()
        except BaseException:
            self.close()
            raise
        self.paths = ([self.dir] if self.dir.is_file() else
                      sorted(p for p in self.dir.iterdir() if p.is_file()))

    def _open_reader(self) -> None:
        reader_cls, self._typestore = _rosbags()
        try:
            self._reader = reader_cls([self.dir], default_typestore=self._typestore)
            self._reader.open()
        except Exception as exc:  # rosbags raises its own error types per storage
            self._reader = None
            raise InputError(f"{self.dir}: cannot read the ROS bag ({_reason(exc)})") from None

    def image_topics(self) -> dict[str, str]:
        """``{topic: message type}`` of the bag's image topics."""
        return {c.topic: c.msgtype for c in self._reader.connections if c.msgtype in IMAGE_TYPES}

    def _pick(self, topic: str | None):
        images = self.image_topics()
        if topic is None:
            if len(images) != 1:
                listed = ", ".join(sorted(images)) or "none"
                raise InputError(f"{self.dir}: {len(images)} image topics ({listed}); "
                                 "name one as the image topic")
            topic = next(iter(images))
        conns = [c for c in self._reader.connections if c.topic == topic]
        if not conns:
            listed = ", ".join(sorted(images)) or "none"
            raise InputError(f"{self.dir}: no topic {topic!r} (image topics: {listed})")
        if any(c.msgtype not in IMAGE_TYPES for c in conns):
            raise InputError(f"{self.dir}: topic {topic!r} carries {conns[0].msgtype}, expected "
                             "sensor_msgs/Image or sensor_msgs/CompressedImage")
        return topic, conns

    def _messages(self, start: int | None = None):
        for conn, t_ns, raw in self._reader.messages(connections=self._connections, start=start):
            try:
                msg = self._reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                raise InputError(f"{self.dir}: a message of {self.topic} at {t_ns} ns cannot be "
                                 f"decoded ({_reason(exc)})") from None
            yield t_ns, msg

    def _index(self) -> tuple[list[int], np.ndarray, str]:
        """(record times (ns) of the messages, their timestamps (s), where those came from)."""
        bag_ns, header = [], []
        try:
            for t_ns, msg in self._messages():
                bag_ns.append(int(t_ns))
                stamp = getattr(getattr(msg, "header", None), "stamp", None)
                header.append(None if stamp is None else (int(stamp.sec), int(stamp.nanosec)))
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"{self.dir}: cannot read the ROS bag ({_reason(exc)})") from None
        if not bag_ns:
            raise InputError(f"{self.dir}: topic {self.topic} has no messages")
        if all(h is not None and h != (0, 0) for h in header):
            t = np.array([s + ns * 1e-9 for s, ns in header], dtype=float)
            if np.all(np.diff(t) > 0):
                return bag_ns, t, "header"
        t = np.array(bag_ns, dtype=float) * 1e-9
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0)) + 1
            raise InputError(f"{self.dir}: the messages of {self.topic} do not increase in time "
                             f"(message {k} at {bag_ns[k]} ns, after {bag_ns[k - 1]} ns)")
        return bag_ns, t, "bag"

    def _raw(self, index: int) -> np.ndarray | bytes:
        """Frame ``index``: an array in OpenCV layout, or the bytes of a compressed image."""
        if self._reader is None:  # closed: reopen, the topic's connections with it
            self._open_reader()
            _, self._connections = self._pick(self.topic)
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
                raise InputError(f"{self.dir}: message {index} of {self.topic} is missing "
                                 "(the bag changed?)") from None
            self._next += 1
            if self._next - 1 == index:
                return self._image(msg, index)

    def _image(self, msg, index: int) -> np.ndarray | bytes:
        where = f"{self.dir}: {self.topic} message {index}"
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

    def _decode(self, index: int) -> np.ndarray:
        raw = self._raw(index)
        name = self.frame_name(index)
        return decode_gray(raw, name) if isinstance(raw, bytes) else grey_from_pixels(raw, name)

    def close(self) -> None:
        """Close the bag (reading again reopens it)."""
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
