"""Trajectories to evaluate, in the formats other tools write (``monovo eval``).

One reader per format, each giving a :class:`PoseFile`, and :func:`read_pose_file`, which
detects the format from the file's content unless told:

* ``tum`` -- ``timestamp tx ty tz qx qy qz qw`` per line (s, m), monovo's trajectory.tum;
* ``kitti`` -- the KITTI odometry poses: 12 numbers per line, the row-major 3x4
  ``[R | t]`` of ``world_from_cam`` (m), no timestamps (pose i is frame i; a times file,
  KITTI's times.txt, one timestamp in s per line, gives them);
* ``euroc`` -- EuRoC's ground-truth CSV: header ``#timestamp [ns], p_RS_R_x [m], ...,
  q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], ...``, timestamps in ns, quaternion w first,
  columns past the quaternion (velocities, biases) ignored;
* ``trajectory-csv`` -- monovo's trajectory.csv (frame, timestamp, pose);
* ``motion-csv`` -- monovo's motion.csv, its relative motions ``T_{k-1}_k`` composed into
  ``T_0_k`` from the identity at the frame before its first row; its timestamps are taken
  from trajectory.csv beside it when that lists the same frames;
* a monovo output folder -- its trajectory.csv, with motion.csv beside it.

When monovo's motion.csv lies beside the trajectory (a folder, trajectory.csv,
trajectory.tum, motion.csv itself), its relative motions and reported std are attached
(:class:`MotionSteps`). Errors are one line naming the file (and line).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.geometry.lie import make_pose, so3_exp
from monovo_cli.io.formats import (
    MOTION_COLUMNS,
    STD_COLUMNS,
    TRAJECTORY_COLUMNS,
    _quat_rotation,
    _reason,
    floats,
    read_trajectory_csv,
    read_tum,
)

FORMATS = ("tum", "kitti", "euroc", "trajectory-csv", "motion-csv")
FORMAT_NAMES = {"tum": "TUM", "kitti": "KITTI poses", "euroc": "EuRoC CSV",
                "trajectory-csv": "trajectory CSV", "motion-csv": "motion CSV",
                "folder": "monovo output folder"}
EUROC_FIRST = "#timestamp"


@dataclass(frozen=True)
class MotionSteps:
    """monovo's motion.csv rows: ``frames`` (M,) k, ``prev_from_cur`` (M, 4, 4) the motion
    ``T_{k-1}_k`` as tracked (m), ``std`` (M, 6) its reported standard deviation of (tx, ty,
    tz) m and (rx, ry, rz) deg (NaN where the file gives none), ``status`` (M,) strings."""

    frames: np.ndarray
    prev_from_cur: np.ndarray
    std: np.ndarray
    status: tuple[str, ...]


@dataclass(frozen=True)
class PoseFile:
    """A trajectory read from ``path`` in ``format`` (:data:`FORMATS` or "folder").

    ``world_from_cam`` (N, 4, 4) poses (m); ``timestamps`` (N,) s, or None when the file has
    none (KITTI without a times file, motion.csv alone): it is then paired by frame;
    ``frames`` (N,) int the frame numbers (the line's index where the file gives none);
    ``motions`` monovo's relative motions and reported std when motion.csv is at hand.
    """

    path: Path
    format: str
    world_from_cam: np.ndarray
    timestamps: np.ndarray | None
    frames: np.ndarray
    motions: MotionSteps | None = None

    @property
    def name(self) -> str:
        """The format's name in words ("KITTI poses")."""
        return FORMAT_NAMES.get(self.format, self.format)


def _text(path: Path, what: str) -> str:
    try:
        return Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read {what} ({_reason(exc)})") from None


def detect_format(path: Path) -> str:
    """The format (:data:`FORMATS`, or "folder" for a directory) of ``path`` by its content:
    monovo's CSV headers, EuRoC's ``#timestamp`` header, else the count of numbers on the
    first data line (8: TUM, 12: KITTI). InputError when it cannot tell."""
    path = Path(path)
    if path.is_dir():
        return "folder"
    text = _text(path, "trajectory")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise InputError(f"{path}: no poses (empty file)")
    first = lines[0]
    if first.startswith(",".join(TRAJECTORY_COLUMNS[:2])):
        return "trajectory-csv"
    if first.startswith(",".join(MOTION_COLUMNS[:2])):
        return "motion-csv"
    if first.replace(" ", "").startswith(EUROC_FIRST) or "p_RS_R_x" in first:
        return "euroc"
    data = next((ln for ln in lines if not ln.startswith("#")), "")
    n = len(data.replace(",", " ").split())
    if n == 8:
        return "tum"
    if n == 12:
        return "kitti"
    raise InputError(f"{path}: cannot tell its format (first data line has {n} fields: "
                     "TUM has 8, KITTI poses 12; EuRoC and monovo's CSVs have a header); "
                     "name the format")


def read_kitti(path: Path) -> PoseFile:
    """KITTI poses: 12 numbers per line, row-major ``[R | t]`` (3, 4) of ``world_from_cam``;
    no timestamps (frame i is line i, blank lines and ``#`` comments skipped)."""
    path = Path(path)
    poses = []
    for i, line in enumerate(_text(path, "KITTI poses").splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        f = line.split()
        if len(f) != 12:
            raise InputError(f"{path}: line {i}: expected 12 numbers (a row-major 3x4 pose "
                             f"of KITTI poses), got {len(f)}")
        M = np.array(floats(f, path, i)).reshape(3, 4)
        R = M[:, :3]
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-3) or np.linalg.det(R) < 0:
            raise InputError(f"{path}: line {i}: the 3x3 part is not a rotation")
        U, _, Vt = np.linalg.svd(R)
        poses.append(make_pose(U @ Vt, M[:, 3]))
    if not poses:
        raise InputError(f"{path}: no poses in KITTI poses file")
    return PoseFile(path, "kitti", np.array(poses), None, np.arange(len(poses)))


def read_euroc(path: Path) -> PoseFile:
    """EuRoC's CSV: ``timestamp [ns], p x y z [m], q w x y z, ...`` after a ``#`` header;
    timestamps returned in s."""
    path = Path(path)
    ts, poses = [], []
    for i, line in enumerate(_text(path, "EuRoC CSV").splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        f = [x.strip() for x in line.split(",")]
        if len(f) < 8:
            raise InputError(f"{path}: line {i}: expected at least 8 fields (timestamp [ns], "
                             f"p_x, p_y, p_z, q_w, q_x, q_y, q_z), got {len(f)}")
        try:
            ns = int(f[0])
        except ValueError:
            raise InputError(f"{path}: line {i}: expected a timestamp in whole ns, "
                             f"got {f[0]!r}") from None
        v = floats(f[1:8], path, i)
        R = _quat_rotation([v[4], v[5], v[6], v[3]], path, i)  # w x y z -> x y z w
        ts.append(ns // 10**9 + (ns % 10**9) * 1e-9)
        poses.append(make_pose(R, np.array(v[:3])))
    if not poses:
        raise InputError(f"{path}: no poses in EuRoC CSV")
    return PoseFile(path, "euroc", np.array(poses), np.array(ts), np.arange(len(poses)))


def read_tum_file(path: Path) -> PoseFile:
    """A TUM file (:func:`~monovo_cli.io.formats.read_tum`) as a :class:`PoseFile`."""
    ts, poses = read_tum(path)
    return PoseFile(Path(path), "tum", poses, ts, np.arange(len(poses)))


def read_trajectory_file(path: Path) -> PoseFile:
    """monovo's trajectory.csv as a :class:`PoseFile`."""
    frames, ts, poses = read_trajectory_csv(path)
    return PoseFile(Path(path), "trajectory-csv", poses, ts, frames)


def read_motion_steps(path: Path) -> MotionSteps:
    """monovo's motion.csv: its rows' motions, reported std (m, deg) and statuses, in file
    order. Frames must follow one another (k, k+1, ...)."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read motion CSV ({_reason(exc)})") from None
    head = [c.strip() for c in rows[0]] if rows else []
    if head[:7] != list(MOTION_COLUMNS[:7]):
        raise InputError(f"{path}: expected a header starting with {','.join(MOTION_COLUMNS[:7])}")
    std_at = [head.index(c) if c in head else None for c in STD_COLUMNS]
    status_at = head.index("status") if "status" in head else None
    frames, motions, std, status = [], [], [], []
    for i, r in enumerate(rows[1:], start=2):
        if not r:
            continue
        if len(r) < 7:
            raise InputError(f"{path}: line {i}: expected at least 7 fields, got {len(r)}")
        v = floats(r[:7], path, i)
        if v[0] != int(v[0]) or v[0] < 1:
            raise InputError(f"{path}: line {i}: frame must be a whole number >= 1, got {r[0]!r}")
        k = int(v[0])
        if frames and k != frames[-1] + 1:
            raise InputError(f"{path}: line {i}: frame {k} follows frame {frames[-1]}; the "
                             "relative motions compose only when frames follow one another")
        frames.append(k)
        motions.append(make_pose(so3_exp(np.radians(v[4:7])), np.array(v[1:4])))
        s = [r[j].strip() if j is not None and j < len(r) else "" for j in std_at]
        std.append(floats(s, path, i) if all(s) else [np.nan] * 6)
        status.append(r[status_at].strip() if status_at is not None and status_at < len(r)
                      else "ok")
    if not frames:
        raise InputError(f"{path}: no rows in motion CSV")
    return MotionSteps(np.array(frames), np.array(motions), np.array(std, dtype=float),
                       tuple(status))


def _beside_timestamps(path: Path, frames: np.ndarray) -> np.ndarray | None:
    """The timestamps of ``frames`` from trajectory.csv beside ``path``, when it lists them."""
    beside = Path(path).with_name("trajectory.csv")
    if not beside.is_file():
        return None
    tf, ts, _ = read_trajectory_csv(beside)
    at = {int(k): t for k, t in zip(tf, ts)}
    if not all(int(k) in at for k in frames):
        return None
    return np.array([at[int(k)] for k in frames])


def read_motion_file(path: Path) -> PoseFile:
    """monovo's motion.csv composed into ``T_0_k`` (identity at the frame before its first
    row), timestamps from trajectory.csv beside it (None when it is not there)."""
    path = Path(path)
    steps = read_motion_steps(path)
    poses = [np.eye(4)]
    for T in steps.prev_from_cur:
        poses.append(poses[-1] @ T)
    frames = np.r_[steps.frames[0] - 1, steps.frames]
    return PoseFile(path, "motion-csv", np.array(poses), _beside_timestamps(path, frames),
                    frames, steps)


def read_times(path: Path, count: int) -> np.ndarray:
    """A times file (KITTI's times.txt): one timestamp (s) per line, ``count`` of them."""
    path = Path(path)
    ts = [floats(ln.split()[:1], path, i)[0]
          for i, ln in enumerate(_text(path, "times file").splitlines(), start=1)
          if ln.strip() and not ln.lstrip().startswith("#")]
    if len(ts) != count:
        raise InputError(f"{path}: holds {len(ts)} timestamps for {count} poses; expected one "
                         "per pose, in order")
    return np.array(ts)


READERS = {"tum": read_tum_file, "kitti": read_kitti, "euroc": read_euroc,
           "trajectory-csv": read_trajectory_file, "motion-csv": read_motion_file}


def read_pose_file(path: Path, fmt: str | None = None, *, times: Path | None = None) -> PoseFile:
    """The trajectory in ``path`` (a file, or a monovo output folder) in format ``fmt``
    (:data:`FORMATS`; None: :func:`detect_format`); ``times`` a times file replacing its
    timestamps. monovo's motion.csv beside a trajectory is attached (module docstring)."""
    path = Path(path)
    if fmt is not None and fmt not in FORMATS:
        raise ValueError(f"format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    if path.is_dir():
        inner = path / "trajectory.csv"
        if not inner.is_file():
            raise InputError(f"{path}: a folder without trajectory.csv; name the trajectory file")
        pf = replace(read_trajectory_file(inner), path=path, format="folder")
    elif fmt is None and not path.exists():
        raise InputError(f"{path}: cannot read trajectory (No such file or directory)")
    else:
        pf = READERS[fmt or detect_format(path)](path)
    if times is not None:
        pf = replace(pf, timestamps=read_times(times, len(pf.world_from_cam)))
    if pf.motions is None:
        pf = _with_motions(pf)
    return pf


def _with_motions(pf: PoseFile) -> PoseFile:
    """``pf`` with motion.csv's rows attached when it lies beside (for a TUM file, when
    trajectory.csv beside it gives its frames)."""
    folder = pf.path if pf.path.is_dir() else pf.path.parent
    motion = folder / "motion.csv"
    if pf.format not in ("folder", "trajectory-csv", "tum") or not motion.is_file():
        return pf
    if pf.format == "tum":
        beside = folder / "trajectory.csv"
        if not beside.is_file():
            return pf
        tf, ts, _ = read_trajectory_csv(beside)
        if len(ts) != len(pf.timestamps) or not np.allclose(ts, pf.timestamps, atol=1e-6):
            return pf
        pf = replace(pf, frames=tf)
    return replace(pf, motions=read_motion_steps(motion))
