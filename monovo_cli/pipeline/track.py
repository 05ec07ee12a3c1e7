"""``monovo init`` and ``monovo track`` on a sequence: read frames, run the tracker, write.

Opening a sequence with its init.yaml, preparing an output folder, building the frame-0
model (:func:`init_model`), and the tracking run (:func:`track_sequence`) that ties the
files to the pure core (:mod:`monovo_cli.core.odometry`). Rows of motion.csv are written
and flushed as frames are done; trajectory.csv / .tum are written atomically at the end,
every ``checkpoint_every`` frames, and when the run is interrupted, so they always hold
exactly the frames done, their poses re-scaled in hindsight over those frames
(:mod:`monovo_cli.mapping.hindsight`; ``TrackOptions.smooth``).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from monovo_cli.geometry.trajectory import path_length
from monovo_cli.mapping.hindsight import Hindsight
from monovo_cli.core.keyframe import Keyframe, build_keyframe
from monovo_cli.core.odometry import FrameResult, track
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.mapping.terrain_map import TerrainMap
from monovo_cli.errors import InputError, OutputError, TrackingError
from monovo_cli.io.atomic import atomic_write_text
from monovo_cli.io.config import InitConfig, check_frame_size, load_init
from monovo_cli.io.formats import CovarianceWriter, MotionRow, MotionWriter, trajectory_csv_text, tum_text
from monovo_cli.io.sources import FrameSource, find_init_yaml, open_frames, resolve_sequence
from monovo_cli.io.model import save_model
from monovo_cli.io.run_record import run_record, write_run_record
from monovo_cli.pipeline.preflight import (
    check_covariance_path,
    existing_results,
    groundtruth_poses,
    model_keyframe,
)
from monovo_cli.pipeline.products import write_terrain, write_trajectory_plot

log = logging.getLogger(__name__)

RESULT_FILES = ("motion.csv", "trajectory.csv", "trajectory.tum", "trajectory.png",
                "terrain.ply", "heightmap.png", "heightmap.csv")


@dataclass(frozen=True)
class TrackSummary:
    frames: int
    mean_msd: float
    seconds: float
    lost: int
    reanchored: int
    distance_m: float
    out_dir: Path | None
    reinit: int = 0

    @property
    def mostly_lost(self) -> bool:
        """More than half of the tracked frames (k >= 1) lost: ``monovo track`` exits 3."""
        return self.lost > 0.5 * max(self.frames - 1, 0)

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def open_sequence(seq: Path, params: Path | None, *,
                  topic: str | None = None) -> tuple[FrameSource, InitConfig]:
    """The frames of ``seq`` and its init.yaml (``params``, or found beside the frames);
    ``topic`` the image topic of a ROS bag."""
    seq_dir = resolve_sequence(Path(seq))
    frames = open_frames(seq_dir, topic=topic)
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
    return frames, cfg


def prepare_out_dir(out_dir: Path, overwrite: bool) -> None:
    """Create ``out_dir`` or refuse one that already holds results (unless ``overwrite``)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputError(f"{out_dir}: exists and is not a directory; give -o a directory")
    if out_dir.is_dir():
        existing = existing_results(out_dir, RESULT_FILES)
        if existing and not overwrite:
            raise OutputError(f"{out_dir}: already holds results ({', '.join(existing)}); "
                              "use --overwrite or another -o")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out_dir}: cannot create output directory ({exc.strerror})") from None
    probe = out_dir / ".monovo_write_test"
    try:
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"{out_dir}: not writable ({exc.strerror})") from None


