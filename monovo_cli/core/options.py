"""Options dataclasses from plain (JSON-able) dicts, the inverse of :func:`dataclasses.asdict`.

:class:`~monovo_cli.core.odometry.TrackOptions` (with the
:class:`~monovo_cli.core.estimate.EstimatorOptions` it nests) is the one place where a
tracking default is written. The command line builds it from the options the user gave;
``monovo batch`` sends it to its workers as ``dataclasses.asdict(options)`` and rebuilds it
there with :func:`options_from_dict`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")


def options_from_dict(cls: type[T], data: Mapping[str, Any]) -> T:
    """An instance of the frozen dataclass ``cls`` from ``data``, a dict of some of its fields.

    Fields missing from ``data`` keep the dataclass defaults; a field holding a dataclass
    (e.g. ``estimator``) may be given as a dict of some of its own fields, so that
    ``options_from_dict(cls, dataclasses.asdict(x)) == x`` and
    ``options_from_dict(TrackOptions, {"estimator": {"robust": "tukey"}})`` changes only the
    M-estimator. Values are not converted (JSON keeps ints, floats, strings, None).

    Raises ValueError naming the keys that are not fields (a programming error, not bad input).
    """
    defaults = cls()
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(map(str, unknown))} of {cls.__name__}; "
                         f"expected some of {', '.join(names)}")
    values = {}
    for name, value in data.items():
        default = getattr(defaults, name)
        if dataclasses.is_dataclass(default) and isinstance(value, Mapping):
            value = options_from_dict(type(default), value)
        values[name] = value
    return cls(**values)
