"""Tracking a sequence in memory: the library entry point.

A newcomer's five lines (docs/architecture.md)::

    import monovo_cli

    run = monovo_cli.track_frames("sample_sequences/navcam_drive")  # init.yaml beside it
    print(run.frames, run.lost, f"{run.path_length:.2f} m")
    for k, pose, status in zip(run.index, run.trajectory, run.status): ...

:func:`track_frames` returns the :class:`~monovo_cli.core.run.TrackRun`; :func:`iter_track`
yields each frame's :class:`~monovo_cli.core.odometry.FrameResult` as it is done. Both open
the sequence with :func:`open_sequence` and run a :class:`Tracking`, which ``monovo track``
(:mod:`monovo_cli.pipeline.track`) drives too, writing rows as they come. Nothing here writes
a file.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.odometry import FrameResult, estimate_frames
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.run import RunRecorder, TrackRun
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import InputError, TrackingError
from monovo_cli.geometry.plane import Plane, pitch_roll_deg
from monovo_cli.io.config import InitConfig, check_frame_size, load_init
from monovo_cli.io.sources import Frame, FrameSource, find_init_yaml, open_frames, resolve_sequence
from monovo_cli.mapping.smoothing import SmoothedDrive, smooth_drive
from monovo_cli.mapping.terrain_map import TerrainMap
from monovo_cli.pipeline.threads import each_on_one_blas_thread, one_blas_thread

log = logging.getLogger(__name__)

# What a bad frame's message suggests (the command line names the flags: cli.group.FLAG_WORDS)
_RERUN = "rerun recording unreadable frames as lost"
_RERUN_REPLACING = "rerun recording unreadable frames as lost and replacing these outputs"


@dataclass(frozen=True)
class OpenedSequence:
    """A sequence ready to track: its ``frames``, its init.yaml ``config`` and frame 0
    (``first``), decoded once and checked against the config's camera."""

    frames: FrameSource
    config: InitConfig
    first: Frame


def open_sequence(seq: str | Path, params: str | Path | InitConfig | None = None, *,
                  topic: str | None = None) -> OpenedSequence:
    """The frames of ``seq`` (a folder of images or PDS products, a video, a ROS bag) with
    their init.yaml: ``params`` (a path or a loaded :class:`InitConfig`), or the init.yaml
    found beside the frames when None; ``topic`` the image topic of a ROS bag.

    InputError when no init.yaml is found, frame 0 cannot be read, or its size is not the
    camera's.
    """
    seq_dir = resolve_sequence(Path(seq))
    frames = open_frames(seq_dir, topic=topic)
    if isinstance(params, InitConfig):
        cfg = params
    else:
        if params is None:
            params = find_init_yaml(Path(seq))
            if params is None:
                raise InputError(f"{seq}: no init.yaml beside the frames; give one with -p init.yaml")
        cfg = load_init(Path(params))
    try:
        first = frames.read(0)
    except InputError as exc:
        raise InputError(f"{exc}; frame 0 carries the ground model, replace the file") from None
    h, w = first.image.shape
    check_frame_size(cfg, w, h, first.path)
    return OpenedSequence(frames, cfg, first)


@contextlib.contextmanager
def naming(path: Path) -> Iterator[None]:
    """Prefix a TrackingError (e.g. too few observation points) with the frame it is about."""
    try:
        yield
    except TrackingError as exc:
        raise TrackingError(f"{path}: {exc}") from None