def init_model(seq: Path, params: Path | None, out: Path, options: TrackOptions, *,
               topic: str | None = None, mask: Path | None = None,
               overwrite: bool = False) -> Keyframe:
    """``monovo init``: build the frame-0 ground model and save it to ``out`` (model.npz),
    with the fingerprints of frame 0, the options and the ``mask`` (a PNG, as for track) it
    was built with. An existing ``out`` is refused unless ``overwrite``."""
    if Path(out).exists() and not overwrite:
        raise OutputError(f"{out}: already exists; use --overwrite or another -o")
    frames, cfg = open_sequence(seq, params, topic=topic)
    usable = _read_mask(Path(mask), cfg) if mask is not None else None
    first = frames.read(0)
    with _naming(first.path):
        key = build_keyframe(0, first.image, cfg.camera, cfg.plane, cfg.region, np.eye(4), options,
                             mask=usable)
    save_model(out, key, cfg.camera, cfg.region, frame0=first.image, options=options, mask=usable)
    return key


@contextlib.contextmanager
def _naming(path: Path) -> Iterator[None]:
    """Prefix a TrackingError (e.g. too few observation points) with the frame it is about."""
    try:
        yield
    except TrackingError as exc:
        raise TrackingError(f"{path}: {exc}") from None


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while a frame is committed to disk and deliver them after,
    so an interruption never separates a motion.csv row from its trajectory entry.

    Only the main thread can set handlers; elsewhere this does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    saved = {}
    try:
        for signum in (signal.SIGINT, signal.SIGTERM):
            saved[signum] = signal.signal(signum, lambda s, _f: caught.append(s))
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
        for signum in dict.fromkeys(caught):
            signal.raise_signal(signum)


def _remove_stale_temporaries(out_dir: Path) -> None:
    """Temporary files a killed run (kill -9) left behind next to the results."""
    for name in RESULT_FILES:
        for tmp in Path(out_dir).glob(f".{name}.*.tmp"):
            tmp.unlink(missing_ok=True)


