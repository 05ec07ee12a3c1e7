"""Fuzzing the readers of monovo's own files: TUM, motion.csv, trajectory.csv, model.npz,
the track checkpoint.

Property: whatever the bytes, a reader either returns finite, well-formed data or raises
an :class:`~monovo_cli.errors.InputError` whose message is one line naming the file;
never another exception. (The init.yaml loader is fuzzed in test_config.py, the frame
reader in test_frames.py; 500 examples each there too.)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from monovo_cli.errors import InputError, MonovoError
from monovo_cli.io.checkpoint import CHECKPOINT_FILE, Checkpoint, read_checkpoint
from monovo_cli.io.formats import (
    MOTION_COLUMNS,
    STD_COLUMNS,
    TRAJECTORY_COLUMNS,
    read_motion_csv,
    read_motion_stats,
    read_trajectory_csv,
    read_tum,
)
from monovo_cli.io.model import load_model

EXAMPLES = 250
FUZZ = settings(max_examples=EXAMPLES, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


# ----------------------------------------------------------------------------- strategies

_number_text = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-1e3, 1e3).map(repr),
    st.integers(-10**6, 10**6).map(str),
    st.integers().map(str),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-1e308", "1e308", "-0", "0", "1", "0.5",
                     "1_0", "0x10", "", " ", "abc", "1e", ".", "+", "∞", "١", "\x00"]),
)
_token = st.one_of(_number_text, _number_text, st.text(max_size=6))
# mostly well-formed numbers, so that many files get past the first line
_good_token = st.one_of(st.floats(allow_nan=False, allow_infinity=False).map(repr),
                        st.floats(-10, 10).map(repr), st.integers(-3, 300).map(str))
_some_token = st.one_of(_good_token, _good_token, _good_token, _good_token, _token)


def _lines(width: st.SearchStrategy[int], sep: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    """Up to 6 lines of ``width`` tokens; per file, the tokens are all well-formed, mostly
    well-formed or anything."""
    def lines(tokens):
        line = st.tuples(width, sep).flatmap(
            lambda ws: st.lists(tokens, min_size=ws[0], max_size=ws[0]).map(ws[1].join))
        extra = st.sampled_from(["", "# a comment", "   ", "\t"])
        return st.lists(st.one_of(line, line, line, extra), max_size=6).flatmap(
            lambda ls: st.sampled_from(["\n", "\r\n", "\r"]).map(lambda nl: nl.join(ls)))
    return st.sampled_from([_good_token, _some_token, _token]).flatmap(lines)


def _with_header(header: str, width: st.SearchStrategy[int]) -> st.SearchStrategy[str]:
    return st.tuples(st.sampled_from([header, header, header + "\n", header.upper(), header[:20]]),
                     _lines(width, st.just(","))).map(lambda hb: hb[0] + "\n" + hb[1])


_tum_text = st.one_of(
    _lines(st.sampled_from([8, 8, 8, 7, 9]), st.sampled_from([" ", ",", "\t", "  "])),
    _lines(st.just(8), st.just(" ")),
    st.text(max_size=300),
)
_motion_text = st.one_of(
    _with_header(",".join(MOTION_COLUMNS + STD_COLUMNS), st.sampled_from([17, 17, 11, 7, 5, 18])),
    _with_header(",".join(MOTION_COLUMNS), st.just(11)),
    st.text(max_size=300),
)
_trajectory_text = st.one_of(
    _with_header(",".join(TRAJECTORY_COLUMNS), st.sampled_from([9, 9, 8, 10])),
    _with_header(",".join(TRAJECTORY_COLUMNS), st.just(9)),
    st.text(max_size=300),
)


def _payload(text_strategy: st.SearchStrategy[str]) -> st.SearchStrategy[bytes]:
    """Text as UTF-8 (sometimes Latin-1 or with bytes spliced in), or random bytes."""
    def spoil(args):
        text, how, junk = args
        if how == "latin-1":
            return text.encode("latin-1", "replace")
        data = text.encode("utf-8", "surrogatepass")
        if how == "splice":
            mid = len(data) // 2
            return data[:mid] + junk + data[mid:]
        return data
    return st.one_of(
        st.tuples(text_strategy, st.sampled_from(["utf-8", "utf-8", "latin-1", "splice"]),
                  st.binary(max_size=8)).map(spoil),
        st.binary(max_size=300),
    )


def _write(scratch: Path, name: str, data: bytes) -> Path:
    path = scratch / name
    path.write_bytes(data)
    return path


def _expect_input_error(exc: Exception, path: Path) -> None:
    assert isinstance(exc, InputError), f"{type(exc).__name__}: {exc}"
    assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc), str(exc)
    event("rejected")


_REJECTED = object()


def _read(scratch: Path, name: str, data: bytes, reader):
    """``reader`` on ``data`` written to ``scratch/name``: its result, or ``_REJECTED`` after
    checking that the failure is a one-line InputError naming the file."""
    path = _write(scratch, name, data)
    try:
        result = reader(path)
    except Exception as exc:  # noqa: BLE001 - the property is about the type
        _expect_input_error(exc, path)
        return _REJECTED
    event("read")
    return result


def _check_poses(poses: np.ndarray, n: int) -> None:
    assert poses.shape == (n, 4, 4) and np.all(np.isfinite(poses))
    R = poses[:, :3, :3]
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-6)
    np.testing.assert_array_equal(poses[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (n, 4)))


# ----------------------------------------------------------------------------- the readers


@FUZZ
@given(data=_payload(_tum_text))
def test_fuzz_read_tum(scratch, data):
    result = _read(scratch, "t.tum", data, read_tum)
    if result is _REJECTED:
        return
    ts, poses = result
    assert ts.ndim == 1 and len(ts) >= 1 and np.all(np.isfinite(ts))
    _check_poses(poses, len(ts))


@FUZZ
@given(data=_payload(_motion_text))
def test_fuzz_read_motion_csv(scratch, data):
    result = _read(scratch, "motion.csv", data, read_motion_csv)
    if result is _REJECTED:
        return
    frames, poses, statuses = result
    assert frames.dtype.kind == "i" and len(statuses) == len(frames)
    _check_poses(poses, len(frames))


@FUZZ
@given(data=_payload(_trajectory_text))
def test_fuzz_read_trajectory_csv(scratch, data):
    result = _read(scratch, "trajectory.csv", data, read_trajectory_csv)
    if result is _REJECTED:
        return
    frames, ts, poses = result
    assert frames.dtype.kind == "i" and len(set(frames.tolist())) == len(frames)
    assert np.all(np.isfinite(ts)) and len(ts) == len(frames)
    _check_poses(poses, len(frames))


@FUZZ
@given(data=_payload(_motion_text))
def test_fuzz_read_motion_stats(scratch, data):
    result = _read(scratch, "motion.csv", data, read_motion_stats)
    if result is _REJECTED:
        return
    stats = result
    for frame, (status, msd) in stats.items():
        assert isinstance(frame, int) and isinstance(status, str) and math.isfinite(msd)


# ----------------------------------------------------------------------------- model.npz


@pytest.fixture(scope="module")
def model_bytes(synth_drive, tmp_path_factory) -> bytes:
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.track import init_model

    seq = synth_drive(preset="drive", frames=2, size=(64, 64), seed=2)
    root = tmp_path_factory.mktemp("model")
    init_model(seq, None, root / "model.npz", TrackOptions(max_points=300))
    return _Blob((root / "model.npz").read_bytes())


class _Blob(bytes):
    """bytes that do not flood hypothesis' report of a failing example."""

    def __repr__(self) -> str:
        return f"<{len(self)} bytes of model.npz>"


