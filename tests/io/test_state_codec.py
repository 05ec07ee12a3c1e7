"""The object-graph codec of the checkpoint: what it keeps, what it refuses, what it never does."""

from __future__ import annotations

import json
import math
from collections import deque
from dataclasses import dataclass
from enum import Enum
from functools import cached_property, partial
from pathlib import Path

import numpy as np
import pytest

from monovo_cli.io.state_codec import ArraySpec, CodecError, Registry, decode, encode


class Mood(Enum):
    CALM = "calm"
    BUSY = "busy"


@dataclass(frozen=True)
class Point:
    xy: np.ndarray
    label: str = ""

    @cached_property
    def norm(self) -> float:
        return float(np.hypot(*self.xy))


class Box:
    """A plain class: its attributes are registered by name."""

    def __init__(self, *items) -> None:
        self.items = list(items)
        self.mood = Mood.CALM
        self.recent: deque = deque(maxlen=3)


def registry() -> Registry:
    types = Registry()
    types.add(Point, arrays={"xy": ArraySpec("<f8", (2,))})
    types.add(Box, ("items", "mood", "recent"))
    types.add_enum(Mood)
    return types


def round_trip(obj, types=None):
    types = types or registry()
    tree, arrays = encode(obj, types)
    tree = json.loads(json.dumps(tree, allow_nan=False))  # (what the file holds)
    return decode(tree, types, arrays.get), tree, arrays


def test_every_kind_of_value_comes_back_equal_and_of_its_type():
    p = Point(np.array([3.0, 4.0]), "p")
    box = Box(p, 1.5, -0.0, math.inf, -math.inf, math.nan, 10**30, True, None, "t\nx",
              np.float64(2.5), np.float32(0.1), np.int64(-7), np.bool_(True),
              np.float64("nan"), (1, (2, "3")), {1: "a", "b": [2], (3, 4): None, None: 0})
    box.recent.extend([1, 2, 3, 4])
    back, _, _ = round_trip(box)
    assert type(back) is Box and back.mood is Mood.CALM
    assert type(back.recent) is deque and back.recent.maxlen == 3 and list(back.recent) == [2, 3, 4]
    q = back.items[0]
    assert type(q) is Point and q.label == "p" and q.xy.dtype == np.float64
    np.testing.assert_array_equal(q.xy, [3.0, 4.0])
    assert q.norm == 5.0  # (a cached property is worked out again)
    for got, want in zip(back.items[1:], box.items[1:]):
        assert type(got) is type(want), (got, want)
        if isinstance(want, float) and math.isnan(want):
            assert math.isnan(got)
        else:
            assert got == want or (got != got and want != want)
    assert math.copysign(1.0, back.items[2]) == -1.0
    assert back.items[-1] == {1: "a", "b": [2], (3, 4): None, None: 0}


@pytest.mark.parametrize("dtype", ["bool", "uint8", "int8", "uint16", "int16", "int32",
                                   "uint32", "int64", "uint64", "float16", "float32", "float64"])
def test_arrays_keep_dtype_shape_and_order(dtype):
    a = (np.arange(24) % 3).astype(dtype).reshape(2, 3, 4)
    f = np.asfortranarray(a[0])
    back, _, arrays = round_trip([a, f, a[:, ::2], np.array(5, dtype), np.zeros((0, 3), dtype)])
    for got, want in zip(back, [a, f, a[:, ::2], np.array(5, dtype), np.zeros((0, 3), dtype)]):
        assert got.dtype == want.dtype and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
    assert back[1].flags.f_contiguous


def test_identity_is_kept_shared_objects_stay_shared():
    """What was one object is one object after (the tracker compares with ``is``)."""
    image = np.zeros((4, 4), np.float32)
    p = Point(np.array([1.0, 2.0]))
    shared = [p, image]
    box = Box(p, p, image, image, shared, shared, (p, image))
    box.items.append(box.items)  # a list that holds itself
    back, tree, _ = round_trip(box)
    b = back.items
    assert b[0] is b[1] and b[2] is b[3] and b[4] is b[5] and b[6][0] is b[0]
    assert b[6][1] is b[2] and b[4][0] is b[0] and b[7] is b
    assert b[0] is not p
    again, _ = encode(back, registry())
    assert again == tree  # the same graph, refs included


def test_tuples_shared_and_empty():
    t = (1, 2)
    back, _, _ = round_trip([t, t, (), ()])
    assert back[0] is back[1] and back[0] == (1, 2) and back[2] == ()


@pytest.mark.parametrize("value, words", [
    (partial(print, 1), "functools.partial is not a registered type"),
    (lambda: 0, "function is not a registered type"),
    ({1, 2}, "builtins.set is not a registered type"),
    (Path("x"), "is not a registered type"),
    (np.array([object()]), "an array of dtype object"),
    (np.array(["text"]), "an array of dtype <U4"),
    (np.complex128(1j), "a numpy scalar of dtype complex128"),
    (np.ma.masked_array([1.0]), "MaskedArray is not a registered type"),
])
def test_what_is_not_data_is_refused_where_it_is(value, words):
    box = Box(1, {"k": [0, value]})
    with pytest.raises(CodecError) as err:
        encode(box, registry())
    assert words in str(err.value) and ".items[1]['k'][1]" in str(err.value), str(err.value)