def track_sequence(seq: Path, params: Path | None, out_dir: Path | None, options: TrackOptions, *,
                   model: Path | None = None, overwrite: bool = False,
                   skip_bad_frames: bool = False, checkpoint_every: int = 100,
                   groundtruth: Path | None = None, mask: Path | None = None,
                   prior: Path | None = None, covariance: Path | None = None,
                   topic: str | None = None, terrain_out: bool = False,
                   progress: Callable[[int, int], None] | None = None) -> TrackSummary:
    """``monovo track``: estimate every frame's motion and write motion.csv, trajectory.csv
    and trajectory.tum (docs/guide.md "File formats").

    With an output directory, ``trajectory.png`` (the path from above, see
    :mod:`monovo_cli.viz.plots`) is written at the end; ``groundtruth`` (a TUM file) is drawn in it.

    ``out_dir`` None streams motion.csv rows to stdout and writes no files.
    A frame after the first that cannot be read stops the run with an InputError (the rows
    done are kept); with ``skip_bad_frames`` it is recorded as ``lost`` at the
    constant-velocity prediction and tracking goes on.
    ``mask`` a PNG of the frame size whose non-zero pixels are never used (rover body, a
    fixed shadow); ``prior`` a motion CSV (motion.csv's columns) whose motions replace the
    constant-velocity guess; ``covariance`` a CSV written row by row with each frame's full
    6x6 covariance of (tx, ty, tz, rx, ry, rz) (m, deg). ``topic`` the image topic of a ROS
    bag. Every side input is checked before anything is written (:mod:`.preflight`).
    ``terrain_out`` (with an output directory): also terrain.ply, heightmap.png and
    heightmap.csv, what tracking learned of the ground (:func:`~monovo_cli.pipeline.products.write_terrain`).
    ``progress(done, total)`` is called after every frame.
    """
    check_covariance_path(covariance, out_dir)
    frames, cfg = open_sequence(seq, params, topic=topic)
    usable = _read_mask(Path(mask), cfg) if mask is not None else None
    priors = _read_prior(Path(prior)) if prior is not None else {}
    gt_poses = groundtruth_poses(Path(groundtruth), frames) if groundtruth is not None else None
    if len(frames) < 2:
        raise InputError(f"{frames.dir}: only {len(frames)} frame; tracking needs at least 2")
    first_key = None
    if model is not None:
        first_key = model_keyframe(Path(model), frames, cfg, options, usable)
    if out_dir is not None:
        prepare_out_dir(out_dir, overwrite)
        for name in RESULT_FILES:  # stale results of an earlier run must not survive
            (Path(out_dir) / name).unlink(missing_ok=True)
        _remove_stale_temporaries(Path(out_dir))
        write_run_record(Path(out_dir), run_record(
            "track", options, {"sequence": Path(seq), "params": cfg.path,
                               "topic": topic, "model": model, "mask": mask, "prior": prior,
                               "covariance": covariance, "groundtruth": groundtruth,
                               "skip_bad_frames": skip_bad_frames, "overwrite": overwrite},
            frames, cfg.path, {"model": model, "mask": mask, "prior": prior,
                               "groundtruth": groundtruth}))
        stream = open(Path(out_dir) / "motion.csv", "w", newline="")
    else:
        stream = sys.stdout
    results: list[tuple[int, float, np.ndarray]] = []
    hindsight = Hindsight() if options.smooth else None

    def final_poses() -> np.ndarray:
        idx, _, poses = zip(*results)
        return hindsight.poses(idx, np.array(poses)) if hindsight else np.array(poses)

    def flush_trajectory() -> None:
        if out_dir is None or not results:
            return
        idx, ts, _ = zip(*results)
        poses = final_poses()
        atomic_write_text(Path(out_dir) / "trajectory.csv", trajectory_csv_text(idx, ts, poses))
        atomic_write_text(Path(out_dir) / "trajectory.tum", tum_text(ts, poses))

    msds, lost, reanchored, reinit = [], 0, 0, 0
    cov_writer = None
    t0 = time.perf_counter()
    try:
        writer = MotionWriter(stream, with_std=True, with_reason=True)
        cov_writer = CovarianceWriter(_open_output(Path(covariance))) if covariance else None
        terrain = TerrainMap(cfg.plane, smooth=options.smooth) \
            if terrain_out and out_dir is not None else None
        images = _LastImage(_read_frames(frames, skip_bad_frames, out_dir), keep=terrain)

        def on_keyframe(key: Keyframe) -> None:
            if hindsight is not None:
                hindsight.add(key.index, key)
            if terrain is not None:
                terrain.add(key, images.last)

        tracked = track(images, cfg.camera, cfg.plane, cfg.region, options, mask=usable,
                        first_keyframe=first_key, priors=priors, on_keyframe=on_keyframe,
                        sigma_distance=cfg.sigma_distance, sigma_deg=cfg.sigma_deg)
        with _naming(frames.paths[0]):  # frame 0 builds the ground model
            first = next(tracked)
        prev = None
        dist, last_lost = 0.0, False
        for res in itertools.chain([first], tracked):
            last_lost = res.status == FrameStatus.LOST
            with _signals_held():
                results.append((res.index, res.timestamp, res.world_from_cam))
                if res.index > 0:
                    writer.write(_row(res))
                    if cov_writer is not None:
                        cov_writer.write(res.index, res.covariance)
                    msds.append(res.msd)
                    lost += res.status == FrameStatus.LOST
                    reanchored += res.status == FrameStatus.REANCHORED
                    reinit += res.status == FrameStatus.REINIT
                    if res.reason:
                        log.info("frame %d %s: %s", res.index, res.status, res.reason)
                    dist += float(np.linalg.norm(res.world_from_cam[:3, 3] - prev[:3, 3]))
                prev = res.world_from_cam
                if checkpoint_every and len(results) % checkpoint_every == 0:
                    flush_trajectory()
            if progress is not None:
                progress(len(results), len(frames))
    finally:
        with _signals_held():
            flush_trajectory()
            if out_dir is not None:
                stream.close()
            if cov_writer is not None:
                cov_writer.close()
    seconds = time.perf_counter() - t0
    if out_dir is not None:
        poses = final_poses()
        # the path of the trajectory written (re-scaled in hindsight), as trajectory.png's
        dist = path_length(poses)
        write_trajectory_plot(Path(out_dir), cfg.plane, [i for i, _, _ in results], poses,
                               gt_poses)
        if terrain is not None:
            terrain.finish(None if last_lost else images.last, results[-1][2])
            if hindsight is not None:
                idx, _, raw = zip(*results)
                terrain.lifts = hindsight.lifts(idx, np.array(raw))
            write_terrain(Path(out_dir), terrain, poses)
    return TrackSummary(len(results), float(np.mean(msds)) if msds else 0.0, seconds, lost,
                        reanchored, dist, Path(out_dir) if out_dir is not None else None, reinit)


