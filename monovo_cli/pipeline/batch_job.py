"""One sequence of a batch: finding sequences, tracking one with its done marker.

The summary table is :mod:`monovo_cli.pipeline.batch_summary`.

Long module: finding sequences, the done marker's fingerprint and the run of one sequence
belong together: the marker records exactly what the run read and wrote.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import socket
import time
import traceback
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import mostly_lost
from monovo_cli.errors import InputError, MonovoError, OutputError
from monovo_cli.io.atomic import digests_recorded
from monovo_cli.version import __version__

FRAMES_SUBDIR = "frames"  # as monovo_cli.io.sources (not imported here: it loads OpenCV)
INIT_FILE = "init.yaml"
DONE_FILE = "done.json"
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
DONE_FORMAT = 3  # 2: options as dataclasses.asdict(JobOptions); 3: inputs by the frames' fingerprint

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class JobOptions:
    """The options of :func:`track_one`: ``track``, the tracking options (the only place
    their defaults are written), and what ``monovo batch`` sets per sequence: ``mask``, one
    PNG for every sequence (an absolute path); ``prior``, a motion CSV's path relative to
    each sequence folder; ``covariance``, a CSV's path relative to each output folder;
    ``skip_bad_frames``, as ``monovo track --skip-bad-frames``; ``topic``, the image topic
    of the sequences that are ROS bags; ``smooth``, the trajectory re-scaled in hindsight;
    ``terrain_out``, the terrain products too; ``threads``, the threads of one sequence's
    run; ``checkpoint_every``, its trajectory files and checkpoint every so many frames
    (None: track's default) -- each as the argument of that name of
    :func:`~monovo_cli.pipeline.track.track_sequence`.

    Travels to the workers as it is (a frozen dataclass pickles); ``done.json`` records it
    as ``dataclasses.asdict``, a JSON-able dict, which :func:`is_complete` compares (see
    :func:`same_job_options`).
    """

    track: TrackOptions = field(default_factory=TrackOptions)
    mask: str | None = None
    prior: str | None = None
    covariance: str | None = None
    skip_bad_frames: bool = False
    topic: str | None = None
    smooth: bool = True
    terrain_out: bool = False
    threads: int = 1
    checkpoint_every: int | None = None


#: JobOptions fields that leave a finished sequence's outputs as they are (the same bytes
#: whatever the threads and checkpoints; a run that finished read every frame it needed):
#: --resume keeps a complete sequence whatever their values.
OUTPUT_NEUTRAL = ("skip_bad_frames", "threads", "checkpoint_every")


def same_job_options(recorded: Any, options: JobOptions) -> bool:
    """Whether ``recorded`` (``done.json``'s ``options``, a dict) is ``options`` in every
    field that shapes the outputs (all but :data:`OUTPUT_NEUTRAL`); a field a done.json
    written before it existed does not hold reads as its default."""
    if not isinstance(recorded, dict):
        return False
    defaults, given = asdict(JobOptions()), asdict(options)
    return all(recorded.get(k, defaults[k]) == given[k] for k in given if k not in OUTPUT_NEUTRAL) \
        and set(recorded) <= set(given)


# --------------------------------------------------------------------------- discovery


def _natural_parts(rel: Path) -> tuple:
    from monovo_cli.io.sources import natural_key

    return tuple(natural_key(p) for p in rel.parts)


def available_cores() -> int:
    """The cores this process may run on: its CPU affinity where the OS has one (a SLURM
    allocation, ``taskset``), else ``os.cpu_count()``."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # macOS, Windows
        return os.cpu_count() or 1


def is_sequence_folder(path: Path) -> bool:
    """True when ``path`` holds a ``frames/`` directory and an ``init.yaml`` file."""
    path = Path(path)
    return (path / FRAMES_SUBDIR).is_dir() and (path / INIT_FILE).is_file()


def _containers(path: Path) -> list[Path]:
    """The videos and ROS bags of a folder holding ``init.yaml`` but no ``frames/``."""
    from monovo_cli.io.sources import list_containers

    return list_containers(path) if (path / INIT_FILE).is_file() else []


def find_sequences(root: Path, *, pattern: str | None = None,
                   exclude: Sequence[Path] = ()) -> list[Path]:
    """The sequences under ``root`` as paths relative to it, in natural order.

    Without ``pattern``: every folder (``root`` itself included) holding ``frames/`` (and
    ``init.yaml``: one without is found too, so that the batch names it and counts it failed,
    see :func:`missing_init_yaml`), and every video (by extension) and ROS bag beside an ``init.yaml`` (in a
    folder without ``frames/``); the search does not descend into a sequence, a bag, hidden
    folders or the folders in ``exclude`` (e.g. the output root when it lies inside ``root``);
    symbolic links to folders are followed (each real folder once). With ``pattern`` (a
    :meth:`pathlib.Path.glob` pattern relative to ``root``, ``**`` allowed): every matching
    directory, video or bag outside ``exclude``, whatever it holds -- ``monovo track``'s rules
    apply to it (a directory of frames with ``init.yaml`` beside them, a folder holding
    ``frames/``, a video or bag with ``init.yaml`` beside it).
    A sequence folder's relative path ``.`` stands for ``root`` itself.

    Raises InputError if ``root`` is not a directory or holds no sequence.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"{root}: {'is not a directory' if root.exists() else 'no such directory'}"
                         " (expected a folder of sequences, each a folder holding "
                         f"{FRAMES_SUBDIR}/ and {INIT_FILE})")
    excluded = {os.path.realpath(p) for p in exclude}
    found: list[Path] = []
    if pattern is not None:
        if Path(pattern).is_absolute():
            raise InputError(f"--glob {pattern!r}: expected a pattern relative to {root}")
        try:
            matches = list(root.glob(pattern))
        except (ValueError, NotImplementedError) as exc:
            raise InputError(f"--glob {pattern!r}: not a usable pattern ({exc})") from None
        from monovo_cli.io.sources import is_container

        for m in matches:
            real = os.path.realpath(m)
            if (m.is_dir() or is_container(m)) and not any(
                    real == e or real.startswith(e + os.sep) for e in excluded):
                found.append(m.relative_to(root))
        what = f"no directory under {root} matches --glob {pattern!r}"
    else:
        seen: set[str] = set()
        for dirpath, dirnames, _ in os.walk(root, followlinks=True):
            real = os.path.realpath(dirpath)
            if real in seen or real in excluded:
                dirnames[:] = []
                continue
            seen.add(real)
            here = Path(dirpath)
            if (here / FRAMES_SUBDIR).is_dir():  # with init.yaml, or without: named, failed
                found.append(here.relative_to(root))
                dirnames[:] = []  # a sequence's subfolders are its own data
                continue
            media = {p.name for p in _containers(here)}  # videos and bags beside init.yaml
            found.extend(here.relative_to(root) / name for name in media)
            dirnames[:] = [d for d in dirnames if not d.startswith(".") and d not in media
                           and d != FRAMES_SUBDIR]
        what = (f"no sequence under {root} (a sequence is a folder holding {FRAMES_SUBDIR}/ and "
                f"{INIT_FILE}, or a video or ROS bag beside an {INIT_FILE}; use --glob PATTERN "
                "for other layouts)")
    if not found:
        raise InputError(what)
    return sorted(set(found), key=_natural_parts)


def missing_init_yaml(seq: Path) -> str | None:
    """Why the sequence folder ``seq`` cannot be tracked when it holds ``frames/`` but no
    ``init.yaml`` (the error of its summary row); None otherwise."""
    seq = Path(seq)
    if seq.is_dir() and (seq / FRAMES_SUBDIR).is_dir() and not (seq / INIT_FILE).is_file():
        return (f"{seq}: holds {FRAMES_SUBDIR}/ but no {INIT_FILE}; write its camera and ground "
                f"into {seq / INIT_FILE} to track it")
    return None


def sequence_name(rel: Path) -> str:
    """The summary's name of a sequence: its path relative to the root, '/'-separated."""
    return Path(rel).as_posix()


# --------------------------------------------------------------------------- one sequence


def checked_job_options(options: JobOptions | None) -> JobOptions:
    """``options``, or the defaults for None.

    Raises TypeError for anything else (a programming error, not bad input).
    """
    if options is None:
        return JobOptions()
    if not isinstance(options, JobOptions):
        raise TypeError(f"options: expected JobOptions or None, got {type(options).__name__}")
    return options


def limit_threads() -> None:
    """OpenCV on one thread (the caller runs one sequence per core). BLAS/OpenMP read their
    thread counts from :data:`THREAD_VARIABLES` when numpy loads: set those in the worker's
    environment before it starts (the Dask nanny sets them to 1 by default)."""
    import cv2

    cv2.setNumThreads(1)


def _sha256(path: Path) -> str:
    from monovo_cli.io.digest import sha256_file

    return sha256_file(path)


def _folder(seq: Path) -> Path:
    """The folder of a sequence: itself, or the one holding a video or bag file."""
    return seq if seq.is_dir() else seq.parent


def _input_fingerprint(seq_dir: Path, prior: str | None,
                       topic: str | None = None) -> tuple[int, str]:
    """(number of frames, SHA-256 over the frames' fingerprint, init.yaml and the prior).

    The frames' fingerprint is the one run.yaml records, less where the sequence lies
    (:meth:`~monovo_cli.io.sources.base.FrameSource.digest`): the names, sizes and
    modification times of the input files, frame 0's file and times.txt, not every frame's
    content -- hashing an archive's images on every resume would cost as much as reading
    them for tracking.
    """
    from monovo_cli.io.sources import find_init_yaml, open_frames

    with open_frames(seq_dir, topic=topic) as frames:
        n_frames = len(frames)
        h = hashlib.sha256(f"frames\0{frames.digest()}\n".encode())
    for extra in (find_init_yaml(Path(seq_dir)), _folder(Path(seq_dir)) / prior if prior else None):
        if extra is not None and Path(extra).is_file():
            h.update(f"{Path(extra).name}\0{_sha256(Path(extra))}\n".encode())
    return n_frames, h.hexdigest()


def result(seq_dir: Path, out_dir: Path, **fields: Any) -> dict[str, Any]:
    """The result dict of one sequence of a batch (the row of ``summary.csv``): every key,
    ``status`` "failed" and the others None or empty unless ``fields`` gives them, and the
    ``worker`` (host:pid) that made it."""
    base = {"sequence": str(seq_dir), "out_dir": str(out_dir), "status": "failed", "frames": None,
            "fps": None, "mean_msd": None, "lost": None, "reanchored": None, "distance_m": None,
            "seconds": None, "error": "", "error_kind": "",
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    base.update(fields)
    return base


class _LogLines(logging.Handler):
    """Keeps the ``monovo_cli`` log records of one sequence as (level, logger, message)."""

    def __init__(self) -> None:
        super().__init__()
        self.lines: list[tuple[int, str, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.levelno, record.name, record.getMessage()))


def track_one(seq_dir: str | Path, out_dir: str | Path, options: JobOptions | None = None, *,
              overwrite: bool = False, single_thread: bool = True) -> dict[str, Any]:
    """Track one sequence into ``out_dir`` as ``monovo track SEQ -o OUT`` does; never raises
    for a bad sequence (see :func:`_track_one`). The result's ``log`` holds the lines the
    run logged (``monovo_cli`` loggers, at their level) as (level, logger name, message),
    for the caller to show: a batch logs them in its own process, above its progress bar."""
    lines = _LogLines()
    logger = logging.getLogger("monovo_cli")
    logger.addHandler(lines)
    try:
        res = _track_one(seq_dir, out_dir, options, overwrite=overwrite,
                         single_thread=single_thread)
    finally:
        logger.removeHandler(lines)
    return {**res, "log": lines.lines}


def _track_one(seq_dir: str | Path, out_dir: str | Path, options: JobOptions | None = None, *,
               overwrite: bool = False, single_thread: bool = True) -> dict[str, Any]:
    """Track one sequence into ``out_dir`` as ``monovo track SEQ -o OUT`` does; never raises
    for a bad sequence.

    ``seq_dir``: a sequence folder (``frames/`` and ``init.yaml``), a directory of frames
    with ``init.yaml`` beside them, or a video or ROS bag with ``init.yaml`` beside it.
    ``options``: :class:`JobOptions` (None: the defaults; anything else raises TypeError).
    ``overwrite``: replace results already in ``out_dir`` (else such a folder is an error).
    ``single_thread``: run OpenCV on one thread (see :func:`limit_threads`).

    Writes motion.csv, trajectory.csv, trajectory.tum and trajectory.png, then, last,
    ``done.json`` (what :func:`is_complete` checks; it records the outcome, see
    :func:`recorded_failure`). Returns a JSON-able dict: ``status`` ``"ok"`` with ``frames``,
    ``fps``, ``mean_msd`` (grey levels^2), ``lost``, ``reanchored``, ``distance_m``,
    ``seconds``; or ``"failed"`` with ``error`` (one line) and ``error_kind``: ``"lost"``
    (tracked to the end, outputs and ``done.json`` written, but more than half of the frames
    lost: the data defeated the tracker), ``"input"`` (a MonovoError: a file to fix) or
    ``"internal"`` (anything else; ``traceback`` holds the details). KeyboardInterrupt and
    other BaseExceptions propagate.
    """
    job = checked_job_options(options)
    seq_dir, out_dir = Path(seq_dir), Path(out_dir)
    t0 = time.perf_counter()
    try:
        if single_thread:
            limit_threads()
        from monovo_cli.pipeline.track import RESULT_FILES, track_sequence

        done = out_dir / DONE_FILE
        if done.exists():
            if not overwrite:
                raise OutputError(f"{out_dir}: already holds results ({DONE_FILE}); use "
                                  "overwrite (--overwrite / --resume) or another output folder")
            done.unlink()
        with digests_recorded() as written:
            run = track_sequence(
                seq_dir, None, out_dir, job.track, overwrite=overwrite,
                skip_bad_frames=job.skip_bad_frames,
                mask=Path(job.mask) if job.mask else None,
                prior=_folder(seq_dir) / job.prior if job.prior else None,
                covariance=out_dir / job.covariance if job.covariance else None, topic=job.topic,
                smooth=job.smooth, terrain_out=job.terrain_out, threads=job.threads,
                **({} if job.checkpoint_every is None else
                   {"checkpoint_every": job.checkpoint_every}))
        n_frames, fingerprint = _input_fingerprint(seq_dir, job.prior, job.topic)
        if run.frames != n_frames:
            raise RuntimeError(f"{seq_dir}: {run.frames} frames tracked, expected {n_frames}")
        names = list(RESULT_FILES) + ([job.covariance] if job.covariance else [])
        files = {n: asdict(written[d]) for n in names if (d := os.path.abspath(out_dir / n)) in written}
        stats = {"frames": run.frames, "fps": run.fps, "mean_msd": run.mean_msd,
                 "lost": run.lost, "reanchored": run.reanchored,
                 "distance_m": run.path_length, "seconds": run.seconds}
        outcome = {"status": "ok", "error": "", "error_kind": ""}
        if run.mostly_lost:  # outputs kept, as monovo track's exit status 3
            outcome = {"status": "failed", "error_kind": "lost",
                       "error": f"{run.lost} of {run.frames - 1} frames lost (more than half)"}
        marker = {"format": DONE_FORMAT, "monovo": __version__, "frames": n_frames,
                  "inputs_sha256": fingerprint, "options": asdict(job), "result": stats,
                  "outcome": outcome, "files": files}
        from monovo_cli.io.atomic import atomic_write_text

        atomic_write_text(done, json.dumps(marker, indent=1, sort_keys=True) + "\n")
        return result(seq_dir, out_dir, **outcome, **stats)
    except MonovoError as exc:
        log.debug("%s failed", seq_dir, exc_info=True)
        return result(seq_dir, out_dir, error=str(exc), error_kind="input",
                      seconds=time.perf_counter() - t0)
    except Exception as exc:
        log.debug("%s failed", seq_dir, exc_info=True)
        return result(seq_dir, out_dir, error=f"internal error: {type(exc).__name__}: {exc}",
                      error_kind="internal", traceback=traceback.format_exc(),
                      seconds=time.perf_counter() - t0)


def is_complete(seq_dir: str | Path, out_dir: str | Path,
                options: JobOptions | None = None) -> tuple[bool, str]:
    """Whether ``out_dir`` holds the finished results of ``seq_dir`` tracked with ``options``.

    Complete means: ``done.json`` (written by :func:`track_one` after every other output)
    is there and readable; it was written for the same options (:class:`JobOptions`, but
    for those that leave the outputs as they are, see :func:`same_job_options`)
    and the same inputs (number of frames; the names, sizes and modification times of the
    frame files, frame 0's file, times.txt, init.yaml and the prior); and every file it
    lists is there with the size and SHA-256 it recorded -- motion.csv with one row per
    frame >= 1, trajectory.csv and .tum with one per frame, as checked before the marker
    was written. Returns ``(complete, reason)``, the reason
    saying what is missing or different.
    """
    seq_dir, out_dir = Path(seq_dir), Path(out_dir)
    job = checked_job_options(options)
    done = out_dir / DONE_FILE
    if not done.is_file():
        return False, f"no {DONE_FILE}"
    try:
        marker = json.loads(done.read_text())
        if marker.get("format") != DONE_FORMAT:
            return False, f"{DONE_FILE} of another format ({marker.get('format')!r})"
        if not same_job_options(marker.get("options"), job):
            return False, "tracked with other options"
        n_frames, fingerprint = _input_fingerprint(seq_dir, job.prior, job.topic)
        if (marker.get("frames"), marker.get("inputs_sha256")) != (n_frames, fingerprint):
            return False, "the sequence's frames, init.yaml, times.txt or prior changed"
        for name, want in marker["files"].items():
            path = out_dir / name
            if not path.is_file():
                return False, f"{name} is missing"
            if path.stat().st_size != want["bytes"] or _sha256(path) != want["sha256"]:
                return False, f"{name} changed since it was written"
        for name in ("motion.csv", "trajectory.csv", "trajectory.tum"):
            if name not in marker["files"]:
                return False, f"{DONE_FILE} does not list {name}"
    except (OSError, ValueError, KeyError, TypeError, AttributeError, MonovoError) as exc:
        return False, f"{DONE_FILE} or the inputs cannot be checked ({type(exc).__name__}: {exc})"
    return True, "complete"


def recorded_failure(out_dir: str | Path) -> str | None:
    """The error ``done.json`` in ``out_dir`` records for a sequence tracked to the end that
    failed (more than half of its frames lost), or None when it records success.

    A ``done.json`` written before outcomes were recorded says it through its figures: a
    failure when more than half of the frames after the first were lost.
    """
    marker = json.loads((Path(out_dir) / DONE_FILE).read_text())
    outcome = marker.get("outcome")
    if outcome is not None:
        return None if outcome["status"] == "ok" else outcome["error"]
    stats = marker["result"]
    lost, frames = stats["lost"], stats["frames"]
    if mostly_lost(lost, frames - 1):
        return f"{lost} of {frames - 1} frames lost (more than half)"
    return None


def done_result(seq_dir: Path, out_dir: Path) -> dict[str, Any]:
    """The result dict of a complete sequence (status ``skipped``), from its ``done.json``."""
    stats = json.loads((Path(out_dir) / DONE_FILE).read_text())["result"]
    return result(seq_dir, out_dir, status="skipped", worker="", **stats)
