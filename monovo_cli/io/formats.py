"""Writers and readers of monovo's text files: motion CSV, trajectory CSV, TUM (docs/guide.md "File formats").

:class:`MotionWriter` streams motion.csv rows and flushes each, so an interrupted run keeps
every whole row; the whole-file formats are built as text (``*_text``) for the caller to
write atomically (:mod:`monovo_cli.io.atomic`). Readers raise one-line InputErrors.
"""

from __future__ import annotations

import csv
import io
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import make_pose, matrix_from_quat, quat_from_matrix, so3_exp, so3_log

MOTION_COLUMNS = ("frame", "tx", "ty", "tz", "rx", "ry", "rz", "msd", "iterations", "points",
                  "status")
STD_COLUMNS = ("std_tx", "std_ty", "std_tz", "std_rx", "std_ry", "std_rz")
REASON_COLUMN = "reason"  # last: why a frame is lost or reinit (empty otherwise)
TRAJECTORY_COLUMNS = ("frame", "timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
MAX_FRAME = 2**53  # frame numbers beyond this are not exact in a float (and overflow int64 soon)
MAX_ROTVEC_DEG = 1e6  # larger rotation-vector components are garbage (and overflow so3_exp)


def fmt(x: float) -> str:
    """A float as text: shortest round-trip repr, never 'nan'/'inf' (caller guarantees)."""
    x = float(x)
    if x == 0.0:
        return "0"  # also folds -0.0
    return repr(x)


@dataclass(frozen=True)
class MotionRow:
    """One row of motion.csv: ``T_{k-1}_k`` of frame k, translation m, rotation rad."""

    frame: int
    prev_from_cur: np.ndarray  # 4x4
    msd: float
    iterations: int
    points: int
    status: FrameStatus | str
    std: np.ndarray | None = None  # (6,) std of (tx, ty, tz, rx, ry, rz), m and rad
    reason: str = ""  # why the frame is lost or reinit; one line, no commas or quotes

    def fields(self, with_std: bool, with_reason: bool = False) -> list[str]:
        """The row's motion.csv fields (strings): translation m, rotation vector deg, then the
        std columns (m, deg; empty where not finite) and the reason if asked for."""
        t = self.prev_from_cur[:3, 3]
        r = np.degrees(so3_log(self.prev_from_cur[:3, :3]))
        out = [str(self.frame), *(fmt(v) for v in t), *(fmt(v) for v in r), fmt(self.msd),
               str(int(self.iterations)), str(int(self.points)), self.status]
        if with_std:
            s = self.std if self.std is not None else np.full(6, np.nan)
            s = np.concatenate([s[:3], np.degrees(s[3:])])
            out += [fmt(v) if math.isfinite(v) else "" for v in s]
        if with_reason:
            out.append(re.sub(r'[,"\r\n]+', ";", self.reason))
        return out


class MotionWriter:
    """Streams motion.csv rows to a text stream, header first (unless ``header`` is False:
    a stream that continues a file), flushing every row."""

    def __init__(self, stream: IO[str], *, with_std: bool = True, with_reason: bool = False,
                 header: bool = True) -> None:
        self._stream = stream
        self._with_std = with_std
        self._with_reason = with_reason
        cols = MOTION_COLUMNS + (STD_COLUMNS if with_std else ()) + \
            ((REASON_COLUMN,) if with_reason else ())
        if header:
            self._stream.write(",".join(cols) + "\n")
            self._stream.flush()

    def write(self, row: MotionRow) -> None:
        """One row, flushed."""
        self._stream.write(",".join(row.fields(self._with_std, self._with_reason)) + "\n")
        self._stream.flush()


class CovarianceWriter:
    """Streams each frame's 6x6 covariance of (tx, ty, tz, rx, ry, rz), row-major, in m and
    degrees like every other output: m^2, m deg, deg^2 (so ``sqrt(c33)`` is motion.csv's
    ``std_rx``). :meth:`write` takes it in m and rad, as the estimator gives it.

    Columns ``frame, c00, c01, ..., c55``; empty fields for a lost frame. The header is
    written first unless ``header`` is False (a stream that continues a file).
    """

    def __init__(self, stream: IO[str], *, header: bool = True) -> None:
        self._stream = stream
        cols = ["frame"] + [f"c{i}{j}" for i in range(6) for j in range(6)]
        if header:
            self._stream.write(",".join(cols) + "\n")
            self._stream.flush()

    def write(self, frame: int, cov: np.ndarray) -> None:
        """One row: ``cov`` (6, 6) of (tx, ty, tz, rx, ry, rz) in m and rad."""
        to_deg = np.r_[1.0, 1.0, 1.0, np.full(3, np.degrees(1.0))]
        cov = np.asarray(cov, float) * np.outer(to_deg, to_deg)
        vals = [fmt(v) if math.isfinite(v) else "" for v in cov.ravel()]
        self._stream.write(",".join([str(frame), *vals]) + "\n")
        self._stream.flush()

    def close(self) -> None:
        """Close the stream (the rows are already flushed)."""
        self._stream.close()


IDENTITY_ATOL = 1e-12  # a pose this close to the identity (m, matrix entries) is the identity


def pose_fields(world_from_cam: np.ndarray) -> list[str]:
    """``tx ty tz qx qy qz qw`` (m; qw >= 0) of a 4x4 pose as text. A pose within
    :data:`IDENTITY_ATOL` of the identity is written as the exact identity: what is left
    there is the rounding of the compositions that made it (frame 0's ``T_0_0`` reads
    ``0 0 0 0 0 0 1.0``, not ``-6.66e-17 ...``)."""
    T = np.asarray(world_from_cam, dtype=float)
    if np.all(np.abs(T - np.eye(4)) <= IDENTITY_ATOL):
        T = np.eye(4)
    q = quat_from_matrix(T[:3, :3])
    return [*(fmt(v) for v in T[:3, 3]), *(fmt(v) for v in q)]


def timestamp_format(timestamps: Sequence[float]) -> str:
    """The one fixed-point format (``".3f"``) of a file's timestamp column: the fewest
    decimals, at least 1 and at most 9 (ns), that write every timestamp as it is (so ``0.0``
    beside ``1.0``, ``0.00`` beside ``0.05``; 9 when one needs more)."""
    ts = [float(t) for t in timestamps]
    for d in range(1, 10):
        if all(float(f"{t:.{d}f}") == t for t in ts):
            return f".{d}f"
    return ".9f"


def trajectory_csv_text(frames: Sequence[int], timestamps: Sequence[float],
                        world_from_cam: Sequence[np.ndarray]) -> str:
    """trajectory.csv content: ``T_0_k`` per frame as translation + quaternion (qw >= 0)
    (:func:`pose_fields`), the timestamps (s) in one format (:func:`timestamp_format`)."""
    buf = io.StringIO()
    buf.write(",".join(TRAJECTORY_COLUMNS) + "\n")
    tf = timestamp_format(timestamps)
    for k, ts, T in zip(frames, timestamps, world_from_cam):
        buf.write(",".join([str(k), format(float(ts), tf), *pose_fields(T)]) + "\n")
    return buf.getvalue()


def tum_text(timestamps: Sequence[float], world_from_cam: Sequence[np.ndarray]) -> str:
    """TUM trajectory: ``timestamp tx ty tz qx qy qz qw`` per line, single spaces; poses as
    :func:`pose_fields` writes them, the timestamps (s) in one format
    (:func:`timestamp_format`)."""
    tf = timestamp_format(timestamps)
    return "".join(" ".join([format(float(ts), tf), *pose_fields(T)]) + "\n"
                   for ts, T in zip(timestamps, world_from_cam))


def motion_csv_text(rows: Iterable[MotionRow], *, with_std: bool = False) -> str:
    """motion.csv content of ``rows``, header first, as :class:`MotionWriter` streams it."""
    buf = io.StringIO()
    w = MotionWriter(buf, with_std=with_std)
    for r in rows:
        w.write(r)
    return buf.getvalue()


def floats(fields: Sequence[str], path: Path, lineno: int) -> list[float]:
    """The ``fields`` (strings) of line ``lineno`` of ``path`` as finite floats; InputError
    naming the file and line when one is not a number or not finite."""
    try:
        vals = [float(v) for v in fields]
    except ValueError:
        raise InputError(f"{path}: line {lineno}: expected numbers, got {' '.join(fields)!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"{path}: line {lineno}: non-finite value")
    return vals


def _reason(exc: Exception) -> str:
    """Why a file could not be read, without repeating its name (OSError.strerror)."""
    return getattr(exc, "strerror", None) or str(exc)


def _quat_rotation(q: Sequence[float], path: Path, lineno: int) -> np.ndarray:
    """Rotation matrix of a quaternion read from ``path``, scaled first so that huge
    components cannot overflow the norm (1e200 0 0 1 is a half turn, not the identity)."""
    q = np.asarray(q, dtype=float)
    scale = float(np.max(np.abs(q)))
    if scale == 0.0 or float(np.linalg.norm(q / scale)) * scale < 1e-6:
        raise InputError(f"{path}: line {lineno}: zero quaternion")
    return matrix_from_quat(q / scale)


def read_tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM file: timestamps (N,) and ``world_from_cam`` poses (N, 4, 4)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read TUM file ({_reason(exc)})") from None
    ts, poses = [], []
    for i, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if not ts and line.startswith("frame,"):
            what = ("a trajectory CSV" if line.startswith(",".join(TRAJECTORY_COLUMNS[:2]))
                    else "a motion CSV (relative motions)" if line.startswith(
                        ",".join(MOTION_COLUMNS[:2])) else "a CSV")
            raise InputError(f"{path}: is {what}, not a TUM trajectory; use trajectory.tum "
                             "(the same poses, in TUM format)")
        f = line.replace(",", " ").split()
        if len(f) != 8:
            raise InputError(f"{path}: line {i}: expected 8 numbers "
                             f"(timestamp tx ty tz qx qy qz qw), got {len(f)}")
        v = floats(f, path, i)
        R = _quat_rotation(v[4:8], path, i)
        ts.append(v[0])
        poses.append(make_pose(R, np.array(v[1:4])))
    if not ts:
        raise InputError(f"{path}: no poses in TUM file")
    return np.array(ts), np.array(poses)


def csv_rows(path: Path, what: str, columns: Sequence[str]) -> list[tuple[int, list[str]]]:
    """The non-empty data rows of the CSV file ``path`` as ``(line number, fields)``, after
    a header that must start with ``columns``; each row has at least ``len(columns)`` fields
    (strings, not yet numbers: :func:`floats`). InputError naming the file (and ``what`` it
    should be, e.g. "motion CSV") when it cannot be read, the header differs or a row is
    short."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read {what} ({_reason(exc)})") from None
    n = len(columns)
    if not rows or [c.strip() for c in rows[0][:n]] != list(columns):
        raise InputError(f"{path}: expected a header starting with {','.join(columns)}")
    out = []
    for i, r in enumerate(rows[1:], start=2):
        if not r:
            continue
        if len(r) < n:
            raise InputError(f"{path}: line {i}: expected at least {n} fields, got {len(r)}")
        out.append((i, r))
    return out


def _frame_number(value: float, field: str, path: Path, lineno: int) -> int:
    if value != int(value) or not 0 <= value <= MAX_FRAME:
        raise InputError(f"{path}: line {lineno}: frame must be a whole number >= 0, got {field!r}")
    return int(value)


def read_motion_csv(path: Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Read a motion CSV (the documented columns first): frames (N,), ``prev_from_cur``
    (N, 4, 4) and statuses (N strings; "ok" where the file has no status column)."""
    path = Path(path)
    frames, poses, statuses = [], [], []
    for i, r in csv_rows(path, "motion CSV", MOTION_COLUMNS[:7]):
        v = floats(r[:7], path, i)
        frames.append(_frame_number(v[0], r[0], path, i))
        if max(abs(x) for x in v[4:7]) > MAX_ROTVEC_DEG:
            raise InputError(f"{path}: line {i}: rotation vector ({', '.join(r[4:7])}) is not "
                             "axis times angle in degrees (components beyond 1e6)")
        poses.append(make_pose(so3_exp(np.radians(v[4:7])), np.array(v[1:4])))
        statuses.append(r[10].strip() if len(r) > 10 else FrameStatus.OK)
    return np.array(frames, dtype=int), np.array(poses).reshape(-1, 4, 4), statuses


def read_trajectory_csv(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a trajectory.csv (the documented columns first): frames (N,), timestamps (N,) s and
    ``world_from_cam`` poses (N, 4, 4). Frames must be distinct whole numbers."""
    path = Path(path)
    frames, ts, poses = [], [], []
    for i, r in csv_rows(path, "trajectory CSV", TRAJECTORY_COLUMNS):
        v = floats(r[:9], path, i)
        _frame_number(v[0], r[0], path, i)
        R = _quat_rotation(v[5:9], path, i)
        frames.append(int(v[0]))
        ts.append(v[1])
        poses.append(make_pose(R, np.array(v[2:5])))
    if not frames:
        raise InputError(f"{path}: no poses in trajectory CSV")
    if len(set(frames)) != len(frames):
        dup = next(k for k in frames if frames.count(k) > 1)
        raise InputError(f"{path}: frame {dup} is given more than once")
    return np.array(frames, dtype=int), np.array(ts), np.array(poses)


def read_motion_stats(path: Path) -> dict[int, tuple[str, float]]:
    """``{frame: (status, msd)}`` from a motion.csv (the documented columns first)."""
    path = Path(path)
    out: dict[int, tuple[str, float]] = {}
    for i, r in csv_rows(path, "motion CSV", MOTION_COLUMNS):
        frame, msd = floats([r[0], r[7]], path, i)
        out[_frame_number(frame, r[0], path, i)] = (r[10].strip(), msd)
    return out
