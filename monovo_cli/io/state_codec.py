"""Object graphs as data: numpy arrays plus a JSON tree, read back into registered classes only.

:func:`encode` walks an object graph into a JSON-able tree and the arrays it holds;
:func:`decode` rebuilds the graph. The walk knows ``None``, ``bool``, ``int``, ``str`` and
``float`` (non-finite ones as ``["float", "nan" | "inf" | "-inf"]``); numpy scalars and
arrays of the dtypes in :data:`DTYPES` (an array goes to the arrays as ``a<id>``); ``list``,
``tuple``, ``dict`` (any keys it knows) and ``collections.deque`` (with its ``maxlen``);
members of the :class:`Registry`'s enums, and instances of its classes with exactly the
fields it lists (a dataclass's fields, or the attributes given for a plain class; values of
``functools.cached_property`` are left out and worked out again when first asked for).
Anything else (a function, a ``functools.partial``, a path, a set) is refused when encoding
(:class:`CodecError`, naming where in the graph it is).

Identity is kept: an object met again (an array, a container, a registered instance) is
written ``["ref", id]``, so what was one object is one object after, as code that compares
with ``is`` relies on. Ids number those objects in the order the walk first meets them: the
tree of a decoded graph, encoded again, is the original tree.

Decoding creates only the registry's classes, by their registered names (``object.__new__``
and the fields set into its ``__dict__``; no ``__init__``, no import of anything the data
names), and checks every node: its form, the class's fields exactly, the declared
:class:`ArraySpec` of a field, every array's dtype. Whatever does not fit is a CodecError.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from enum import Enum
from functools import cached_property
from typing import Any

import numpy as np

#: The array and scalar dtypes a graph may hold (numpy's ``dtype.str``): no objects, no
#: strings, no structured or big-endian types.
DTYPES = frozenset({"|b1", "|u1", "|i1", "<u2", "<i2", "<u4", "<i4", "<u8", "<i8",
                    "<f2", "<f4", "<f8"})


class CodecError(ValueError):
    """A graph that cannot be encoded, or a tree that is not one :func:`encode` writes."""

    def __init__(self, message: str, where: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.message, self.where = message, where

    def within(self, key: str) -> CodecError:
        return CodecError(self.message, (key,) + self.where)

    def __str__(self) -> str:
        return f"{''.join(self.where) or 'the root'}: {self.message}" if self.where else \
            self.message


@dataclass(frozen=True)
class ArraySpec:
    """What a registered class's field holds: an array of ``dtype`` (numpy's ``dtype.str``,
    e.g. ``"<f8"``) and ``shape`` (None: any length on that axis), or None when
    ``optional``."""

    dtype: str
    shape: tuple[int | None, ...]
    optional: bool = False

    def check(self, value: Any) -> None:
        if value is None and self.optional:
            return
        if not isinstance(value, np.ndarray):
            raise CodecError(f"expected an array, found {type(value).__name__}")
        if value.dtype.str != self.dtype:
            raise CodecError(f"expected a {self.dtype} array, found {value.dtype.str}")
        if len(value.shape) != len(self.shape) or \
                any(n is not None and n != m for n, m in zip(self.shape, value.shape)):
            raise CodecError(f"expected an array of shape {_shape_words(self.shape)}, "
                             f"found {value.shape}")


def _shape_words(shape: tuple[int | None, ...]) -> str:
    return "(" + ", ".join("n" if n is None else str(n) for n in shape) + \
        ("," if len(shape) == 1 else "") + ")"


@dataclass(frozen=True)
class _Entry:
    cls: type
    fields: tuple[str, ...]
    caches: frozenset[str]
    specs: Mapping[str, ArraySpec]


class Registry:
    """The classes and enums a graph may hold, each by a name of its own (its ``__qualname__``
    unless given), the only ones :func:`decode` creates."""

    def __init__(self) -> None:
        self._by_type: dict[type, tuple[str, _Entry]] = {}
        self._by_name: dict[str, _Entry] = {}
        self._enums_by_type: dict[type, str] = {}
        self._enums_by_name: dict[str, type[Enum]] = {}

    def add(self, cls: type, fields: Iterable[str] | None = None, *,
            arrays: Mapping[str, ArraySpec] | None = None, name: str | None = None) -> None:
        """Register ``cls``: a dataclass (its fields; ``fields`` None) or a plain class whose
        instances hold exactly the attributes ``fields``; ``arrays`` what some fields hold."""
        name = name or cls.__qualname__
        if name in self._by_name or name in self._enums_by_name:
            raise ValueError(f"{name}: registered twice")
        if fields is None:
            if not dataclasses.is_dataclass(cls):
                raise ValueError(f"{name}: not a dataclass; give its fields")
            fields = [f.name for f in dataclasses.fields(cls)]
        fields = tuple(fields)
        specs = dict(arrays or {})
        if not set(specs) <= set(fields):
            raise ValueError(f"{name}: array specs of fields it has not: {set(specs) - set(fields)}")
        caches = frozenset(k for c in cls.__mro__ for k, v in vars(c).items()
                           if isinstance(v, cached_property))
        entry = _Entry(cls, fields, caches, specs)
        self._by_type[cls] = name, entry
        self._by_name[name] = entry

    def add_enum(self, cls: type[Enum], name: str | None = None) -> None:
        name = name or cls.__qualname__
        if name in self._by_name or name in self._enums_by_name:
            raise ValueError(f"{name}: registered twice")
        self._enums_by_type[cls] = name
        self._enums_by_name[name] = cls


# ----------------------------------------------------------------------------- encoding


class _Encoder:
    def __init__(self, registry: Registry) -> None:
        self.registry = registry
        self.ids: dict[int, int] = {}  # id(object) -> its id in the tree
        self.keep: list[Any] = []  # (the objects numbered stay alive while ids are compared)
        self.open_tuples: set[int] = set()
        self.arrays: dict[str, np.ndarray] = {}

    def _number(self, obj: Any) -> int:
        n = len(self.ids)
        self.ids[id(obj)] = n
        self.keep.append(obj)
        return n

    def node(self, obj: Any) -> Any:
        t = type(obj)
        if obj is None or t is bool or t is int or t is str:
            return obj
        if t is float:
            return obj if math.isfinite(obj) else ["float", repr(obj)]
        seen = self.ids.get(id(obj))
        if seen is not None:
            if seen in self.open_tuples:
                raise CodecError("a tuple that contains itself")
            return ["ref", seen]
        if t is np.ndarray:
            if obj.dtype.str not in DTYPES:
                raise CodecError(f"an array of dtype {obj.dtype} (not one of the kept dtypes)")
            n = self._number(obj)
            self.arrays[f"a{n}"] = obj
            return ["array", n]
        if isinstance(obj, np.generic):
            if obj.dtype.str not in DTYPES:
                raise CodecError(f"a numpy scalar of dtype {obj.dtype}")
            return ["scalar", obj.dtype.str, self.node(obj.item())]
        if isinstance(obj, Enum):
            name = self.registry._enums_by_type.get(t)
            if name is None:
                raise CodecError(f"{t.__module__}.{t.__qualname__} is not a registered enum")
            return ["enum", name, self.node(obj.value)]
        if t is list:
            n = self._number(obj)
            return ["list", n, self._items(obj)]
        if t is tuple:
            n = self._number(obj)
            self.open_tuples.add(n)
            items = self._items(obj)
            self.open_tuples.discard(n)
            return ["tuple", n, items]
        if t is deque:
            n = self._number(obj)
            return ["deque", n, obj.maxlen, self._items(obj)]
        if t is dict:
            n = self._number(obj)
            pairs = []
            for i, (k, v) in enumerate(obj.items()):
                try:
                    pairs.append([self.node(k), self.node(v)])
                except CodecError as exc:
                    raise exc.within(f"[{k!r}]" if type(k) in (int, str) else f"[key {i}]") from None
            return ["dict", n, pairs]
        found = self.registry._by_type.get(t)
        if found is None:
            raise CodecError(f"{t.__module__}.{t.__qualname__} is not a registered type "
                             "(a checkpoint keeps data only)")
        name, entry = found
        state = getattr(obj, "__dict__", None)
        if state is None:
            raise CodecError(f"{name} has no attributes to keep")
        kept = set(state) - entry.caches
        if kept != set(entry.fields):
            extra, missing = sorted(kept - set(entry.fields)), sorted(set(entry.fields) - kept)
            raise CodecError(f"{name}'s attributes are not the registered ones (not registered: "
                             f"{', '.join(extra) or 'none'}; missing: {', '.join(missing) or 'none'})")
        n = self._number(obj)
        fields = {}
        for f in entry.fields:
            try:
                fields[f] = self.node(state[f])
            except CodecError as exc:
                raise exc.within(f".{f}") from None
        return ["object", n, name, fields]

    def _items(self, items: Iterable[Any]) -> list[Any]:
        return _each(items, self.node)


def _each(items: Iterable[Any], node: Callable[[Any], Any]) -> list[Any]:
    """``node`` of each of ``items``; an error names the item's place (``[i]``)."""
    out = []
    for i, x in enumerate(items):
        try:
            out.append(node(x))
        except CodecError as exc:
            raise exc.within(f"[{i}]") from None
    return out


