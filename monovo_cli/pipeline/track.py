"""``monovo init`` and ``monovo track`` on a sequence: the files around a tracking run.

Preparing an output folder, building the frame-0 model (:func:`init_model`), and the
tracking run (:func:`track_sequence`) that writes what a
:class:`~monovo_cli.pipeline.tracking.Tracking` yields. Rows of motion.csv are written and
flushed as frames are done; trajectory.csv / .tum are written atomically at the end, every
``checkpoint_every`` frames, and when the run is interrupted, so they always hold exactly
the frames done, their poses re-scaled in hindsight over those frames
(:mod:`monovo_cli.mapping.smoothing`) unless ``smooth`` is False.

Every ``checkpoint_every`` frames the run's whole state is saved too
(:mod:`monovo_cli.io.checkpoint`), with the lengths of the streamed CSVs and the fingerprint
of the inputs and options (run.yaml's record); a run continued from it (``resume``) cuts the
CSVs back to those lengths and tracks on from the next frame, so its files are the bytes an
uninterrupted run writes. The checkpoint is removed when the run is finished.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from monovo_cli.core.keyframe import Keyframe, build_keyframe
from monovo_cli.core.odometry import FrameResult
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.run import TrackRun
from monovo_cli.errors import InputError, OutputError
from monovo_cli.io.atomic import DigestingStream, atomic_write_text
from monovo_cli.io.checkpoint import (
    CHECKPOINT_FILE,
    Checkpoint,
    continue_stream,
    read_checkpoint,
    remove_checkpoint,
    write_checkpoint,
)
from monovo_cli.io.formats import CovarianceWriter, MotionRow, MotionWriter, trajectory_csv_text, tum_text
from monovo_cli.io.model import save_model
from monovo_cli.io.run_record import run_record, write_run_record
from monovo_cli.pipeline.preflight import (
    check_covariance_path,
    existing_results,
    groundtruth_poses,
    model_keyframe,
)
from monovo_cli.pipeline.products import sequence_name, write_terrain, write_trajectory_plot
from monovo_cli.pipeline.report import THUMBNAIL_SIDE, THUMBNAILS, write_report
from monovo_cli.pipeline.threads import one_blas_thread
from monovo_cli.pipeline.tracking import (
    Tracking,
    TrackingState,
    naming,
    open_sequence,
    read_mask,
    read_prior,
    state_types,
)

log = logging.getLogger(__name__)

RESULT_FILES = ("motion.csv", "trajectory.csv", "trajectory.tum", "trajectory.png",
                "terrain.ply", "heightmap.png", "heightmap.csv", "report.html")


def prepare_out_dir(out_dir: Path, overwrite: bool) -> None:
    """Create ``out_dir`` or refuse one that already holds results (unless ``overwrite``)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputError(f"{out_dir}: exists and is not a directory; give -o a directory")
    if out_dir.is_dir():
        existing = existing_results(out_dir, RESULT_FILES)
        if existing and not overwrite:
            resumable = "; its run was interrupted: use --resume to continue it, or" if \
                (out_dir / CHECKPOINT_FILE).is_file() else ";"
            raise OutputError(f"{out_dir}: already holds results ({', '.join(existing)})"
                              f"{resumable} use --overwrite or another -o")
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
    opened = open_sequence(seq, params, topic=topic)
    cfg, first = opened.config, opened.first
    usable = read_mask(Path(mask), cfg) if mask is not None else None
    with naming(first.path), one_blas_thread():
        key = build_keyframe(0, first.image, cfg.camera, cfg.plane, cfg.region, np.eye(4), options,
                             mask=usable)
    save_model(out, key, cfg.camera, cfg.region, frame0=first.image, options=options, mask=usable)
    return key


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
    for name in (*RESULT_FILES, CHECKPOINT_FILE):
        for tmp in Path(out_dir).glob(f".{name}.*.tmp"):
            tmp.unlink(missing_ok=True)


