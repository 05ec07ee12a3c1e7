"""Atomic file writes: a temporary file beside the target, fsync, rename; the umask's mode.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from monovo_cli.errors import OutputError


def created_mode(directory: bool = False) -> int:
    """The mode a plain create would give a new file (0666) or directory (0777) less the
    umask: what a temporary one (mkstemp 0600, mkdtemp 0700) gets before its rename."""
    mask = os.umask(0)
    os.umask(mask)
    return (0o777 if directory else 0o666) & ~mask


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same directory + rename.

    No half-written file ever carries the final name; the file gets the mode a plain
    ``open()`` would give it.
    """
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.fchmod(fd, created_mode())
    except OSError as exc:
        raise OutputError(f"{path.parent}: cannot write here ({exc.strerror})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def atomic_write_text(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8, newlines as given) to ``path`` atomically."""
    atomic_write_bytes(path, text.encode("utf-8"))