def encode(root: Any, registry: Registry) -> tuple[Any, dict[str, np.ndarray]]:
    """``(tree, arrays)``: ``root``'s graph as a JSON-able tree and the arrays it holds, by
    name (``a<id>``, in the order met). CodecError naming where in the graph something is
    not kept."""
    enc = _Encoder(registry)
    return enc.node(root), enc.arrays


# ----------------------------------------------------------------------------- decoding

_FLOATS = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
_PENDING = object()  # a tuple's number while its items are decoded


class _Decoder:
    def __init__(self, registry: Registry, array: Callable[[str], np.ndarray]) -> None:
        self.registry, self.array = registry, array
        self.table: dict[int, Any] = {}

    def _register(self, n: Any, obj: Any) -> None:
        if type(n) is not int or n != len(self.table):
            raise CodecError(f"object number {n!r} out of order")
        self.table[n] = obj

    def node(self, node: Any) -> Any:
        t = type(node)
        if node is None or t is bool or t is int or t is str or t is float:
            return node
        if t is not list or not node or type(node[0]) is not str:
            raise CodecError(f"not a node: {type(node).__name__}")
        tag, args = node[0], node[1:]
        if tag == "ref":
            _arity(node, 1)
            n = args[0]
            if type(n) is not int or n not in self.table:
                raise CodecError(f"a reference to no object ({n!r})")
            if self.table[n] is _PENDING:
                raise CodecError("a tuple that contains itself")
            return self.table[n]
        if tag == "float":
            _arity(node, 1)
            if args[0] not in _FLOATS:
                raise CodecError(f"not a float: {args[0]!r}")
            return _FLOATS[args[0]]
        if tag == "array":
            _arity(node, 1)
            n = args[0]
            a = self.array(f"a{n}") if type(n) is int else None
            if not isinstance(a, np.ndarray) or a.dtype.str not in DTYPES:
                raise CodecError(f"not an array of a kept dtype: a{n!r}")
            self._register(n, a)
            return a
        if tag == "scalar":
            _arity(node, 2)
            dtype, value = args[0], self.node(args[1])
            if dtype not in DTYPES or type(value) not in (bool, int, float):
                raise CodecError(f"not a numpy scalar: {dtype!r}, {value!r}")
            try:
                with np.errstate(all="raise"):
                    out = np.array(value, dtype=np.dtype(dtype))[()]
            except (OverflowError, ValueError, FloatingPointError):
                raise CodecError(f"{value!r} is not a {dtype} value") from None
            if out.item() != value and not (value != value and out != out):
                raise CodecError(f"{value!r} is not a {dtype} value")
            return out
        if tag == "enum":
            _arity(node, 2)
            cls = self.registry._enums_by_name.get(args[0]) if type(args[0]) is str else None
            if cls is None:
                raise CodecError(f"not a registered enum: {args[0]!r}")
            try:
                return cls(self.node(args[1]))
            except (ValueError, TypeError):
                raise CodecError(f"not a {args[0]}: {args[1]!r}") from None
        if tag in ("list", "tuple"):
            _arity(node, 2)
            items = _list(args[1])
            if tag == "list":
                out: list = []
                self._register(args[0], out)
                out.extend(self._items(items))
                return out
            n = args[0]
            self._register(n, _PENDING)  # (numbered before its items, as encode did)
            out_t = tuple(self._items(items))
            self.table[n] = out_t
            return out_t
        if tag == "deque":
            _arity(node, 3)
            maxlen, items = args[1], _list(args[2])
            if maxlen is not None and (type(maxlen) is not int or maxlen < 0 or
                                       len(items) > maxlen):
                raise CodecError(f"not a deque's maxlen: {maxlen!r} ({len(items)} items)")
            dq: deque = deque(maxlen=maxlen)
            self._register(args[0], dq)
            dq.extend(self._items(items))
            return dq
        if tag == "dict":
            _arity(node, 2)
            pairs = _list(args[1])
            d: dict = {}
            self._register(args[0], d)
            for i, pair in enumerate(pairs):
                if type(pair) is not list or len(pair) != 2:
                    raise CodecError("not a key and its value").within(f"[key {i}]")
                try:
                    k = self.node(pair[0])
                    if k in d:
                        raise CodecError("a key given twice")
                    d[k] = self.node(pair[1])
                except TypeError:  # (an unhashable key)
                    raise CodecError("not a key").within(f"[key {i}]") from None
                except CodecError as exc:
                    raise exc.within(f"[key {i}]") from None
            return d
        if tag == "object":
            _arity(node, 3)
            name, fields = args[1], args[2]
            entry = self.registry._by_name.get(name) if type(name) is str else None
            if entry is None:
                raise CodecError(f"not a registered type: {name!r}")
            if type(fields) is not dict or set(fields) != set(entry.fields):
                got = set(fields) if type(fields) is dict else set()
                raise CodecError(f"{name}'s fields are not the registered ones (unknown: "
                                 f"{', '.join(sorted(got - set(entry.fields))) or 'none'}; "
                                 f"missing: {', '.join(sorted(set(entry.fields) - got)) or 'none'})")
            obj = object.__new__(entry.cls)
            self._register(args[0], obj)
            state = {}
            for f in entry.fields:
                try:
                    state[f] = value = self.node(fields[f])
                    spec = entry.specs.get(f)
                    if spec is not None:
                        spec.check(value)
                except CodecError as exc:
                    raise exc.within(f".{f}") from None
            vars(obj).update(state)
            return obj
        raise CodecError(f"not a node: {tag!r}")

    def _items(self, items: list) -> list:
        return _each(items, self.node)


def _arity(node: list, n: int) -> None:
    if len(node) != n + 1:
        raise CodecError(f"a {node[0]!r} node of {len(node) - 1} values, not {n}")


def _list(items: Any) -> list:
    if type(items) is not list:
        raise CodecError(f"expected a list of items, found {type(items).__name__}")
    return items


def decode(tree: Any, registry: Registry, array: Callable[[str], np.ndarray]) -> Any:
    """The graph :func:`encode` gave ``tree`` for, its arrays got by name from ``array``
    (which returns anything but an array, or raises CodecError, for a name it has not).
    CodecError when ``tree`` is not such a tree."""
    return _Decoder(registry, array).node(tree)
