"""Fingerprints of files: the SHA-256 of a file's contents, and ``{path, bytes, sha256}``.

What run.yaml, done.json and the frame sources' fingerprints are made of; no YAML, no
OpenCV, so a batch worker can use it before loading either.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any


def sha256_file(path: Path) -> str:
    """SHA-256 (hex) of the file ``path``, read in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def file_fingerprint(path: Path | None) -> dict[str, Any] | None:
    """``{path, bytes, sha256}`` of a file (absolute path), None for no file."""
    if path is None:
        return None
    path = Path(path)
    return {"path": str(path.resolve()), "bytes": path.stat().st_size, "sha256": sha256_file(path)}
