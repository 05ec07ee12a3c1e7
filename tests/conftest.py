"""Synthetic drives shared by the tests: each is synthesised once per session.

``synth_drive(**kwargs)`` runs :func:`monovo_cli.synth.write.synthesize` with those
arguments the first time they are asked for and returns the sequence folder; later calls
with the same arguments (defaults filled in) return the same folder, from any test file.
The drives are the exact ones a test would write itself: same seed, same parameters.

The folders are shared, so they are read-only: a test that changes its drive (damages a
frame, adds times.txt, writes outputs beside it) copies it to its ``tmp_path`` first.
Each drive's file list, sizes and modification times are checked at the end of the
session, so a test that writes into a shared drive fails loudly instead of changing what
the tests after it see.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path

import pytest

from monovo_cli.synth.write import synthesize

_SYNTHESIZE = inspect.signature(synthesize)


def _key(kwargs: dict) -> tuple:
    """The arguments with synthesize's defaults filled in: one key per distinct drive."""
    bound = _SYNTHESIZE.bind(None, **kwargs)
    bound.apply_defaults()
    return tuple(sorted((name, tuple(v) if isinstance(v, list) else v)
                        for name, v in bound.arguments.items() if name != "out_dir"))


def _state(seq: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(seq)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(seq.rglob("*"))}


@pytest.fixture(scope="session")
def synth_drive(tmp_path_factory) -> Callable[..., Path]:
    """``synth_drive(preset=..., frames=..., size=..., seed=..., ...)``: the folder of that
    synthetic sequence (frames/, init.yaml, ground truth), made once per session. Read-only."""
    made: dict[tuple, tuple[Path, dict]] = {}

    def drive(**kwargs) -> Path:
        key = _key(kwargs)
        if key not in made:
            seq = tmp_path_factory.mktemp("drive") / "seq"
            synthesize(seq, **kwargs)
            made[key] = seq, _state(seq)
        return made[key][0]

    yield drive
    changed = [f"{seq} ({dict(key)})" for key, (seq, state) in made.items() if _state(seq) != state]
    assert not changed, f"a test wrote into a shared drive; copy it to tmp_path first: {changed}"


@pytest.fixture(scope="session")
def small_drive(synth_drive) -> Path:
    """10 frames of 128 x 128, seed 4 (``monovo synth --frames 10 --size 128x128 --seed 4``)."""
    return synth_drive(preset="drive", frames=10, size=(128, 128), seed=4)


@pytest.fixture(scope="session")
def other_small_drive(synth_drive) -> Path:
    """The same kind of drive with seed 5: another sequence, another frame 0."""
    return synth_drive(preset="drive", frames=10, size=(128, 128), seed=5)
