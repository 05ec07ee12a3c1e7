"""The track checkpoint as data: the tracker's whole state round trips, shared objects
stay shared, and a file that is not exactly what monovo wrote is one clear InputError."""

from __future__ import annotations

import ast
import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from monovo_cli.core.options import TrackOptions
from monovo_cli.errors import InputError
from monovo_cli.io import checkpoint as ckpt
from monovo_cli.io.checkpoint import (
    CHECKPOINT_FILE,
    FORMAT,
    OLD_CHECKPOINT_FILE,
    Checkpoint,
    read_checkpoint,
    write_checkpoint,
)
from monovo_cli.io.state_codec import encode
from monovo_cli.pipeline.tracking import Tracking, TrackingState, open_sequence, state_types
from monovo_cli.version import __version__

PKG = Path(__file__).resolve().parents[2] / "monovo_cli"
FRAMES = 40


@pytest.fixture(scope="module")
def lossy(synth_drive, tmp_path_factory) -> Path:
    """The resume tests' drive (192x192), its first 40 frames, 4 of them noise (lost, then
    the recovery: the feature hypothesis and the gap's state are in the checkpoint)."""
    import cv2

    seq = synth_drive(preset="drive", frames=60, size=(192, 192), seed=4)
    copy = tmp_path_factory.mktemp("lossy") / "seq"
    shutil.copytree(seq, copy)
    frames = sorted((copy / "frames").glob("*.png"))
    for path in frames[FRAMES:]:
        path.unlink()
    rng = np.random.default_rng(3)
    for path in frames[20:24]:
        cv2.imwrite(str(path), rng.integers(0, 256, (192, 192), dtype=np.uint8))
    return copy


def _tracking(seq: Path) -> Tracking:
    return Tracking(open_sequence(seq), TrackOptions(), terrain=True, thumbnails=4,
                    thumbnail_side=32)


def _checkpoint(tracking: Tracking) -> Checkpoint:
    return Checkpoint(tracking.done, {"inputs": {"frames": 1}, "options": (1, 2.5)},
                      tracking.state(), 321, 654, 1.25)


def _same_graph(a, b) -> None:
    """``a`` and ``b`` encode to the same tree (refs included: the same sharing of
    objects) and equal arrays of the same dtypes."""
    tree_a, arrays_a = encode(a, state_types())
    tree_b, arrays_b = encode(b, state_types())
    assert tree_a == tree_b
    assert list(arrays_a) == list(arrays_b)
    for name, x in arrays_a.items():
        y = arrays_b[name]
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)


def test_the_tracker_state_round_trips_at_every_kind_of_frame(lossy, tmp_path):
    """Every 3rd frame (before, in and after the lost ones, at re-anchors): the state read
    back is the state written, graph and arrays, and its shared objects are shared."""
    tracking, statuses = _tracking(lossy), set()
    types = state_types()
    for res in tracking:
        statuses.add(res.status.value)
        if tracking.done % 3:
            continue
        cp = _checkpoint(tracking)
        write_checkpoint(tmp_path, cp, types)
        back = read_checkpoint(tmp_path, types, TrackingState)
        _same_graph(cp, back)
        a, b = cp.state.odometry, back.state.odometry
        assert (b._key is b._announced) == (a._key is a._announced)
        assert (back.state.terrain._last is b._key) == (cp.state.terrain._last is a._key)
        if a._motion_cov._sample is not None:
            assert (b._motion_cov._sample[0] is b._key.levels[0]) == \
                (a._motion_cov._sample[0] is a._key.levels[0])
        assert (back.state.last_image is b._prev_image) == \
            (cp.state.last_image is a._prev_image)
        assert back.fingerprint == cp.fingerprint and back.seconds == 1.25
        assert (back.motion_bytes, back.covariance_bytes) == (321, 654)
    assert {"ok", "lost", "reanchored"} <= statuses, statuses


def test_a_continued_tracking_gives_the_same_results(lossy, tmp_path):
    """A Tracking restored from the file at frame 21 (in the lost frames) yields what the
    one that wrote it yields next, exactly."""
    a = _tracking(lossy)
    for _ in a:
        if a.done == 21:
            break
    write_checkpoint(tmp_path, _checkpoint(a), state_types())
    b = _tracking(lossy)
    b.restore(read_checkpoint(tmp_path, state_types(), TrackingState).state)
    rest_a, rest_b = list(a), list(b)
    assert len(rest_a) == len(rest_b) == FRAMES - 21
    for x, y in zip(rest_a, rest_b):
        assert (x.index, x.status, x.reason) == (y.index, y.status, y.reason)
        np.testing.assert_array_equal(x.world_from_cam, y.world_from_cam)
        np.testing.assert_array_equal(x.covariance, y.covariance)
    np.testing.assert_array_equal(a.trajectory(), b.trajectory())


# ----------------------------------------------------------------------------- damaged files