class Tracking:
    """One tracking run over an :class:`OpenedSequence`, frame by frame.

    Iterating yields each frame's :class:`~monovo_cli.core.odometry.FrameResult`, frame 0
    first, and records it; :meth:`result` then gives the :class:`TrackRun`, its trajectory
    smoothed in hindsight once (``smooth``). A caller that must commit a frame's outputs
    together with its record (``monovo track`` holds signals over both) iterates
    :meth:`results` with ``record=False`` and calls :meth:`record` itself.

    ``options`` the tracking options; ``mask`` (H, W) bool, the pixels that may be used;
    ``priors`` frame index -> prior motion T_{k-1}_k (4x4) replacing the constant-velocity
    guess; ``first_keyframe`` a frame-0 ground model built before (``monovo init``);
    ``skip_bad_frames`` records a frame that cannot be read (after frame 0) as lost instead
    of stopping; ``terrain`` keeps what tracking learns of the ground (:attr:`terrain`);
    ``stopped(index)`` adds to the message of a frame that cannot be read what was kept;
    ``rerun_replaces`` says in it that the rerun it suggests (recording unreadable frames as
    lost) must be allowed to replace the outputs written so far.
    """

    def __init__(self, seq: OpenedSequence, options: TrackOptions | None = None, *,
                 mask: np.ndarray | None = None, priors: Mapping[int, np.ndarray] | None = None,
                 first_keyframe: Keyframe | None = None, skip_bad_frames: bool = False,
                 smooth: bool = True, terrain: bool = False,
                 stopped: Callable[[int], str] | None = None,
                 rerun_replaces: bool = False) -> None:
        self.seq = seq
        self.options = options or TrackOptions()
        self.smooth = smooth
        self.terrain = TerrainMap(seq.config.plane) if terrain else None
        self._mask, self._priors, self._first_key = mask, dict(priors or {}), first_keyframe
        self._skip_bad_frames = skip_bad_frames
        self._stopped = stopped or (lambda index: f"frames 0..{index - 1} were done")
        self._rerun_replaces = rerun_replaces
        self._recorder = RunRecorder()
        self._last_image: np.ndarray | None = None
        self.drive: SmoothedDrive | None = None

    def __len__(self) -> int:
        """The number of frames in the sequence."""
        return len(self.seq.frames)

    def __iter__(self) -> Iterator[FrameResult]:
        return self.results(record=True)

    def results(self, *, record: bool) -> Iterator[FrameResult]:
        """Each frame's result, frame 0 first; recorded as it comes if ``record``."""
        cfg = self.seq.config

        def on_keyframe(key: Keyframe) -> None:
            self._recorder.add_keyframe(key)
            log.info("frame %d: keyframe of %d observation points; its ground %s", key.index,
                     len(key.levels[0].points), _ground_words(key.plane))
            if self.terrain is not None:
                self.terrain.add(key, self._last_image)

        tracked = each_on_one_blas_thread(estimate_frames(
            self._images(), cfg.camera, cfg.plane, cfg.region, self.options, mask=self._mask,
            first_keyframe=self._first_key, priors=self._priors, on_keyframe=on_keyframe,
            sigma_distance=cfg.sigma_distance, sigma_deg=cfg.sigma_deg))
        with naming(self.seq.first.path):  # frame 0 builds the ground model
            first = next(tracked)
        for res in _chain(first, tracked):
            if record:
                self.record(res)
            yield res

    def record(self, res: FrameResult) -> None:
        """Add ``res`` to the run (:meth:`results` with ``record=False``)."""
        self._recorder.add(res)

    @property
    def done(self) -> int:
        """The frames recorded so far."""
        return len(self._recorder)

    def trajectory(self) -> np.ndarray:
        """(n, 4, 4) the poses to write of the n frames recorded so far: smoothed in
        hindsight over them (``smooth``) or as estimated."""
        rec = self._recorder
        W = rec.world_from_cam.reshape(-1, 4, 4)
        if not self.smooth:
            return W
        with one_blas_thread():
            return smooth_drive(rec.index, W, [(k.index, k) for k in rec.keyframes]).world_from_cam

    def result(self, seconds: float = 0.0) -> TrackRun:
        """The run of the frames recorded, smoothed in hindsight once (``smooth``); the
        terrain (when kept) is finished against the last frame and placed with the same
        smoothing (:attr:`drive`)."""
        rec = self._recorder
        W = rec.world_from_cam.reshape(-1, 4, 4)
        with one_blas_thread():
            self.drive = (smooth_drive(rec.index, W, [(k.index, k) for k in rec.keyframes])
                          if self.smooth and len(rec) else None)
            if self.drive is not None and self.drive.key_index:
                log.info("the ground at frame %d as the whole drive measured it: %s; "
                         "init.yaml gave %s", self.drive.key_index[0],
                         _ground_words(self.drive.planes[0]),
                         _ground_words(self.seq.config.plane))
            if self.terrain is not None and len(rec):
                last_lost = rec.last_status == FrameStatus.LOST
                self.terrain.finish(None if last_lost else self._last_image, W[-1])
        return rec.result(self.drive.world_from_cam if self.drive is not None else None, seconds)

    def _images(self) -> Iterator[tuple[int, float, np.ndarray | None]]:
        """``(index, timestamp, image)`` of every frame for the core's loop, frame 0 as
        :func:`open_sequence` decoded it.

        A frame that cannot be read stops the run with an InputError, or with
        ``skip_bad_frames`` (after frame 0) comes as ``image`` None, which the tracker
        records as lost.
        """
        frames, first = self.seq.frames, self.seq.first
        self._last_image = first.image
        yield first.index, first.timestamp, first.image
        for index in range(1, len(frames)):
            try:
                frame = frames.read(index)
            except InputError as exc:
                if not self._skip_bad_frames:
                    rerun = _RERUN_REPLACING if self._rerun_replaces else _RERUN
                    raise InputError(f"{exc}; tracking stopped at frame {index} "
                                     f"({self._stopped(index)}); replace the file, or "
                                     f"{rerun}") from None
                log.warning("%s; recorded as lost (unreadable frames are skipped)", exc)
                self._last_image = None
                yield index, float(frames.timestamps[index]), None
            else:
                self._last_image = frame.image
                yield frame.index, frame.timestamp, frame.image