def track_sequence(seq: Path, params: Path | None, out_dir: Path | None, options: TrackOptions, *,
                   model: Path | None = None, overwrite: bool = False,
                   skip_bad_frames: bool = False, checkpoint_every: int = 100,
                   groundtruth: Path | None = None, mask: Path | None = None,
                   prior: Path | None = None, covariance: Path | None = None,
                   topic: str | None = None, terrain_out: bool = False, smooth: bool = True,
                   report: bool = True, resume: bool = False, threads: int | None = None,
                   progress: Callable[[int, int], None] | None = None,
                   resumed: Callable[[int, int], None] | None = None) -> TrackRun | None:
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
    ``smooth`` False writes the trajectory as estimated, not re-scaled in hindsight.
    ``report`` (with an output directory): also report.html, the run on one self-contained
    page (:func:`~monovo_cli.pipeline.report.write_report`).
    ``checkpoint_every`` (with an output directory): every so many frames the trajectory
    files and the checkpoint are written (0: the trajectory at the end only, no
    checkpoint). ``resume`` (with an output directory): continue the run interrupted there
    from its checkpoint, or from frame 0 when it has none; an InputError when the
    checkpoint was taken with other inputs or options; ``resumed(frame, total)`` is then
    called once before tracking, with the frame the run continues at (0: there was no
    checkpoint) and the number of frames. ``progress(done, total)`` is called after every
    frame. Returns the run (:class:`~monovo_cli.core.run.TrackRun`), or None
    when ``resume`` finds the run in ``out_dir`` finished (nothing to do). ``threads``: OpenCV's
    threads while tracking, and from 2 on, frames are decoded on a thread of their own ahead of
    the tracker (:mod:`monovo_cli.pipeline.read_ahead`); None: all cores.
    """
    check_covariance_path(covariance, out_dir)
    if resume and out_dir is None:
        raise InputError("resuming a run needs the output directory it was writing, not stdout")
    opened = open_sequence(seq, params, topic=topic)
    frames, cfg = opened.frames, opened.config
    usable = read_mask(Path(mask), cfg) if mask is not None else None
    priors = read_prior(Path(prior)) if prior is not None else {}
    gt_poses = groundtruth_poses(Path(groundtruth), frames) if groundtruth is not None else None
    if len(frames) < 2:
        raise InputError(f"{frames.dir}: only {len(frames)} frame; tracking needs at least 2")
    first_key = None
    if model is not None:
        first_key = model_keyframe(Path(model), opened, options, usable)
    saved: Checkpoint | None = None
    fingerprint: dict = {}
    if out_dir is not None:
        record = run_record(
            "track", options, {"sequence": Path(seq), "params": cfg.path,
                               "topic": topic, "model": model, "mask": mask, "prior": prior,
                               "covariance": covariance, "groundtruth": groundtruth,
                               "skip_bad_frames": skip_bad_frames, "overwrite": overwrite,
                               "smooth": smooth},
            frames, cfg.path, {"model": model, "mask": mask, "prior": prior,
                               "groundtruth": groundtruth})
        record["ground"] = {"init_yaml": cfg.convention}
        fingerprint = _fingerprint(record)
        if resume:
            saved = _resume_point(Path(out_dir), fingerprint)
            if saved is None and (Path(out_dir) / "trajectory.png").is_file():
                log.info("%s: the run there is finished; nothing to resume", out_dir)
                return None
        prepare_out_dir(out_dir, overwrite or resume)
        _remove_stale_temporaries(Path(out_dir))
        motion = Path(out_dir) / "motion.csv"
        if saved is None:
            for name in RESULT_FILES:  # stale results of an earlier run must not survive
                (Path(out_dir) / name).unlink(missing_ok=True)
            remove_checkpoint(Path(out_dir))
            write_run_record(Path(out_dir), record)
            stream = DigestingStream(open(motion, "w", newline="", encoding="utf-8"), motion)
        else:
            log.info("%s: continuing the run from frame %d", out_dir, saved.next_frame)
            stream = continue_stream(motion, saved.motion_bytes)
        if resume and resumed is not None:
            resumed(saved.next_frame if saved is not None else 0, len(frames))
    else:
        stream = sys.stdout

    def stopped(index: int) -> str:
        return (f"the rows of frames 1..{index - 1} went to stdout" if out_dir is None
                else f"frames 0..{index - 1} are kept in {out_dir}")

    tracking = Tracking(opened, options, mask=usable, priors=priors, first_keyframe=first_key,
                        skip_bad_frames=skip_bad_frames, smooth=smooth,
                        terrain=terrain_out and out_dir is not None, stopped=stopped,
                        thumbnails=THUMBNAILS if report and out_dir is not None else 0,
                        thumbnail_side=THUMBNAIL_SIDE,
                        rerun_replaces=out_dir is not None,
                        threads=(os.cpu_count() or 1) if threads is None else threads)

    if saved is not None:
        tracking.restore(saved.state)

    def write_trajectory(poses: np.ndarray) -> None:
        if out_dir is None or not len(poses):
            return
        index, times = tracking.frames_recorded()
        atomic_write_text(Path(out_dir) / "trajectory.csv", trajectory_csv_text(index, times, poses))
        atomic_write_text(Path(out_dir) / "trajectory.tum", tum_text(times, poses))

    def write_checkpoint_now() -> None:
        stream.sync()  # the rows the checkpoint counts are on the disk before it
        if cov_stream is not None:
            cov_stream.sync()
        write_checkpoint(Path(out_dir), Checkpoint(
            tracking.done, fingerprint, tracking.state(), stream.size,
            cov_stream.size if cov_stream is not None else None,
            time.perf_counter() - t0), types)

    run: TrackRun | None = None
    types = state_types()
    cov_writer = cov_stream = None
    t0 = time.perf_counter() - (saved.seconds if saved is not None else 0.0)
    try:
        writer = MotionWriter(stream, with_std=True, with_reason=True, header=saved is None)
        if covariance and saved is not None:
            if saved.covariance_bytes is None:
                raise InputError(f"{out_dir}: the checkpoint holds no covariance rows; start "
                                 "the run afresh: allow overwriting or choose another output")
            cov_stream = continue_stream(Path(covariance), saved.covariance_bytes)
        elif covariance:
            cov_stream = _open_output(Path(covariance))
        cov_writer = CovarianceWriter(cov_stream, header=saved is None) if cov_stream else None
        if saved is not None:  # the trajectory of the frames kept (a later one may be there)
            write_trajectory(tracking.trajectory())
        for res in tracking.results(record=False):
            with _signals_held():
                tracking.record(res)
                if res.index > 0:
                    writer.write(_row(res))
                    if cov_writer is not None:
                        cov_writer.write(res.index, res.covariance)
                    if res.reason:
                        log.info("frame %d %s: %s", res.index, res.status, res.reason)
                if checkpoint_every and tracking.done % checkpoint_every == 0 and \
                        tracking.done < len(frames):  # (after the last frame: the end's files)
                    write_trajectory(tracking.trajectory())
                    if out_dir is not None:
                        write_checkpoint_now()
            if progress is not None:
                progress(tracking.done, len(frames))
        run = tracking.result(time.perf_counter() - t0)
        log.info("tracked %d frames in %.2f s (%.1f frames/s)", run.frames, run.seconds,
                 run.fps)
    finally:
        with _signals_held():
            write_trajectory(run.trajectory if run is not None else tracking.trajectory())
            if out_dir is not None:
                stream.close()
            if cov_writer is not None:
                cov_writer.close()
    if out_dir is not None:
        if tracking.initial_tilt is not None:  # what the images said of init.yaml's tilt
            record["ground"]["images_tilt"] = _tilt_record(tracking.initial_tilt)
            write_run_record(Path(out_dir), record)
        t1 = time.perf_counter()
        name = sequence_name(frames.dir)
        path_image = write_trajectory_plot(Path(out_dir), cfg.plane, run, gt_poses, name)
        heights = None
        if tracking.terrain is not None:
            heights = write_terrain(Path(out_dir), tracking.terrain, run.trajectory, tracking.drive,
                                    name)
        log.info("trajectory.png%s written in %.2f s", " and the terrain products"
                 if tracking.terrain is not None else "", time.perf_counter() - t1)
        if report:
            t1 = time.perf_counter()
            write_report(Path(out_dir), run, cfg, record, title=name,
                         trajectory_image=path_image, heightmap_image=heights,
                         thumbnails=tracking.thumbnails, groundtruth=groundtruth)
            log.info("report.html written in %.2f s", time.perf_counter() - t1)
        remove_checkpoint(Path(out_dir))  # finished: nothing to resume
    return run


def _tilt_record(tilt) -> dict:
    """run.yaml's ``ground.images_tilt``: the tilt the first frames measured against
    init.yaml's (deg, in its chart), its std, and what was done with it."""
    return {"frame": tilt.frame, "measured_deg": [round(v, 4) for v in tilt.measured_deg],
            "std_deg": [round(v, 4) for v in tilt.std_deg], "chi2": round(tilt.chi2, 2),
            "contradicts_init_yaml": tilt.contradicts, "corrected": tilt.adopted}