class _LastImage:
    """Iterates ``frames`` and, when ``keep`` is set, remembers the last image (``last``)."""

    def __init__(self, frames: Iterator[tuple[int, float, np.ndarray | None]], keep) -> None:
        self._frames, self._keep, self.last = frames, keep is not None, None

    def __iter__(self):
        return self

    def __next__(self) -> tuple[int, float, np.ndarray | None]:
        index, ts, image = next(self._frames)
        if self._keep:
            self.last = image
        return index, ts, image


def _read_frames(frames: FrameSource, skip_bad_frames: bool,
                 out_dir: Path | None) -> Iterator[tuple[int, float, np.ndarray | None]]:
    """``(index, timestamp, image)`` of every frame for :func:`~monovo_cli.core.odometry.track`.

    A frame that cannot be read stops the run with an InputError, or with ``skip_bad_frames``
    (after frame 0) comes as ``image`` None, which the tracker records as lost.
    """
    for index in range(len(frames)):
        try:
            frame = frames.read(index)
        except InputError as exc:
            if index == 0 or not skip_bad_frames:
                kept = (f"the rows of frames 1..{index - 1} went to stdout" if out_dir is None
                        else f"frames 0..{index - 1} are kept in {out_dir}")
                raise InputError(f"{exc}; tracking stopped at frame {index} ({kept}); replace "
                                 "the file, or use --skip-bad-frames to record bad frames as "
                                 "lost and go on") from None
            log.warning("%s; recorded as lost (--skip-bad-frames)", exc)
            yield index, float(frames.timestamps[index]), None
        else:
            yield frame.index, frame.timestamp, frame.image


def _read_mask(path: Path, cfg: InitConfig) -> np.ndarray:
    """--mask PNG -> (H, W) bool of usable pixels (the PNG's non-zero pixels are excluded)."""
    from monovo_cli.io.grey import read_gray

    img = read_gray(path)
    if img.shape != (cfg.camera.height, cfg.camera.width):
        raise InputError(f"{path}: mask is {img.shape[1]}x{img.shape[0]} but frames are "
                         f"{cfg.camera.width}x{cfg.camera.height}")
    usable = img <= 0
    if not usable.any():
        raise InputError(f"{path}: the mask excludes every pixel (non-zero pixels are excluded)")
    return usable


def _read_prior(path: Path) -> dict[int, np.ndarray]:
    """--prior CSV (motion.csv's columns) -> {frame: T_{k-1}_k}."""
    from monovo_cli.io.formats import read_motion_csv

    idx, poses, _ = read_motion_csv(path)
    return {int(k): p for k, p in zip(idx, poses)}


def _open_output(path: Path):
    try:
        return open(path, "w", newline="")
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({exc.strerror})") from None


def _row(res: FrameResult) -> MotionRow:
    return MotionRow(frame=res.index, prev_from_cur=res.prev_from_cur, msd=res.msd,
                     iterations=res.iterations, points=res.points, status=res.status, std=res.std,
                     reason=res.reason)
