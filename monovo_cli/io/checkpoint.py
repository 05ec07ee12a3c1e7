"""The checkpoint of a ``monovo track`` run: what an interrupted run needs to continue.

``OUT/.track-checkpoint.npz`` (written atomically, :mod:`monovo_cli.io.atomic`) holds a
:class:`Checkpoint`: the tracking state after a frame (the caller's object), the length of
motion.csv (and of the covariance CSV) at that frame, and the fingerprint of the inputs and
options that produced it. A run that continues from it truncates the streamed CSVs to
those lengths (:func:`continue_stream`) and appends to them.

The file is data only: an uncompressed ``.npz`` whose member ``checkpoint`` is a JSON text
(UTF-8, uint8) with the format, the monovo version, a table of the other members (each
array's dtype, shape and CRC-32 as zip stored it) and the checkpoint's object graph as a
tree (:mod:`monovo_cli.io.state_codec`); every other member is one array of that graph.
Reading it (``np.load(..., allow_pickle=False)``) runs no code from the file: it creates
only the classes of :func:`state_types` and checks, before anything is used, the format and
version, that the members are exactly the table's, each array's dtype (one of
:data:`~monovo_cli.io.state_codec.DTYPES`), shape and checksum against the table, each
class's fields, and the shapes declared for the fields below. A file that fails any of them
is an InputError.

``.track-checkpoint.pkl``, the pickle that monovo wrote before, is never opened: its
presence is an InputError telling to start the run afresh.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, KeyLevel
from monovo_cli.core.estimator.ground import LevelPoints
from monovo_cli.core.estimator.terrain_grid import TerrainGrid
from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.odometry import GoodFrame, Odometry, OdometryState
from monovo_cli.core.options import EstimatorOptions, FeatureOptions, TrackOptions
from monovo_cli.core.plane.belief import PlaneBelief, PlaneLink
from monovo_cli.core.plane.motion_covariance import MotionCovariance, PlaneCovarianceCalibration
from monovo_cli.core.plane.tracker import InitialTilt, PlaneTracker
from monovo_cli.core.recovery.features import FeatureMotion
from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.core.recovery.lost_frames import ChainedHypothesis, LostFrameRecovery, TrustedFrame
from monovo_cli.core.run import KeyRecord, RunRecorder
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import InputError, OutputError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.io.atomic import DigestingStream, atomic_write_with
from monovo_cli.io.state_codec import DTYPES, ArraySpec, CodecError, Registry, decode, encode
from monovo_cli.mapping.terrain_map import TerrainMap, _Chunk
from monovo_cli.version import __version__

CHECKPOINT_FILE = ".track-checkpoint.npz"
OLD_CHECKPOINT_FILE = ".track-checkpoint.pkl"  # (a pickle: monovo before format 6; never read)
FORMAT = "monovo-checkpoint-6"  # 6: data only, an .npz of the arrays and a JSON record, no
#                                  pickle (5: keyframe records keep sample points, the tracker
#                                  the model error it hands to the next row; 3, 4: the plane
#                                  tracker keeps the ground seen, and whether frame 0's tilt
#                                  was contradicted later; 2: the recorder keeps columns, not a
#                                  row object per frame)
_START_AFRESH = "start the run afresh: allow overwriting or choose another output"
_RECORD = "checkpoint"  # the record's member (model.npz has a "record" of its own)
_NPY_HEADER_MAX = 1 << 16  # (bytes before an array's data in its member, at most)


@dataclass(frozen=True)
class Checkpoint:
    """A run's state after frame ``next_frame - 1``.

    ``fingerprint`` a plain dict of the inputs and options (compared, never interpreted);
    ``state`` whatever the tracking run needs to continue (of the classes of
    :func:`state_types`); ``motion_bytes`` and ``covariance_bytes`` the lengths (bytes) of
    motion.csv and of the covariance CSV (None: none written) after that frame's row;
    ``seconds`` the run's wall-clock time so far.
    """

    next_frame: int
    fingerprint: dict[str, Any]
    state: Any
    motion_bytes: int
    covariance_bytes: int | None = None
    seconds: float = 0.0


def _f(*shape: int | None, optional: bool = False) -> ArraySpec:
    """float64 of ``shape`` (None: any length)."""
    return ArraySpec("<f8", tuple(shape), optional)


def _f4(*shape: int | None, optional: bool = False) -> ArraySpec:
    """float32 (images, observation rows, intensities, gradients)."""
    return ArraySpec("<f4", tuple(shape), optional)


_POSE = _f(4, 4)
_IMAGE = _f4(None, None, optional=True)
_MASK = ArraySpec("|b1", (None, None), optional=True)

#: The attributes of the plain (not dataclass) classes of the tracking state, exactly.
_ODOMETRY = (
    "camera", "region", "options", "mask", "_plane0", "_plane", "_key", "_world_from_prev",
    "_cur_from_key_prev", "_motion_cov", "_velocity", "_state", "_gain", "_bias",
    "_recent_msd", "_sigma", "_chance_msd", "_prev_image", "_key_image", "rebuilt_keyframes",
    "_recovery", "_key_msd", "_lost_run", "_unmeasured", "_motion_changes", "_last_motion", "_last_std",
    "_last_accepted", "_gap_variance", "_gap_steps", "_handed_over", "_good", "_started",
    "_announced")
_PLANE_TRACKER = (
    "sigmas", "latent_mount", "_reference", "mounting", "covariance", "keep_initial_tilt",
    "initial_tilt", "_tilt_checks", "_model_variance", "_disputed_tilt", "_unconfirmed_tilt",
    "_contradicted_later", "_spread_tilt", "consistency", "_report_distance",
    "_next_report_distance", "_mount_tilt")


def state_types() -> Registry:
    """The classes a checkpoint may hold, with what their array fields hold: the tracker's
    (:class:`~monovo_cli.core.odometry.Odometry` and all it keeps), the run's recorder and
    terrain map, and :class:`Checkpoint`. A caller whose state is of a class of its own
    adds it (:meth:`~monovo_cli.io.state_codec.Registry.add`)."""
    types = Registry()
    types.add(Checkpoint)
    types.add_enum(FrameStatus)
    types.add_enum(OdometryState)
    # the options (the fingerprint holds them too) and the geometry
    for cls in (TrackOptions, EstimatorOptions, FeatureOptions, PinholeCamera, InitialTilt):
        types.add(cls)
    types.add(Plane, arrays={"normal": _f(3)})
    # the tracker
    types.add(Odometry, _ODOMETRY, arrays={
        "mask": _MASK, "_world_from_prev": _POSE, "_cur_from_key_prev": _POSE,
        "_velocity": _POSE, "_prev_image": _IMAGE, "_key_image": _IMAGE,
        "_last_motion": _f(6, optional=True), "_last_std": _f(6), "_gap_variance": _f(6),
        "_handed_over": _f(6, 6, optional=True)})
    types.add(GoodFrame, arrays={"image": _f4(None, None), "world_from_cur": _POSE,
                                 "cur_from_key": _POSE})
    types.add(Keyframe, arrays={"world_from_key": _POSE, "corners": _f(4, 3),
                               "periods": _f(None, 3, optional=True)})
    types.add(KeyLevel, arrays={"Jt": _f4(8, None), "probes": _f(None, 3),
                                "grid": _f4(None, None, 2), "plane_m": _f(3),
                                "box_rays": _f(None, 3)})
    types.add(LevelPoints, arrays={"uv": _f(None, 2), "X": _f(None, 3), "intensity": _f4(None),
                                   "grad": _f4(None, 2), "corners": _f(4, 3)})
    types.add(TerrainGrid, arrays={"h": _f(None, None)})
    types.add(Estimate, arrays={
        "cur_from_key": _POSE, "covariance": _f(6, 6), "residuals": _f4(None, optional=True),
        "valid": ArraySpec("|b1", (None,), optional=True), "weights": _f4(None, optional=True),
        "normal": _f(None, None, optional=True)})
    types.add(MotionCovariance, ("_cov_prev", "_sens_prev", "_sample", "_sens_of", "_noise_of"),
              arrays={"_cov_prev": _f(6, 6), "_sens_prev": _f(6, 3)})
    types.add(PlaneTracker, _PLANE_TRACKER, arrays={
        "covariance": _f(3, 3), "_disputed_tilt": _f(2, 2, optional=True),
        "_unconfirmed_tilt": _f(2, 2, optional=True), "_spread_tilt": _f(2, 2, optional=True)})
    types.add(PlaneCovarianceCalibration,
              ("_distance_nis", "_distance_offsets", "_tilt_excess", "_seen_excess",
               "_calibration"))
    types.add(PlaneBelief, arrays={"information": _f(3, 3), "vector": _f(3, optional=True)})
    types.add(PlaneLink, arrays={"gain": _f(3, 3), "innovation": _f(3)})
    types.add(LostFrameRecovery, ("camera", "mask", "region", "options", "reference", "current"),
              arrays={"mask": _MASK})
    types.add(TrustedFrame, arrays={"image": _f4(None, None), "from_key": _POSE})
    types.add(ChainedHypothesis, arrays={"image": _f4(None, None), "cur_from_key": _POSE,
                                         "ref_from_key": _POSE})
    types.add(FeatureMotion, arrays={"cur_from_key": _POSE, "homography": _f(3, 3),
                                     "key_rays": _f(None, 3), "cur_rays": _f(None, 3)})
    types.add(GapClosure, arrays={"predicted": _POSE, "variances": _f(None, 6)})
    # the run's record and terrain map
    types.add(RunRecorder, ("_n", "_blocks", "_status", "_reason", "_gaps", "_keys"))
    types.add(KeyRecord, arrays={"world_from_key": _POSE, "samples": _f(None, 3, optional=True)})
    types.add(TerrainMap, ("plane0", "points_per_keyframe", "refine", "_chunks", "_last",
                           "_last_image", "refined"), arrays={"_last_image": _IMAGE})
    types.add(_Chunk, name="TerrainMap.Chunk", arrays={
        "X": _f(None, 3), "intensity": _f4(None), "world_from_key": _POSE})
    return types


def checkpoint_path(out_dir: Path) -> Path:
    return Path(out_dir) / CHECKPOINT_FILE


def write_checkpoint(out_dir: Path, checkpoint: Checkpoint, types: Registry | None = None) -> None:
    """Replace ``out_dir``'s checkpoint with ``checkpoint``, atomically; ``types`` the classes
    its state is of (:func:`state_types`; None: the tracker's alone).

    A ValueError (:class:`~monovo_cli.io.state_codec.CodecError`) naming the attribute when
    the state holds anything but data of those classes (a bug: the class's fields in
    :func:`state_types` were not updated with the class)."""
    tree, arrays = encode(checkpoint, types or state_types())
    # streamed into the file: the state is tens of MB, and a bytes object of it at every
    # checkpoint is what made a long run's peak memory grow (docs/benchmarks.md "Memory").
    # Not hashed: no record lists the checkpoint (batch's done.json lists the results), and
    # the SHA-256 of its tens of MB took a third of its writing time
    atomic_write_with(checkpoint_path(out_dir), lambda f: _write_npz(f, tree, arrays),
                      digest=False)


def _write_npz(f: IO[bytes], tree: Any, arrays: dict[str, np.ndarray]) -> None:
    """The .npz of ``arrays`` and the record (module docstring), ``record`` last: it lists
    the CRC-32 zip computed of each member as it went by."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as z:
        table = {}
        for name, a in arrays.items():
            with z.open(f"{name}.npy", "w", force_zip64=True) as member:
                _write_npy(member, a)
            table[name] = [a.dtype.str, list(a.shape), z.getinfo(f"{name}.npy").CRC]
        record = {"format": FORMAT, "monovo": __version__, "arrays": table, "root": tree}
        text = json.dumps(record, allow_nan=False, separators=(",", ":")).encode("utf-8")
        with z.open(f"{_RECORD}.npy", "w", force_zip64=True) as member:
            _write_npy(member, np.frombuffer(text, np.uint8))


def _write_npy(f: IO[bytes], a: np.ndarray) -> None:
    """``a`` in the .npy format (what ``np.save`` writes), its bytes handed to ``f`` as they
    lie in memory rather than copied (``np.lib.format.write_array`` copies them in chunks)."""
    if not (a.flags.c_contiguous or a.flags.f_contiguous):
        a = np.ascontiguousarray(a)
    np.lib.format.write_array_header_1_0(f, np.lib.format.header_data_from_array_1_0(a))
    data = a if a.flags.c_contiguous else a.T  # (Fortran order: the header says so)
    f.write(memoryview(data.reshape(-1).view(np.uint8)))


def read_checkpoint(out_dir: Path, types: Registry | None = None,
                    state_type: type = object) -> Checkpoint | None:
    """``out_dir``'s checkpoint, or None when it has none; ``types`` the classes its state
    may be of (:func:`state_types`; None: the tracker's alone), ``state_type`` the class its
    state must be.

    InputError when the file cannot be read, is not a checkpoint (damaged, foreign, of
    another format), fails any check (module docstring), or was written by another version
    of monovo (whose state need not continue the same way); and when ``out_dir`` holds the
    pickle an earlier monovo wrote (never opened).
    """
    path = checkpoint_path(out_dir)
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except FileNotFoundError:
        old = Path(out_dir) / OLD_CHECKPOINT_FILE
        if old.exists() or old.is_symlink():
            raise InputError(f"{old}: the checkpoint of an earlier monovo, a pickle, which "
                             f"this one never loads (loading one can run code); "
                             f"{_START_AFRESH}") from None
        return None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the checkpoint ({exc.strerror})") from None
    if magic != b"PK\x03\x04":  # an .npz is a zip archive
        raise InputError(f"{path}: not a readable checkpoint (not an .npz archive); "
                         f"{_START_AFRESH}")
    try:
        with np.load(path, allow_pickle=False) as z:
            record = _record(path, z)
            arrays = _Arrays(z, record["arrays"])
            root = decode(record["root"], types or state_types(), arrays.get)
            arrays.check_all_used()
    except InputError:
        raise
    except CodecError as exc:
        raise InputError(f"{path}: not a readable checkpoint ({_one_line(str(exc))}); "
                         f"{_START_AFRESH}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the checkpoint "
                         f"({_one_line(exc.strerror or str(exc))})") from None
    except Exception as exc:  # noqa: BLE001 - numpy's npy/zip readers raise ValueError,
        # BadZipFile, EOFError, even SyntaxError on a damaged header; json a ValueError, a
        # RecursionError for deep nesting: all mean the same
        raise InputError(f"{path}: not a readable checkpoint ({type(exc).__name__}); "
                         f"{_START_AFRESH}") from None
    _check_checkpoint(path, root, state_type)
    return root


def _record(path: Path, z) -> dict:
    """The record of the open .npz ``z`` with its format and version checked."""
    if _RECORD not in z.files:
        raise InputError(f"{path}: not a monovo track checkpoint (no record); {_START_AFRESH}")
    raw = z[_RECORD]
    if not isinstance(raw, np.ndarray) or raw.dtype != np.uint8 or raw.ndim != 1:
        raise InputError(f"{path}: not a monovo track checkpoint (its record is not a text); "
                         f"{_START_AFRESH}")
    record = json.loads(raw.tobytes().decode("utf-8"), parse_constant=_no_constant)
    fmt = record.get("format") if isinstance(record, dict) else None
    if fmt != FORMAT:
        if isinstance(fmt, str) and fmt.startswith("monovo-checkpoint-"):
            raise InputError(f"{path}: a checkpoint of format {_one_line(fmt)!r}, this monovo "
                             f"reads {FORMAT!r}; {_START_AFRESH}")
        raise InputError(f"{path}: not a monovo track checkpoint; {_START_AFRESH}")
    if record.get("monovo") != __version__:
        raise InputError(f"{path}: written by monovo {_one_line(str(record.get('monovo')))}, "
                         f"this is {__version__}; {_START_AFRESH}")
    if set(record) != {"format", "monovo", "arrays", "root"} or \
            not isinstance(record["arrays"], dict):
        raise CodecError("the record's entries are not a checkpoint's")
    return record


def _no_constant(name: str) -> None:
    raise CodecError(f"{name} in the record")


class _Arrays:
    """The arrays of the open .npz ``z`` as the record's ``table`` lists them: each checked
    (dtype, shape, checksum) when the tree asks for it."""

    def __init__(self, z, table: dict) -> None:
        self.z, self.table, self.used = z, table, set()
        members = sorted(z.zip.namelist())
        expected = sorted([f"{name}.npy" for name in table] + [f"{_RECORD}.npy"])
        if members != expected:
            raise CodecError("its arrays are not the ones its record lists")

    def get(self, name: str) -> np.ndarray:
        entry = self.table.get(name)
        if name in self.used or type(entry) is not list or len(entry) != 3:
            raise CodecError(f"{name}: not in the record, or asked for twice")
        dtype, shape, crc = entry
        if dtype not in DTYPES or type(shape) is not list or \
                not all(type(n) is int and n >= 0 for n in shape) or type(crc) is not int:
            raise CodecError(f"{name}: not an array's dtype, shape and checksum")
        info = self.z.zip.getinfo(f"{name}.npy")
        if info.CRC != crc:
            raise CodecError(f"{name}: not the array written (its checksum differs)")
        size = np.dtype(dtype).itemsize * math.prod(shape)
        if not size <= info.file_size <= size + _NPY_HEADER_MAX:
            raise CodecError(f"{name}: {info.file_size} bytes for a {dtype} array of shape "
                             f"{tuple(shape)}")
        a = self.z[name]
        if not isinstance(a, np.ndarray):
            raise CodecError(f"{name}: not an array")
        if a.dtype.str != dtype or list(a.shape) != shape:
            raise CodecError(f"{name}: a {a.dtype.str} array of shape {a.shape}, the record "
                             f"says {dtype} {tuple(shape)}")
        self.used.add(name)
        return a

    def check_all_used(self) -> None:
        if self.used != set(self.table):
            raise CodecError("its record lists arrays the state does not hold")


def _check_checkpoint(path: Path, root: Any, state_type: type) -> None:
    """InputError unless ``root`` is a Checkpoint of sensible numbers and a ``state_type``."""
    ok = isinstance(root, Checkpoint) and isinstance(root.state, state_type) and \
        type(root.next_frame) is int and root.next_frame >= 1 and \
        type(root.motion_bytes) is int and root.motion_bytes >= 0 and \
        (root.covariance_bytes is None or
         (type(root.covariance_bytes) is int and root.covariance_bytes >= 0)) and \
        type(root.seconds) is float and math.isfinite(root.seconds) and \
        isinstance(root.fingerprint, dict)
    if not ok:
        raise InputError(f"{path}: not a monovo track checkpoint (its contents are not a "
                         f"checkpoint's); {_START_AFRESH}")


def _one_line(text: str, limit: int = 200) -> str:
    text = text.replace("\r", "\\r").replace("\n", "\\n")
    return text if len(text) <= limit else text[:limit] + "..."


def remove_checkpoint(out_dir: Path) -> None:
    """Delete ``out_dir``'s checkpoint (the run is finished, or starts afresh), an earlier
    monovo's pickled one, and any temporary one."""
    checkpoint_path(out_dir).unlink(missing_ok=True)
    (Path(out_dir) / OLD_CHECKPOINT_FILE).unlink(missing_ok=True)
    for name in (CHECKPOINT_FILE, OLD_CHECKPOINT_FILE):
        for tmp in Path(out_dir).glob(f".{name}.*.tmp"):
            tmp.unlink(missing_ok=True)


def continue_stream(path: Path, size: int) -> DigestingStream:
    """``path`` (a CSV streamed row by row) cut to its first ``size`` bytes and opened to
    append to; its digest covers the bytes kept.

    InputError when the file holds fewer than ``size`` bytes (it is not the file the
    checkpoint was taken with).
    """
    path = Path(path)
    try:
        with open(path, "r+b") as f:
            kept = f.read(size)
            if len(kept) < size:
                raise InputError(f"{path}: holds {len(kept)} bytes, fewer than the {size} "
                                 "the checkpoint was taken with; start the run afresh: allow "
                                 "overwriting or choose another output")
            f.truncate(size)
            f.flush()
            os.fsync(f.fileno())
        return DigestingStream(open(path, "a", newline="", encoding="utf-8"), path, prefix=kept)
    except FileNotFoundError:
        raise InputError(f"{path}: missing, but the checkpoint continues it; start the run "
                         "afresh: allow overwriting or choose another output") from None
    except OSError as exc:
        raise OutputError(f"{path}: cannot continue writing it ({exc.strerror})") from None