def _fingerprint(record: dict) -> dict:
    """What a checkpoint must have been taken with to be continued: run.yaml's ``record``
    less when the run started and whether it could replace earlier results."""
    options = {k: v for k, v in record["options"].items() if k != "overwrite"}
    return {"monovo": record["monovo"], "command": record["command"], "options": options,
            "inputs": record["inputs"]}


def _resume_point(out_dir: Path, fingerprint: dict) -> Checkpoint | None:
    """``out_dir``'s checkpoint if it was taken with ``fingerprint`` (None: there is none);
    an InputError naming the first setting or input that differs otherwise."""
    saved = read_checkpoint(out_dir, state_types(), TrackingState)
    if saved is not None and saved.fingerprint != fingerprint:
        what = _first_difference(saved.fingerprint, fingerprint) or "the record"
        raise InputError(f"{out_dir}: its run was made with other inputs or options ({what} "
                         "differs); continue it with the same ones, or start afresh: allow "
                         "overwriting or choose another output")
    return saved


def _first_difference(a: object, b: object, where: str = "") -> str:
    """The dotted key of the first value that differs between ``a`` and ``b`` ('' if none)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b), key=str):
            found = _first_difference(a.get(key), b.get(key), f"{where}.{key}" if where else str(key))
            if found:
                return found
        return ""
    return "" if a == b else where


def _open_output(path: Path) -> DigestingStream:
    try:
        return DigestingStream(open(path, "w", newline="", encoding="utf-8"), path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({exc.strerror})") from None


def _row(res: FrameResult) -> MotionRow:
    return MotionRow(frame=res.index, prev_from_cur=res.prev_from_cur, msd=res.msd,
                     iterations=res.iterations, points=res.points, status=res.status, std=res.std,
                     reason=res.reason)
