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

import cv2
import numpy as np

from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.odometry import FrameResult, Odometry
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.run import RunRecorder, TrackRun
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import InputError, TrackingError
from monovo_cli.geometry.plane import Plane, pitch_roll_deg
from monovo_cli.io.checkpoint import state_types as checkpoint_types
from monovo_cli.io.config import InitConfig, check_frame_size, load_init
from monovo_cli.io.sources import Frame, FrameSource, find_init_yaml, open_frames, resolve_sequence
from monovo_cli.io.state_codec import ArraySpec, Registry
from monovo_cli.mapping.gaps import close_gaps
from monovo_cli.mapping.smoothing import SmoothedDrive, smooth_drive
from monovo_cli.mapping.terrain_map import TerrainMap
from monovo_cli.pipeline.read_ahead import read_frames
from monovo_cli.pipeline.threads import one_blas_thread, opencv_threads

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


@dataclass(frozen=True)
class TrackingState:
    """A :class:`Tracking` between two frames (:meth:`Tracking.state`): ``next_frame`` the
    index of the next frame to track, the ``odometry`` and the ``recorder`` of the frames
    before it, the ``terrain`` map (None when not kept), ``last_image`` (H, W), the last
    frame's image (None if it could not be read), and its index ``last_index``;
    ``thumbnails`` the keyframe thumbnails kept so far with their thinning's counters."""

    next_frame: int
    odometry: Odometry
    recorder: RunRecorder
    terrain: TerrainMap | None
    last_image: np.ndarray | None
    last_index: int = -1
    thumbnails: tuple = ({}, 1, 0, -1)


def state_types() -> Registry:
    """The classes of a :class:`TrackingState`, for its checkpoint
    (:func:`monovo_cli.io.checkpoint.state_types` and :class:`TrackingState` itself)."""
    types = checkpoint_types()
    types.add(TrackingState, arrays={"last_image": ArraySpec("<f4", (None, None), optional=True)})
    return types