def _ground_words(plane: Plane) -> str:
    """A plane in its camera as a log line says it: the camera's pitch and roll, its height."""
    pitch, roll = pitch_roll_deg(plane.normal)
    return f"pitch {pitch:.2f} deg, roll {roll:.2f} deg, {plane.distance:.3f} m below the camera"


def _chain(first: FrameResult, rest: Iterator[FrameResult]) -> Iterator[FrameResult]:
    yield first
    yield from rest


def read_mask(path: Path, cfg: InitConfig) -> np.ndarray:
    """A mask PNG -> (H, W) bool of usable pixels (the PNG's non-zero pixels are excluded)."""
    from monovo_cli.io.grey import read_gray

    img = read_gray(path)
    if img.shape != (cfg.camera.height, cfg.camera.width):
        raise InputError(f"{path}: mask is {img.shape[1]}x{img.shape[0]} but frames are "
                         f"{cfg.camera.width}x{cfg.camera.height}")
    usable = img <= 0
    if not usable.any():
        raise InputError(f"{path}: the mask excludes every pixel (non-zero pixels are excluded)")
    return usable


def read_prior(path: Path) -> dict[int, np.ndarray]:
    """A prior motion CSV (motion.csv's columns) -> {frame index: T_{k-1}_k (4, 4)}."""
    from monovo_cli.io.formats import read_motion_csv

    idx, poses, _ = read_motion_csv(path)
    return {int(k): p for k, p in zip(idx, poses)}


def iter_track(frames: str | Path, init: str | Path | InitConfig | None = None,
               options: TrackOptions | None = None, *, topic: str | None = None,
               mask: str | Path | None = None, prior: str | Path | None = None,
               skip_bad_frames: bool = False) -> Iterator[FrameResult]:
    """Track the sequence ``frames`` (a folder of frames, a video, a ROS bag; with ``topic``)
    with its ``init`` (init.yaml's path or a loaded config; None: found beside the frames)
    and yield each frame's :class:`~monovo_cli.core.odometry.FrameResult`, frame 0 first.

    ``mask`` a PNG whose non-zero pixels are never used; ``prior`` a CSV of prior motions
    (motion.csv's columns) replacing the constant-velocity guess.
    """
    yield from _tracking(frames, init, options, topic=topic, mask=mask, prior=prior,
                         skip_bad_frames=skip_bad_frames, smooth=False)


def track_frames(frames: str | Path, init: str | Path | InitConfig | None = None,
                 options: TrackOptions | None = None, *, topic: str | None = None,
                 mask: str | Path | None = None, prior: str | Path | None = None,
                 skip_bad_frames: bool = False, smooth: bool = True) -> TrackRun:
    """Track the sequence ``frames`` as :func:`iter_track` does and return the whole
    :class:`~monovo_cli.core.run.TrackRun`, its ``trajectory`` smoothed in hindsight unless
    ``smooth`` is False (what ``monovo track`` writes to trajectory.csv)."""
    tracking = _tracking(frames, init, options, topic=topic, mask=mask, prior=prior,
                         skip_bad_frames=skip_bad_frames, smooth=smooth)
    for _ in tracking:
        pass
    return tracking.result()


def _tracking(frames, init, options, *, topic, mask, prior, skip_bad_frames, smooth) -> Tracking:
    seq = open_sequence(frames, init, topic=topic)
    usable = read_mask(Path(mask), seq.config) if mask is not None else None
    priors = read_prior(Path(prior)) if prior is not None else None
    return Tracking(seq, options, mask=usable, priors=priors, skip_bad_frames=skip_bad_frames,
                    smooth=smooth)
