"""One tracking run's result in memory: what every frame and keyframe left.

:class:`RunRecorder` collects the numbers of each frame's :class:`~monovo_cli.core.odometry.FrameResult`
and every keyframe anchored as the tracking loop yields them; :meth:`RunRecorder.result`
freezes them into a :class:`TrackRun`, the one value that the products, the plots, the
evaluation and batch's summary read (no layer reads back a file the run wrote).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.core.status import FrameStatus, mostly_lost
from monovo_cli.geometry.plane import Plane
from monovo_cli.geometry.trajectory import path_length


@dataclass(frozen=True)
class KeyRecord:
    """What a keyframe leaves for the work after the run, without its images and points.

    ``index`` the frame it was anchored on; ``world_from_key`` (4, 4) its pose T_0_key;
    ``plane`` its ground in its own camera frame; ``link`` how that plane was fused with the
    previous keyframe's (None for the first keyframe and after a re-initialisation);
    ``samples`` (m, 3) about SAMPLES of its finest observation points, in its camera, where
    they lie on its plane (where its images hold the motions;
    :func:`~monovo_cli.mapping.smoothing.reread_motions`); None where they were lifted off
    it by a terrain grid (solved with the images, they keep their place when the plane's
    tilt moves in hindsight).
    """

    index: int
    world_from_key: np.ndarray
    plane: Plane
    link: PlaneLink | None
    samples: np.ndarray | None = None

    @classmethod
    def of(cls, key: Keyframe) -> KeyRecord:
        return cls(int(key.index), np.array(key.world_from_key), key.plane, key.link,
                   key_samples(key))


SAMPLES = 32  # observation points a keyframe's record keeps


def key_samples(key: Keyframe, count: int = SAMPLES) -> np.ndarray | None:
    """(<= count, 3): every k-th of ``key``'s finest observation points (finite ones), in
    its camera; None where a terrain grid lifted them off its plane."""
    levels = getattr(key, "levels", None)  # (None: a stand-in without points)
    if not levels or getattr(key, "terrain_grid", None) is not None:
        return None
    return subsample(levels[0].points.X, count)


def subsample(X: np.ndarray, count: int = SAMPLES) -> np.ndarray:
    """(<= count, 3): every k-th of the points ``X`` (N, 3), finite ones."""
    X = X[::max(1, -(-len(X) // count))]
    return np.array(X[np.all(np.isfinite(X), axis=1)], dtype=float)


@dataclass(frozen=True, eq=False)
class TrackRun:
    """A tracking run over N frames, frame 0 first (docs/guide.md "File formats").

    Per frame: ``index`` (N,) int; ``timestamp`` (N,) s; ``world_from_cam`` (N, 4, 4) T_0_k as
    estimated frame by frame (motion.csv's poses, causal); ``prev_from_cur`` (N, 4, 4)
    T_{k-1}_k (the identity for frame 0); ``status`` (N,) :class:`FrameStatus`; ``reason``
    (N,) why a frame was not ``ok`` ("" otherwise); ``msd`` (N,) grey levels^2;
    ``iterations`` (N,); ``points`` (N,); ``std`` (N, 6) of (tx, ty, tz) m and (rx, ry, rz)
    rad of ``prev_from_cur`` (NaN where none); ``covariance`` (N, 6, 6) the same as a matrix.
    ``keyframes``: every keyframe anchored, oldest first (a keyframe rebuilt in place
    replaces its earlier record). ``gaps``: ``(frame index, GapClosure)`` of every frame
    that closed a run of lost frames by measuring its pose directly
    (:mod:`monovo_cli.core.recovery.gap`). ``trajectory`` (N, 4, 4): the poses written to
    trajectory.csv / .tum, ``world_from_cam`` with the gaps' corrections spread over their
    lost frames (:mod:`monovo_cli.mapping.gaps`) and re-scaled in hindsight
    (:mod:`monovo_cli.mapping.smoothing`), or ``world_from_cam`` itself. ``seconds``: the
    wall-clock time of the run.
    """

    index: np.ndarray
    timestamp: np.ndarray
    world_from_cam: np.ndarray
    prev_from_cur: np.ndarray
    status: tuple[FrameStatus, ...]
    reason: tuple[str, ...]
    msd: np.ndarray
    iterations: np.ndarray
    points: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    keyframes: tuple[KeyRecord, ...]
    trajectory: np.ndarray
    seconds: float = 0.0
    gaps: tuple[tuple[int, GapClosure], ...] = ()

    @property
    def frames(self) -> int:
        """N, frame 0 included."""
        return len(self.index)

    def count(self, status: FrameStatus) -> int:
        """How many frames after frame 0 have ``status``."""
        return sum(s == status for s in self.status[1:])

    @property
    def lost(self) -> int:
        return self.count(FrameStatus.LOST)

    @property
    def reanchored(self) -> int:
        return self.count(FrameStatus.REANCHORED)

    @property
    def reinit(self) -> int:
        return self.count(FrameStatus.REINIT)

    @property
    def mostly_lost(self) -> bool:
        """More than half of the tracked frames (k >= 1) lost (``monovo track`` exits 3)."""
        return mostly_lost(self.lost, self.frames - 1)

    @property
    def mean_msd(self) -> float:
        """The mean of the frames' msd after frame 0 (grey levels^2; 0 with none)."""
        return float(np.mean(self.msd[1:])) if self.frames > 1 else 0.0

    @property
    def path_length(self) -> float:
        """The length (m) of the camera path through ``trajectory``."""
        return path_length(self.trajectory)

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


#: The numeric columns a :class:`RunRecorder` keeps per frame: (dtype, shape of one row).
_COLUMNS = {
    "index": (np.int64, ()),
    "timestamp": (np.float64, ()),
    "world_from_cam": (np.float64, (4, 4)),
    "prev_from_cur": (np.float64, (4, 4)),
    "msd": (np.float64, ()),
    "iterations": (np.int64, ()),
    "points": (np.int64, ()),
    "std": (np.float64, (6,)),
    "covariance": (np.float64, (6, 6)),
}
_BLOCK = 512  # frames per block of columns (0.33 MB)


class RunRecorder:
    """Collects a run as the tracking loop yields it: :meth:`add` every frame's result in
    order, :meth:`add_keyframe` every keyframe anchored or rebuilt in place.

    A frame's numbers go into columns allocated a block of frames at a time, not a kept
    object per frame: about 0.65 kB a frame, so a run's memory barely grows with its length
    and a checkpoint holds a few arrays.
    """

    def __init__(self) -> None:
        self._n = 0
        self._blocks: list[dict[str, np.ndarray]] = []
        self._status: list[FrameStatus] = []
        self._reason: list[str] = []
        self._gaps: list[tuple[int, GapClosure]] = []
        self._keys: dict[int, KeyRecord] = {}

    def __len__(self) -> int:
        return self._n

    def add(self, res) -> None:
        """``res``: a :class:`~monovo_cli.core.odometry.FrameResult`."""
        n = self._n % _BLOCK
        if n == 0:
            self._blocks.append({name: np.zeros((_BLOCK,) + shape, dtype)
                                 for name, (dtype, shape) in _COLUMNS.items()})
        for name, col in self._blocks[-1].items():
            col[n] = getattr(res, name)
        self._status.append(FrameStatus(res.status))
        self._reason.append(res.reason)
        if getattr(res, "gap", None) is not None:
            self._gaps.append((res.index, res.gap))
        self._n += 1

    def add_keyframe(self, key: Keyframe) -> None:
        self._keys[int(key.index)] = KeyRecord.of(key)

    def _column(self, name: str) -> np.ndarray:
        dtype, shape = _COLUMNS[name]
        if not self._blocks:
            return np.empty((0,) + shape, dtype)
        return np.concatenate([b[name] for b in self._blocks])[:self._n]

    @property
    def index(self) -> list[int]:
        return self._column("index").tolist()

    @property
    def timestamp(self) -> list[float]:
        return self._column("timestamp").tolist()

    @property
    def world_from_cam(self) -> np.ndarray:
        """(n, 4, 4) the poses of the frames added so far."""
        return self._column("world_from_cam")

    @property
    def keyframes(self) -> tuple[KeyRecord, ...]:
        return tuple(self._keys[k] for k in sorted(self._keys))

    @property
    def gaps(self) -> tuple[tuple[int, GapClosure], ...]:
        """``(frame index, GapClosure)`` of the frames added that closed lost ones."""
        return tuple(self._gaps)

    @property
    def last_status(self) -> FrameStatus | None:
        return self._status[-1] if self._status else None

    def result(self, trajectory: np.ndarray | None = None, seconds: float = 0.0) -> TrackRun:
        """The :class:`TrackRun` of the frames added; ``trajectory`` (n, 4, 4) the poses to
        write (None: the poses as estimated)."""
        W = self.world_from_cam
        return TrackRun(
            index=self._column("index"),
            timestamp=self._column("timestamp"),
            world_from_cam=W,
            prev_from_cur=self._column("prev_from_cur"),
            status=tuple(self._status),
            reason=tuple(self._reason),
            msd=self._column("msd"),
            iterations=self._column("iterations"),
            points=self._column("points"),
            std=self._column("std"),
            covariance=self._column("covariance"),
            keyframes=self.keyframes,
            trajectory=W if trajectory is None else np.asarray(trajectory, dtype=float),
            seconds=float(seconds), gaps=self.gaps)
