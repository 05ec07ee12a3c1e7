"""``run.yaml``: what produced the outputs of a ``monovo track`` run, written beside them.

The record holds the monovo version, the options -- ``dataclasses.asdict`` of the
:class:`~monovo_cli.core.options.TrackOptions` and the command's own options -- and
fingerprints of the inputs:

* small files (init.yaml, times.txt, the model, mask, prior and ground truth): their size
  and SHA-256;
* the frames: their source's fingerprint
  (:meth:`~monovo_cli.io.sources.base.FrameSource.fingerprint`): their number and the
  SHA-256 of the frame list, one line per input file with its name, size (bytes) and
  modification time (ns). The frames' contents are **not** hashed --
  reading a long archive twice would cost as much as tracking it -- except frame 0's file,
  which carries the ground model. A video or a bag is fingerprinted the same way (its
  file(s) by name, size and modification time).

It is written atomically (:mod:`monovo_cli.io.atomic`) when the run starts, so an
interrupted run has one too.
"""

from __future__ import annotations

import dataclasses
import datetime
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.digest import file_fingerprint
from monovo_cli.io.sources import FrameSource
from monovo_cli.version import __version__

RUN_FILE = "run.yaml"
#: libyaml's safe dumper where PyYAML was built with it (yaml.safe_dump's text, in C; a run
#: writes the record twice), else PyYAML's own.
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
FORMAT = "monovo-run-1"


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


def run_record(command: str, options: Any, own: Mapping[str, Any], frames: FrameSource,
               init_yaml: Path, files: Mapping[str, Path | None]) -> dict[str, Any]:
    """The record of a run of ``monovo command``: ``options`` the TrackOptions, ``own`` the
    command's own options, ``files`` the side inputs (model, mask, ...) to fingerprint."""
    return {
        "format": FORMAT,
        "monovo": __version__,
        "command": command,
        "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "options": {"track": dataclasses.asdict(options), **_plain(dict(own))},
        "inputs": {"init_yaml": file_fingerprint(init_yaml), "frames": frames.fingerprint(),
                   **{name: file_fingerprint(p) for name, p in files.items()}},
    }


def write_run_record(out_dir: Path, record: Mapping[str, Any]) -> Path:
    """Write ``record`` to ``out_dir/run.yaml`` atomically; returns its path."""
    path = Path(out_dir) / RUN_FILE
    text = ("# What produced the outputs in this folder (docs/guide.md \"File formats\").\n"
            + yaml.dump(_plain(dict(record)), Dumper=_DUMPER, sort_keys=False,
                        default_flow_style=False))
    atomic_write_text(path, text)
    return path
