"""The speed benchmarks time monovo on the thread budget of the peers they set it against:
one thread (no frames decoded ahead on a second core) unless asked for more."""

from __future__ import annotations

import benchmarks.peers as peers
import benchmarks.speed as speed
from benchmarks.profile import profile_drive


def _threads_of(monkeypatch, module, call) -> list:
    """The ``threads`` of every ``module.track_sequence`` call ``call()`` makes."""
    seen = []
    real = module.track_sequence

    def spy(*args, **kwargs):
        seen.append(kwargs.get("threads"))
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "track_sequence", spy)
    call()
    return seen


def test_monovo_runs_on_one_thread_against_the_peers(small_drive, tmp_path, monkeypatch):
    assert _threads_of(monkeypatch, peers,
                       lambda: peers.monovo_on_drive(small_drive, tmp_path / "a")) == [1]
    assert _threads_of(monkeypatch, peers, lambda: peers.monovo_on_drive(
        small_drive, tmp_path / "b", threads=2)) == [2]  # (asked for: both get two)
    assert _threads_of(monkeypatch, speed,
                       lambda: speed.end_to_end(small_drive, tmp_path / "c")) == [1]


def test_the_profile_decodes_in_the_frame_loop(small_drive, tmp_path, monkeypatch):
    """With a reader thread its decodes were counted inside the tracker's parts."""
    import monovo_cli.pipeline.track as track  # (profile_drive imports it when called)

    assert _threads_of(monkeypatch, track,
                       lambda: profile_drive(small_drive, tmp_path / "p")) == [1]
