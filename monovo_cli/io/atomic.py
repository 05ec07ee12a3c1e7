"""Atomic file writes: a temporary file beside the target, fsync, rename; the umask's mode.

Inside :func:`digests_recorded`, every file written here (but those written with
``digest=False``) or through a :class:`DigestingStream` leaves its size and SHA-256 in the
recorder, computed from the bytes as they are written, so a caller can fingerprint what it
wrote without reading it back.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from monovo_cli.errors import OutputError


def created_mode(directory: bool = False) -> int:
    """The mode a plain create would give a new file (0666) or directory (0777) less the
    umask: what a temporary one (mkstemp 0600, mkdtemp 0700) gets before its rename."""
    mask = os.umask(0)
    os.umask(mask)
    return (0o777 if directory else 0o666) & ~mask


@dataclass(frozen=True)
class FileDigest:
    """A file's size (bytes) and the SHA-256 of its content (hex)."""

    bytes: int
    sha256: str


_RECORDER: ContextVar[dict[str, FileDigest] | None] = ContextVar("monovo_digests", default=None)


@contextlib.contextmanager
def digests_recorded() -> Iterator[dict[str, FileDigest]]:
    """A dict, absolute path -> :class:`FileDigest`, of the files written in this context
    (the last write of a path wins). Per thread and task (a context variable)."""
    digests: dict[str, FileDigest] = {}
    token = _RECORDER.set(digests)
    try:
        yield digests
    finally:
        _RECORDER.reset(token)


def _record(path: Path, size: int, sha256: str) -> None:
    digests = _RECORDER.get()
    if digests is not None:
        digests[os.path.abspath(path)] = FileDigest(size, sha256)


class DigestingStream:
    """A text stream to ``path`` (opened for writing, ``newline=""``) that hashes what it
    writes (UTF-8) and records the digest when closed (:func:`digests_recorded`).

    ``prefix``: the bytes already in the file when ``stream`` appends to it, so that the
    digest and :attr:`size` are the whole file's."""

    def __init__(self, stream: IO[str], path: Path, prefix: bytes = b"") -> None:
        self._stream, self._path = stream, Path(path)
        self._hash, self._size = hashlib.sha256(prefix), len(prefix)

    @property
    def size(self) -> int:
        """The file's length in bytes so far (the prefix and what was written)."""
        return self._size

    def write(self, text: str) -> int:
        data = text.encode("utf-8")
        self._hash.update(data)
        self._size += len(data)
        return self._stream.write(text)

    def flush(self) -> None:
        self._stream.flush()

    def sync(self) -> None:
        """Flush and fsync: what was written is on the disk, not only in the OS's cache."""
        self._stream.flush()
        os.fsync(self._stream.fileno())

    def close(self) -> None:
        if not self._stream.closed:
            self._stream.close()
            _record(self._path, self._size, self._hash.hexdigest())


class _HashingWriter:
    """A binary file that hashes what is written to it (for :func:`atomic_write_with`;
    ``digest`` False: only counts it)."""

    def __init__(self, f: IO[bytes], digest: bool = True) -> None:
        self._f, self.hash, self.size = f, hashlib.sha256() if digest else None, 0

    def write(self, data) -> int:
        if self.hash is not None:
            self.hash.update(data)
        n = self._f.write(data)
        self.size += memoryview(data).nbytes
        return n

    def flush(self) -> None:
        self._f.flush()


def atomic_write_with(path: Path, write: Callable[[IO[bytes]], object], *,
                      digest: bool = True) -> None:
    """Write ``path`` through a temporary file in the same directory + rename, the bytes
    given by ``write(f)`` to a binary file-like ``f`` (its ``write`` and ``flush`` methods
    only, not seekable: a zip archive streams into it without the whole file ever being one
    bytes object in memory).

    No half-written file ever carries the final name; the file gets the mode a plain
    ``open()`` would give it. ``digest`` False: the bytes are not hashed and the file is not
    recorded (:func:`digests_recorded`), for a file no record lists (the checkpoint).
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.fchmod(fd, created_mode())
    except OSError as exc:
        raise OutputError(f"{path.parent}: cannot write here ({exc.strerror})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            out = _HashingWriter(f, digest)
            write(out)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        if out.hash is not None:
            _record(path, out.size, out.hash.hexdigest())
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`atomic_write_with`)."""
    atomic_write_with(path, lambda f: f.write(data))


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))