@st.composite
def _damaged(draw, original: bytes) -> bytes:
    data = bytearray(original)
    how = draw(st.sampled_from(["truncate", "flip", "flip", "splice", "zero"]))
    if how == "truncate":
        return bytes(data[: draw(st.integers(0, len(data) - 1))])
    if how == "flip":
        for _ in range(draw(st.integers(1, 6))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
    elif how == "splice":
        i = draw(st.integers(0, len(data)))
        data[i:i] = draw(st.binary(min_size=1, max_size=32))
    else:
        i = draw(st.integers(0, len(data) - 1))
        data[i:i + draw(st.integers(1, 64))] = b"\0" * 8
    return bytes(data)


@FUZZ
@given(data=st.data())
def test_fuzz_load_model(scratch, model_bytes, data):
    blob = data.draw(st.one_of(_damaged(model_bytes), st.binary(max_size=200),
                               st.binary(max_size=60).map(lambda b: b"PK\x03\x04" + b)))
    result = _read(scratch, "model.npz", blob, load_model)
    if result is _REJECTED:
        return
    camera, region, key = result
    assert camera.width > 0 and len(region) == 4 and len(key.levels) >= 1


def test_an_intact_model_loads(scratch, model_bytes):
    camera, region, key = load_model(_write(scratch, "ok.npz", model_bytes))
    assert (camera.width, camera.height) == (64, 64) and region == (0, 0, 64, 64)


def test_huge_quaternion_components_do_not_overflow(scratch):
    """1e200 0 0 1 is a half turn about x (normalised), not the identity."""
    ts, poses = read_tum(_write(scratch, "big.tum", b"0 1 2 3 1e200 0 0 1\n"))
    np.testing.assert_allclose(poses[0][:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    np.testing.assert_array_equal(poses[0][:3, 3], [1.0, 2.0, 3.0])


def test_monovo_error_is_the_root():
    assert issubclass(InputError, MonovoError)


# ----------------------------------------------------------------------------- the checkpoint


@pytest.fixture(scope="module")
def checkpoint_bytes(synth_drive, tmp_path_factory) -> bytes:
    """The checkpoint of a 2-frame 64x64 drive tracked with its terrain map and thumbnails."""
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.io.checkpoint import write_checkpoint
    from monovo_cli.pipeline.tracking import Tracking, open_sequence, state_types

    seq = synth_drive(preset="drive", frames=2, size=(64, 64), seed=2)
    tracking = Tracking(open_sequence(seq), TrackOptions(max_points=300), terrain=True,
                        thumbnails=2, thumbnail_side=16)
    for _ in tracking:
        pass
    root = tmp_path_factory.mktemp("checkpoint")
    write_checkpoint(root, Checkpoint(2, {"inputs": [1, "x"]}, tracking.state(), 100, None, 0.5),
                     state_types())
    return _Blob((root / CHECKPOINT_FILE).read_bytes())


def _members(data: bytes) -> dict[str, bytes]:
    import io
    import zipfile

    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return {name: z.read(name) for name in z.namelist()}


def _zipped(members: dict[str, bytes]) -> bytes:
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def _npy(a: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def _loaded(data: bytes) -> np.ndarray:
    import io

    return np.load(io.BytesIO(data), allow_pickle=False)


_json_leaf = st.one_of(st.none(), st.booleans(), st.integers(-3, 300), st.integers(),
                       st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=8),
                       st.sampled_from(["ok", "lost", "<f8", "|O", "a0", "FrameStatus",
                                        "Odometry", "Plane", "os.system", "nan", "-inf"]))
_json_node = st.recursive(
    _json_leaf,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3),
        st.tuples(st.sampled_from(["ref", "array", "float", "list", "tuple", "deque", "dict",
                                   "object", "enum", "scalar", "exec"]),
                  st.lists(inner, max_size=4)).map(lambda t: [t[0], *t[1]])),
    max_leaves=8)


def _places(node, out: list) -> list:
    """Every (container, key) of a JSON tree."""
    if isinstance(node, list):
        for i, x in enumerate(node):
            out.append((node, i))
            _places(x, out)
    elif isinstance(node, dict):
        for k, x in node.items():
            out.append((node, k))
            _places(x, out)
    return out


@st.composite
def _spoiled_checkpoint(draw, original: bytes) -> bytes:
    """The checkpoint re-zipped intact (zip's own checksums right) after one change inside:
    two arrays swapped, an array of another dtype or shape (the record's table told or not),
    a member dropped or cut short, or any node of the record's JSON replaced by other JSON."""
    import json
    import zipfile

    members = _members(original)
    names = sorted(n for n in members if n != "checkpoint.npy")
    record = json.loads(_loaded(members["checkpoint.npy"]).tobytes())
    how = draw(st.sampled_from(["swap", "dtype", "dtype", "drop", "cut", "record", "record",
                                "record", "record"]))
    if how == "swap":
        a, b = draw(st.lists(st.sampled_from(names), min_size=2, max_size=2, unique=True))
        members[a], members[b] = members[b], members[a]
    elif how == "dtype":
        name = draw(st.sampled_from(names))
        a = _loaded(members[name])
        dtype = draw(st.sampled_from(["<f4", "<f8", "<i8", "|b1", "|u1", "<c8", ">f8", "<U2"]))
        if draw(st.booleans()) and a.size:
            a = a.reshape(-1)[: draw(st.integers(0, a.size - 1))]
        members[name] = _npy(a.astype(dtype))
        if draw(st.booleans()):  # the table agrees with the member: the spec must catch it
            b = _loaded(members[name])
            record["arrays"][name[:-4]] = [b.dtype.str, list(b.shape),
                                           zipfile.crc32(members[name])]
    elif how == "drop":
        del members[draw(st.sampled_from(sorted(members)))]
    elif how == "cut":
        name = draw(st.sampled_from(sorted(members)))
        members[name] = members[name][: draw(st.integers(0, len(members[name]) - 1))]
    else:
        places = _places(record, [])
        container, key = places[draw(st.integers(0, len(places) - 1))]
        container[key] = draw(_json_node)
    if how in ("dtype", "record"):  # (the record changed)
        text = json.dumps(record).encode("utf-8")
        members["checkpoint.npy"] = _npy(np.frombuffer(text, np.uint8))
    return _Blob(_zipped(members))


def _read_checkpoint(path: Path):
    from monovo_cli.pipeline.tracking import TrackingState, state_types

    return read_checkpoint(path.parent, state_types(), TrackingState)


def _check_checkpoint(result) -> None:
    from monovo_cli.pipeline.tracking import TrackingState

    if result is not _REJECTED:
        assert isinstance(result, Checkpoint) and isinstance(result.state, TrackingState)


@FUZZ
@given(data=st.data())
def test_fuzz_read_checkpoint_bytes(scratch, checkpoint_bytes, data):
    """Random bytes, truncations, flipped, spliced and zeroed bytes."""
    blob = data.draw(st.one_of(_damaged(checkpoint_bytes), st.binary(max_size=200),
                               st.binary(max_size=60).map(lambda b: b"PK\x03\x04" + b)))
    _check_checkpoint(_read(scratch, CHECKPOINT_FILE, blob, _read_checkpoint))


@FUZZ
@given(data=st.data())
def test_fuzz_read_checkpoint_inside(scratch, checkpoint_bytes, data):
    """Valid zips holding swapped arrays, wrong dtypes and shapes, missing or short members,
    and records whose JSON was changed anywhere."""
    blob = data.draw(_spoiled_checkpoint(checkpoint_bytes))
    _check_checkpoint(_read(scratch, CHECKPOINT_FILE, blob, _read_checkpoint))


def test_an_intact_checkpoint_reads(scratch, checkpoint_bytes):
    back = _read_checkpoint(_write(scratch, CHECKPOINT_FILE, checkpoint_bytes))
    assert back.next_frame == 2 and back.fingerprint == {"inputs": [1, "x"]}
    again = _read_checkpoint(_write(scratch, CHECKPOINT_FILE, _zipped(_members(checkpoint_bytes))))
    assert again.next_frame == 2
