"""monovo: intensity-difference based monocular visual odometry (Martinez, ch. 10).

The library's front door (docs/architecture.md, "From Python")::

    import monovo_cli

    run = monovo_cli.track_frames("sample_sequences/navcam_drive")
    print(run.frames, run.lost, f"{run.path_length:.2f} m")

:func:`track_frames` returns a :class:`TrackRun`; :func:`iter_track` yields each frame's
result as it is done; :class:`TrackOptions` holds every tracking choice. They are imported
on first use, so ``import monovo_cli`` (and ``monovo --help``) stays light.
"""

from monovo_cli.version import __version__

__all__ = ["TrackOptions", "TrackRun", "__version__", "iter_track", "open_sequence", "track_frames"]


def __getattr__(name: str):
    """The entry points, imported on first use (PEP 562)."""
    if name in ("track_frames", "iter_track", "open_sequence"):
        from monovo_cli.pipeline import tracking

        return getattr(tracking, name)
    if name == "TrackRun":
        from monovo_cli.core.run import TrackRun

        return TrackRun
    if name == "TrackOptions":
        from monovo_cli.core.options import TrackOptions

        return TrackOptions
    raise AttributeError(f"module 'monovo_cli' has no attribute {name!r}")
