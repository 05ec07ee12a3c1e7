"""``run.yaml``: what produced the outputs of a ``monovo track`` run, written beside them.

The record holds the monovo version, the options -- ``dataclasses.asdict`` of the
:class:`~monovo_cli.core.options.TrackOptions` and the command's own options -- and
fingerprints of the inputs:

* small files (init.yaml, times.txt, the model, mask, prior and ground truth): their size
  and SHA-256;
* the frames: their number and the SHA-256 of the frame list, one line per input file with
  its name, size (bytes) and modification time (ns). The frames' contents are **not**
  hashed -- reading a long archive twice would cost as much as tracking it -- except frame
  0's file, which carries the ground model. A video or a bag is fingerprinted the same way
  (its file(s) by name, size and modification time).

It is written atomically (:mod:`monovo_cli.io.atomic`) when the run starts, so an
interrupted run has one too.
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from monovo_cli import __version__
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.digest import file_fingerprint, sha256_file
from monovo_cli.io.frames import FrameSequence

RUN_FILE = "run.yaml"
FORMAT = "monovo-run-1"


def frames_fingerprint(frames: FrameSequence) -> dict[str, Any]:
    """The frames' fingerprint (module docstring): source, kind, count, the SHA-256 of the
    list of (name, size, mtime) of the input files, frame 0's file's SHA-256 (images and PDS
    products), and times.txt's fingerprint."""
    h = hashlib.sha256()
    for p in frames.paths:
        try:
            st = p.stat()
            size, mtime = st.st_size, st.st_mtime_ns
        except OSError:  # e.g. a dangling link: tracking reports the frame when it gets there
            size, mtime = -1, -1
        h.update(f"{p.name}\0{size}\0{mtime}\n".encode())
    one_file_per_frame = frames.kind in ("images", "pds")
    return {
        "source": str(Path(frames.dir).resolve()),
        "kind": frames.kind,
        "count": len(frames),
        "list_sha256": h.hexdigest(),
        "list_covers": "name, size and mtime of every input file (contents not hashed)",
        "frame0_sha256": sha256_file(frames.paths[0]) if one_file_per_frame else None,
        "times": file_fingerprint(frames.times_path),
    }


def _plain(value: Any) -> Any:
    """Paths as absolute paths' text, tuples as lists, recursively: what yaml.safe_dump
    writes."""
    if isinstance(value, Path):
        return str(value.resolve())
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def run_record(command: str, options: Any, own: Mapping[str, Any], frames: FrameSequence,
               init_yaml: Path, files: Mapping[str, Path | None]) -> dict[str, Any]:
    """The record of a run of ``monovo command``: ``options`` the TrackOptions, ``own`` the
    command's own options, ``files`` the side inputs (model, mask, ...) to fingerprint."""
    return {
        "format": FORMAT,
        "monovo": __version__,
        "command": command,
        "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "options": {"track": dataclasses.asdict(options), **_plain(dict(own))},
        "inputs": {"init_yaml": file_fingerprint(init_yaml), "frames": frames_fingerprint(frames),
                   **{name: file_fingerprint(p) for name, p in files.items()}},
    }


def write_run_record(out_dir: Path, record: Mapping[str, Any]) -> Path:
    """Write ``record`` to ``out_dir/run.yaml`` atomically; returns its path."""
    path = Path(out_dir) / RUN_FILE
    text = ("# What produced the outputs in this folder (docs/guide.md \"File formats\").\n"
            + yaml.safe_dump(_plain(dict(record)), sort_keys=False, default_flow_style=False))
    atomic_write_text(path, text)
    return path