def test_a_plain_object_with_an_attribute_not_registered_is_refused():
    box = Box()
    box.extra = 1
    with pytest.raises(CodecError, match="not registered: extra; missing: none"):
        encode(box, registry())
    del box.extra, box.mood
    with pytest.raises(CodecError, match="not registered: none; missing: mood"):
        encode(box, registry())


def _tree(obj):
    tree, arrays = encode(obj, registry())
    return json.loads(json.dumps(tree)), arrays


@pytest.mark.parametrize("spoil, words", [
    (lambda t: t[:3] + [{**t[3], "extra": 1}], "fields are not the registered ones (unknown: extra"),
    (lambda t: t[:3] + [{k: v for k, v in t[3].items() if k != "mood"}], "missing: mood"),
    (lambda t: t[:2] + ["os.system"] + t[3:], "not a registered type: 'os.system'"),
    (lambda t: t[:2] + ["Path"] + t[3:], "not a registered type: 'Path'"),
    (lambda t: ["object", 1] + t[2:], "object number 1 out of order"),
    (lambda t: ["ref", 0], "a reference to no object"),
    (lambda t: ["exec", "print(1)"], "not a node: 'exec'"),
    (lambda t: {"object": t}, "not a node: dict"),
    (lambda t: t[:3] + [{**t[3], "mood": ["enum", "Mood", "angry"]}], "not a Mood: 'angry'"),
    (lambda t: t[:3] + [{**t[3], "mood": ["enum", "Signals", "x"]}], "not a registered enum"),
    (lambda t: t[:3] + [{**t[3], "recent": ["deque", 2, 1, [1, 2]]}], "not a deque's maxlen"),
    (lambda t: t[:3] + [{**t[3], "items": ["list", 1, [["float", "1e400"]]]}], "not a float"),
    (lambda t: t[:3] + [{**t[3], "items": ["list", 1, [["scalar", "<i8", 2 ** 70]]]}],
     "not a <i8 value"),
    (lambda t: t[:3] + [{**t[3], "items": ["list", 1, [["scalar", "|O", 1]]]}],
     "not a numpy scalar"),
    (lambda t: t[:3] + [{**t[3], "items": ["list", 1, [["dict", 2, [[["list", 3, []], 1]]]]]}],
     "not a key"),
    (lambda t: t[:3] + [{**t[3], "items": ["list", 1, [["tuple", 2, [["ref", 2]]]]]}],
     "a tuple that contains itself"),
])
def test_a_spoiled_tree_is_a_codec_error(spoil, words):
    tree, arrays = _tree(Box())
    with pytest.raises(CodecError) as err:
        decode(spoil(tree), registry(), arrays.get)
    assert words in str(err.value), str(err.value)


@pytest.mark.parametrize("xy, words", [
    (np.array([1.0, 2.0, 3.0]), "expected an array of shape (2,), found (3,)"),
    (np.array([1, 2]), "expected a <f8 array, found <i8"),
    (np.array([1, 2], np.float32), "expected a <f8 array, found <f4"),
    (np.array([[1.0, 2.0]]), "expected an array of shape (2,), found (1, 2)"),
    ("text", "expected an array, found str"),
])
def test_a_field_s_declared_array_is_checked_when_read(xy, words):
    tree, arrays = _tree(Box(Point(xy)))  # (written as it is: the spec is the reader's check)
    with pytest.raises(CodecError) as err:
        decode(tree, registry(), arrays.get)
    assert words in str(err.value) and ".items[0].xy" in str(err.value), str(err.value)


def test_an_array_the_reader_does_not_give_is_refused():
    tree, arrays = _tree(Box(np.zeros(3)))
    with pytest.raises(CodecError, match="not an array of a kept dtype"):
        decode(tree, registry(), lambda name: None)
    with pytest.raises(CodecError, match="not an array of a kept dtype"):
        decode(tree, registry(), lambda name: np.array(["s"]))


def test_decoding_creates_registered_classes_without_their_init(monkeypatch):
    calls = []
    monkeypatch.setattr(Box, "__init__", lambda self, *a: calls.append(a))
    box = object.__new__(Box)
    box.items, box.mood, box.recent = [], Mood.BUSY, deque()
    back, _, _ = round_trip(box)
    assert calls == [] and back.mood is Mood.BUSY


def test_registering_twice_or_specs_of_missing_fields_is_an_error():
    types = registry()
    with pytest.raises(ValueError, match="registered twice"):
        types.add(Point)
    with pytest.raises(ValueError, match="not a dataclass"):
        Registry().add(Box)
    with pytest.raises(ValueError, match="array specs of fields it has not"):
        Registry().add(Point, arrays={"z": ArraySpec("<f8", ())})