@pytest.fixture(scope="module")
def written(lossy, tmp_path_factory) -> Path:
    """A folder holding the checkpoint at frame 24 (the recovery after the lost frames)."""
    tracking = _tracking(lossy)
    for _ in tracking:
        if tracking.done == 24:
            break
    out = tmp_path_factory.mktemp("written")
    write_checkpoint(out, _checkpoint(tracking), state_types())
    return out


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as z:
        return {name: z.read(name) for name in z.namelist()}


def _rezip(path: Path, members: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)


def _npy(a: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def _record_of(members: dict[str, bytes]) -> dict:
    import io

    return json.loads(np.load(io.BytesIO(members["checkpoint.npy"])).tobytes())


def _with_record(members: dict[str, bytes], record: dict) -> dict[str, bytes]:
    text = json.dumps(record).encode()
    return {**members, "checkpoint.npy": _npy(np.frombuffer(text, np.uint8))}


def _read(out: Path):
    return read_checkpoint(out, state_types(), TrackingState)


def _refused(out: Path, words: str) -> str:
    with pytest.raises(InputError) as err:
        _read(out)
    text = str(err.value)
    assert text.startswith(f"{out / CHECKPOINT_FILE}: ") and "\n" not in text, text
    assert words in text, text
    assert text.endswith("start the run afresh: allow overwriting or choose another output"), text
    return text


def _spoiled(written: Path, tmp_path: Path, spoil) -> Path:
    out = tmp_path / "out"
    out.mkdir()
    members = _members(written / CHECKPOINT_FILE)
    _rezip(out / CHECKPOINT_FILE, spoil(members))
    return out


def _big_arrays(members: dict[str, bytes]) -> list[str]:
    record = _record_of(members)
    by_kind: dict = {}
    for name, (dtype, shape, _) in record["arrays"].items():
        by_kind.setdefault((dtype, tuple(shape)), []).append(name)
    return next(names for names in by_kind.values() if len(names) >= 2)


def test_an_intact_file_rezipped_reads(written, tmp_path):
    out = _spoiled(written, tmp_path, lambda m: m)
    assert _read(out).next_frame == 24


def test_swapped_arrays_of_one_dtype_and_shape_are_refused(written, tmp_path):
    def swap(m):
        a, b = _big_arrays(m)[:2]
        return {**m, f"{a}.npy": m[f"{b}.npy"], f"{b}.npy": m[f"{a}.npy"]}
    _refused(_spoiled(written, tmp_path, swap), "not the array written (its checksum differs)")


def test_an_array_of_another_dtype_is_refused(written, tmp_path):
    def retype(m):
        record = _record_of(m)
        name, (dtype, shape, _) = next((n, e) for n, e in record["arrays"].items()
                                       if e[0] == "<f8" and len(e[1]) == 2 and e[1] == [4, 4])
        data = _npy(np.zeros(shape, np.float32))
        record["arrays"][name] = ["<f4", shape, zipfile.crc32(data)]
        return {**_with_record(m, record), f"{name}.npy": data}
    _refused(_spoiled(written, tmp_path, retype), "expected a <f8 array, found <f4")


def test_an_array_of_an_undeclared_dtype_is_refused(written, tmp_path):
    def to_complex(m):
        record = _record_of(m)
        name, (_, shape, _) = next(iter(record["arrays"].items()))
        data = _npy(np.zeros(shape, np.complex64))
        record["arrays"][name] = ["<c8", shape, zipfile.crc32(data)]
        return {**_with_record(m, record), f"{name}.npy": data}
    _refused(_spoiled(written, tmp_path, to_complex), "not an array's dtype, shape and checksum")


@pytest.mark.parametrize("grow, words", [
    (lambda n: n + 1, "the record says <f8 (4,)"),
    (lambda n: n * 10**9, "bytes for a <f8 array of shape (3000000000,)"),  # (never allocated)
])
def test_an_array_whose_table_entry_lies_about_it_is_refused(written, tmp_path, grow, words):
    def lie(m):
        record = _record_of(m)
        name, (dtype, shape, crc) = next(iter(record["arrays"].items()))
        assert (dtype, shape) == ("<f8", [3])  # (frame 0's plane's normal)
        record["arrays"][name] = [dtype, [grow(shape[0])], crc]
        return _with_record(m, record)
    _refused(_spoiled(written, tmp_path, lie), words)


@pytest.mark.parametrize("spoil, words", [
    (lambda m: {**m, "a0.npy": m["checkpoint.npy"]}, "its arrays are not the ones its record lists"),
    (lambda m: {k: v for k, v in m.items() if k != sorted(m)[0]},
     "its arrays are not the ones its record lists"),
    (lambda m: {**m, "extra.npy": _npy(np.zeros(3))}, "its arrays are not the ones its record"),
    (lambda m: {k: v for k, v in m.items() if k != "checkpoint.npy"}, "not a monovo track checkpoint"),
    (lambda m: _with_record(m, {**_record_of(m), "format": "monovo-checkpoint-5"}),
     "a checkpoint of format 'monovo-checkpoint-5', this monovo reads"),
    (lambda m: _with_record(m, {**_record_of(m), "format": "something"}),
     "not a monovo track checkpoint"),
    (lambda m: _with_record(m, {**_record_of(m), "monovo": "0.0.1"}),
     f"written by monovo 0.0.1, this is {__version__}"),
    (lambda m: _with_record(m, {**_record_of(m), "more": 1}), "the record's entries"),
    (lambda m: {**m, "checkpoint.npy": _npy(np.frombuffer(b"{not json", np.uint8))},
     "not a readable checkpoint (JSONDecodeError)"),
    (lambda m: {**m, "checkpoint.npy": _npy(np.zeros(3))}, "its record is not a text"),
    (lambda m: {**m, "checkpoint.npy": b"not an npy"}, "its record is not a text"),
])
def test_a_foreign_or_other_format_file_is_refused(written, tmp_path, spoil, words):
    _refused(_spoiled(written, tmp_path, spoil), words)


def test_a_checkpoint_of_something_else_is_refused(written, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    write_checkpoint(out, Checkpoint(3, {}, {"not": "a tracking state"}, 10), state_types())
    _refused(out, "its contents are not a checkpoint's")
    write_checkpoint(out, Checkpoint(0, {}, _read(written).state, 10), state_types())
    _refused(out, "its contents are not a checkpoint's")


@pytest.mark.parametrize("cut", [0, 3, 100, 0.5, -200, -1])
def test_a_truncated_file_is_refused(written, tmp_path, cut):
    out = tmp_path / "out"
    out.mkdir()
    data = (written / CHECKPOINT_FILE).read_bytes()
    n = int(len(data) * cut) if isinstance(cut, float) else cut % len(data) if cut < 0 else cut
    (out / CHECKPOINT_FILE).write_bytes(data[:n])
    _refused(out, "not a readable checkpoint")


def test_a_flipped_byte_in_an_array_is_refused(written, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    data = bytearray((written / CHECKPOINT_FILE).read_bytes())
    data[len(data) // 3] ^= 0xFF  # (inside the big arrays)
    (out / CHECKPOINT_FILE).write_bytes(bytes(data))
    _refused(out, "not a readable checkpoint")


def test_a_model_npz_is_not_a_checkpoint(tmp_path, synth_drive):
    from monovo_cli.pipeline.track import init_model

    seq = synth_drive(preset="drive", frames=2, size=(64, 64), seed=2)
    out = tmp_path / "out"
    out.mkdir()
    init_model(seq, None, out / CHECKPOINT_FILE, TrackOptions(max_points=300))
    _refused(out, "not a monovo track checkpoint (no record)")


def test_an_earlier_monovo_s_pickle_is_refused_and_never_opened(tmp_path, monkeypatch):
    (tmp_path / OLD_CHECKPOINT_FILE).write_bytes(b"\x80\x05 a pickle")
    opened = []
    real_open = open

    def spy(path, *args, **kwargs):
        opened.append(str(path))
        return real_open(path, *args, **kwargs)
    monkeypatch.setattr("builtins.open", spy)
    with pytest.raises(InputError) as err:
        _read(tmp_path)
    assert str(err.value) == (
        f"{tmp_path / OLD_CHECKPOINT_FILE}: the checkpoint of an earlier monovo, a pickle, which "
        "this one never loads (loading one can run code); start the run afresh: allow "
        "overwriting or choose another output")
    assert not any(p.endswith(".pkl") for p in opened), opened
    ckpt.remove_checkpoint(tmp_path)
    assert not (tmp_path / OLD_CHECKPOINT_FILE).exists() and _read(tmp_path) is None


def test_the_format_is_named_in_the_file(written):
    record = _record_of(_members(written / CHECKPOINT_FILE))
    assert record["format"] == FORMAT and record["monovo"] == __version__
    assert set(record) == {"format", "monovo", "arrays", "root"}


# ----------------------------------------------------------------------------- no pickle


def test_the_package_neither_imports_pickle_nor_loads_with_allow_pickle():
    """Nothing in monovo_cli/ can turn a file into code: no pickle (nor its kin) imported,
    no ``allow_pickle=True``, no numpy load with allow_pickle other than False."""
    unsafe = {"pickle", "_pickle", "cPickle", "cloudpickle", "dill", "shelve", "marshal",
              "joblib", "copyreg"}
    found = []
    for path in sorted(PKG.rglob("*.py")):
        text = path.read_text()
        if "allow_pickle=True" in text.replace(" ", ""):
            found.append(f"{path}: allow_pickle=True")
        for node in ast.walk(ast.parse(text)):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            found += [f"{path}:{node.lineno}: imports {n}" for n in names
                      if n.split(".")[0] in unsafe]
            if isinstance(node, ast.keyword) and node.arg == "allow_pickle" and not (
                    isinstance(node.value, ast.Constant) and node.value.value is False):
                found.append(f"{path}:{node.value.lineno}: allow_pickle not False")
    assert not found, "\n".join(found)