class Tracking:
    """One tracking run over an :class:`OpenedSequence`, frame by frame.

    Iterating yields each frame's :class:`~monovo_cli.core.odometry.FrameResult`, frame 0
    first, and records it; :meth:`result` then gives the :class:`TrackRun`, its trajectory
    smoothed in hindsight once (``smooth``). A caller that must commit a frame's outputs
    together with its record (``monovo track`` holds signals over both) iterates
    :meth:`results` with ``record=False`` and calls :meth:`record` itself. :meth:`state`
    between two frames, given to :meth:`restore` of another Tracking of the same sequence
    and settings, continues the run exactly (``monovo track --resume``).

    ``options`` the tracking options; ``mask`` (H, W) bool, the pixels that may be used;
    ``priors`` frame index -> prior motion T_{k-1}_k (4x4) replacing the constant-velocity
    guess; ``first_keyframe`` a frame-0 ground model built before (``monovo init``);
    ``skip_bad_frames`` records a frame that cannot be read (after frame 0) as lost instead
    of stopping; ``terrain`` keeps what tracking learns of the ground (:attr:`terrain`);
    ``stopped(index)`` adds to the message of a frame that cannot be read what was kept;
    ``rerun_replaces`` says in it that the rerun it suggests (recording unreadable frames as
    lost) must be allowed to replace the outputs written so far.
    ``thumbnails`` > 0 keeps a small grey copy (uint8, at most ``thumbnail_side`` px on its
    longer side) of at most that many keyframes' images (:attr:`thumbnails`, frame index ->
    image): when there are more, every other one is dropped, frame 0 kept, so those kept
    stay spread evenly over the drive. ``threads``: OpenCV's while tracking, and from 2 on
    the frames are decoded on a thread of their own, ahead of the tracker (the same results).
    """

    def __init__(self, seq: OpenedSequence, options: TrackOptions | None = None, *,
                 mask: np.ndarray | None = None, priors: Mapping[int, np.ndarray] | None = None,
                 first_keyframe: Keyframe | None = None, skip_bad_frames: bool = False,
                 smooth: bool = True, terrain: bool = False,
                 stopped: Callable[[int], str] | None = None, thumbnails: int = 0,
                 thumbnail_side: int = 240, rerun_replaces: bool = False,
                 threads: int = 1) -> None:
        self.seq = seq
        self.options = options or TrackOptions()
        self.smooth = smooth
        self.terrain = TerrainMap(seq.config.plane) if terrain else None
        self._priors = dict(priors or {})
        self._skip_bad_frames = skip_bad_frames
        self._threads = int(threads)
        self._stopped = stopped or (lambda index: f"frames 0..{index - 1} were done")
        self._rerun_replaces = rerun_replaces
        cfg = seq.config
        self._odometry = Odometry(cfg.camera, cfg.plane, cfg.region, self.options, mask=mask,
                                  first_keyframe=first_keyframe,
                                  mounting=cfg.mounting)
        self._recorder = RunRecorder()
        self._next = 0  # the next frame to track
        self._last_image: np.ndarray | None = None
        self._last_index = -1
        self.thumbnails: dict[int, np.ndarray] = {}
        self._thumbnail_limit, self._thumbnail_side = int(thumbnails), int(thumbnail_side)
        self._thumbnail_stride, self._keyframes_seen, self._last_keyframe = 1, 0, -1
        self.drive: SmoothedDrive | None = None

    @property
    def initial_tilt(self):
        """The images' verdict on init.yaml's ground tilt
        (:class:`~monovo_cli.core.plane.tracker.InitialTilt`), None until measured."""
        return self._odometry.initial_tilt

    def __len__(self) -> int:
        """The number of frames in the sequence."""
        return len(self.seq.frames)

    def __iter__(self) -> Iterator[FrameResult]:
        return self.results(record=True)

    def results(self, *, record: bool) -> Iterator[FrameResult]:
        """Each frame's result, frame 0 first (or the frame after a :meth:`restore`d
        state); recorded as it comes if ``record``."""
        odo, priors = self._odometry, self._priors
        with opencv_threads(self._threads):  # (for the run: a change rebuilds OpenCV's pool)
            for index, timestamp, image in self._images():
                with one_blas_thread(), (naming(self.seq.first.path) if self._next == 0
                                         else contextlib.nullcontext()):  # frame 0: the model
                    res, keys = odo.advance(index, timestamp, image, priors.get(index))
                    for key in keys:
                        self._recorder.add_keyframe(key)
                        log.info("frame %d: keyframe of %d observation points; its ground %s",
                                 key.index, len(key.levels[0].points), _ground_words(key.plane))
                        if self.terrain is not None:
                            self.terrain.add(key, self._last_image)
                        if self._thumbnail_limit > 0:
                            self._keep_thumbnail(int(key.index))
                self._next = index + 1
                if record:
                    self.record(res)
                yield res

    def _keep_thumbnail(self, index: int) -> None:
        """A small copy of the keyframe image just read (frame ``index``), evenly thinned."""
        image = self._last_image
        if image is None or index != self._last_index:
            return
        if index != self._last_keyframe:  # not a keyframe rebuilt in place
            self._last_keyframe = index
            self._keyframes_seen += 1
        if (self._keyframes_seen - 1) % self._thumbnail_stride:
            return
        h, w = image.shape
        s = min(1.0, self._thumbnail_side / max(h, w))
        small = cv2.resize(image, (max(1, round(w * s)), max(1, round(h * s))),
                           interpolation=cv2.INTER_AREA) if s < 1.0 else image
        self.thumbnails[index] = np.clip(np.rint(small), 0, 255).astype(np.uint8)
        while len(self.thumbnails) > self._thumbnail_limit:
            self._thumbnail_stride *= 2
            keep = sorted(self.thumbnails)[::2]
            self.thumbnails = {k: self.thumbnails[k] for k in keep}

    def state(self) -> TrackingState:
        """Everything this run holds between two frames, after the frames recorded so far:
        :meth:`restore` on a new Tracking of the same sequence and settings continues it
        exactly. Take it after :meth:`record` of the last frame yielded (the objects are
        shared, not copied: write it, :mod:`monovo_cli.io.checkpoint`, before the next
        frame; :func:`state_types` lists its classes)."""
        if self._next != self.done:
            raise ValueError(f"state: {self._next} frames tracked but {self.done} recorded")
        return TrackingState(self._next, self._odometry, self._recorder, self.terrain,
                             self._last_image, self._last_index,
                             (self.thumbnails, self._thumbnail_stride, self._keyframes_seen,
                              self._last_keyframe))

    def restore(self, state: TrackingState) -> None:
        """Continue from ``state`` (:meth:`state` of a run of the same sequence and settings):
        :meth:`results` goes on with frame ``state.next_frame``."""
        if not 0 < state.next_frame <= len(self.seq.frames):
            raise InputError(f"{self.seq.frames.dir}: the saved state continues at frame "
                             f"{state.next_frame}, but the sequence has {len(self.seq.frames)}")
        self._next, self._odometry, self._recorder = (state.next_frame, state.odometry,
                                                      state.recorder)
        self.terrain, self._last_image = state.terrain, state.last_image
        self._last_index = state.last_index
        (self.thumbnails, self._thumbnail_stride, self._keyframes_seen,
         self._last_keyframe) = state.thumbnails

    def record(self, res: FrameResult) -> None:
        """Add ``res`` to the run (:meth:`results` with ``record=False``)."""
        self._recorder.add(res)

    def frames_recorded(self) -> tuple[list[int], list[float]]:
        """The indices and timestamps (s) of the frames recorded so far, in order."""
        return self._recorder.index, self._recorder.timestamp

    @property
    def done(self) -> int:
        """The frames recorded so far."""
        return len(self._recorder)

    def trajectory(self) -> np.ndarray:
        """(n, 4, 4) the poses to write of the n frames recorded so far: the lost frames
        moved with the gaps closed after them (:func:`~monovo_cli.mapping.gaps.close_gaps`),
        then smoothed in hindsight over them (``smooth``)."""
        closed, drive = self._hindsight()
        return closed if drive is None else drive.world_from_cam

    def result(self, seconds: float = 0.0) -> TrackRun:
        """The run of the frames recorded, its lost frames moved with the gaps closed after
        them and smoothed in hindsight once (``smooth``); the terrain (when kept) is
        finished against the last frame and placed with the same smoothing (:attr:`drive`)."""
        rec = self._recorder
        closed, self.drive = self._hindsight()
        with one_blas_thread():
            if self.drive is not None and self.drive.key_index:
                log.info("the ground at frame %d as the whole drive measured it: %s; "
                         "init.yaml gave %s", self.drive.key_index[0],
                         _ground_words(self.drive.planes[0]),
                         _ground_words(self.seq.config.plane))
            if self.terrain is not None and len(rec):
                last_lost = rec.last_status == FrameStatus.LOST
                self.terrain.finish(None if last_lost else self._last_image,
                                    rec.world_from_cam.reshape(-1, 4, 4)[-1])
        return rec.result(self.drive.world_from_cam if self.drive is not None else closed, seconds)

    def _hindsight(self) -> tuple[np.ndarray, SmoothedDrive | None]:
        """The poses of the frames recorded with the gaps closed after lost ones, and their
        smoothing in hindsight (None: ``smooth`` off, or no frame recorded)."""
        rec = self._recorder
        closed = close_gaps(rec.index, rec.world_from_cam.reshape(-1, 4, 4), rec.gaps)
        if not self.smooth or not len(rec):
            return closed, None
        with one_blas_thread():
            return closed, smooth_drive(rec.index, closed, [(k.index, k) for k in rec.keyframes],
                                        tilts=self._odometry.ground_planar)

    def _images(self) -> Iterator[tuple[int, float, np.ndarray | None]]:
        """``(index, timestamp, image)`` of every frame for the core's loop, frame 0 as
        :func:`open_sequence` decoded it.

        A frame that cannot be read stops the run with an InputError, or with
        ``skip_bad_frames`` (after frame 0) comes as ``image`` None, which the tracker
        records as lost.
        """
        frames, first = self.seq.frames, self.seq.first
        if self._next == 0:
            self._last_image, self._last_index = first.image, first.index
            yield first.index, first.timestamp, first.image
        for index, frame, exc in read_frames(frames, max(self._next, 1), self._threads):
            if exc is not None:
                if not self._skip_bad_frames:
                    rerun = _RERUN_REPLACING if self._rerun_replaces else _RERUN
                    raise InputError(f"{exc}; tracking stopped at frame {index} "
                                     f"({self._stopped(index)}); replace the file, or "
                                     f"{rerun}") from None
                log.warning("%s; recorded as lost (unreadable frames are skipped)", exc)
                self._last_image, self._last_index = None, index
                yield index, float(frames.timestamps[index]), None
            else:
                self._last_image, self._last_index = frame.image, frame.index
                yield frame.index, frame.timestamp, frame.image


def _ground_words(plane: Plane) -> str:
    """A plane in its camera as a log line says it: the camera's pitch and roll, its height."""
    pitch, roll = pitch_roll_deg(plane.normal)
    return f"pitch {pitch:.2f} deg, roll {roll:.2f} deg, {plane.distance:.3f} m below the camera"


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
