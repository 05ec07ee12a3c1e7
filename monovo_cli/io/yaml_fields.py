"""Reading and writing validated YAML fields: one ConfigError line per problem.

The generic half of :mod:`monovo_cli.io.config` (and of any YAML file monovo reads): a
loader that refuses a key given twice, numbers and whole numbers from what PyYAML returns
(YAML 1.1 reads ``1e3`` as a string: such plain numbers are accepted), key checks with a
"did you mean" hint, short renderings of values for messages, and float literals that
round-trip exactly. Every failure is a :class:`~monovo_cli.errors.ConfigError` of one line:
the file, the field, what is wrong.
"""

from __future__ import annotations

import difflib
import math
import re
from pathlib import Path
from typing import Any

import yaml

from monovo_cli.errors import ConfigError

# PyYAML (YAML 1.1) reads 1e3 and 1.5e3 as strings; accept such plain numbers.
NUMBER_RE = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def fail(name: str, message: str) -> ConfigError:
    """The ConfigError ``name: message`` on one line (newlines in values are escaped)."""
    return ConfigError(f"{name}: {message}".replace("\n", "\\n").replace("\r", "\\r"))


def show(value: Any) -> str:
    """A short one-line rendering of a YAML value for messages (never expands aliases)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        if abs(value) < 10**30:
            return str(value)
        return f"a {int(value.bit_length() * 0.30103) + 1}-digit number"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, str):
        s = value if len(value) <= 40 else value[:37] + "..."
        return repr(s)
    if isinstance(value, (list, tuple)):
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return "a mapping"
    return f"a {type(value).__name__}"


def number(name: str, where: str, value: Any) -> float:
    """A finite float from a YAML value, or ConfigError."""
    if isinstance(value, bool) or value is None:
        raise fail(name, f"{where} must be a number, got {show(value)}")
    if isinstance(value, str):
        if not NUMBER_RE.fullmatch(value.strip()):
            raise fail(name, f"{where} must be a number, got {show(value)}")
        value = value.strip()
    if not isinstance(value, (int, float, str)):
        raise fail(name, f"{where} must be a number, got {show(value)}")
    try:
        x = float(value)
    except (OverflowError, ValueError):
        x = math.inf
    if not math.isfinite(x):
        raise fail(name, f"{where} must be a finite number, got {show(value)}")
    return x


def integer(name: str, where: str, value: Any) -> int:
    """A whole number from a YAML value (688 or 688.0), or ConfigError."""
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    x = number(name, where, value)
    if not x.is_integer():
        raise fail(name, f"{where} must be a whole number, got {show(value)}")
    return int(x)


def numbers(name: str, where: str, value: Any, lengths: tuple[int, ...], what: str) -> list[float]:
    """A list of finite floats of one of ``lengths`` (``what`` describes it), or ConfigError."""
    if not isinstance(value, (list, tuple)) or len(value) not in lengths:
        raise fail(name, f"{where} must be {what}, got {show(value)}")
    return [number(name, f"{where}[{i}]", v) for i, v in enumerate(value)]


def check_keys(name: str, found: dict, allowed: tuple[str, ...], prefix: str) -> None:
    """ConfigError naming the first key of ``found`` not in ``allowed`` (with a close match)."""
    for key in found:
        if isinstance(key, str) and key in allowed:
            continue
        plain = isinstance(key, str) and key.isprintable() and 0 < len(key) <= 40
        shown = key if plain else show(key)
        close = difflib.get_close_matches(str(key), allowed, n=1)
        hint = f"did you mean '{close[0]}'?" if close else f"expected one of {', '.join(allowed)}"
        raise fail(name, f"unknown key '{prefix}{shown}' ({hint})")


def mapping(name: str, where: str, value: Any, what: str) -> dict:
    """``value`` if it is a mapping (of ``what``), else ConfigError."""
    if not isinstance(value, dict):
        raise fail(name, f"{where} must be a mapping of {what}, got {show(value)}")
    return value


def positive(name: str, where: str, value: Any) -> float:
    """A finite float > 0 from a YAML value, or ConfigError."""
    x = number(name, where, value)
    if x <= 0:
        raise fail(name, f"{where} must be > 0, got {show(value)}")
    return x


class UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice in one mapping."""

    def construct_mapping(self, node, deep=False):
        """SafeLoader's mapping of ``node``; ConstructorError for a key given twice."""
        if isinstance(node, yaml.MappingNode):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    duplicate = key in seen
                    seen.add(key)
                except TypeError:  # unhashable: SafeLoader reports it
                    continue
                if duplicate:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"key {show(key)} is given twice", key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: Path, name: str, what: str) -> Any:
    """Parse a YAML file; every failure is one ConfigError line naming ``name``."""
    try:
        data = path.read_bytes()
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise fail(name, f"cannot read {what} ({reason})") from None
    try:
        return yaml.load(data, Loader=UniqueKeyLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = " ".join(str(exc.problem or exc.context or "syntax error").split())
        raise fail(name, f"not valid YAML{where}: {problem}") from None
    except yaml.YAMLError as exc:
        msg = " ".join(str(exc).split())
        raise fail(name, f"not valid YAML: {msg}") from None
    except (ValueError, TypeError, OverflowError, RecursionError, MemoryError) as exc:
        # e.g. a date such as 2001-13-45, or absurdly deep nesting
        msg = " ".join(str(exc).split())[:80] or type(exc).__name__
        raise fail(name, f"not valid YAML: {msg}") from None


def yaml_float(x: float) -> str:
    """A float as a YAML 1.1 float literal that round-trips exactly (1e-20 -> 1.0e-20)."""
    s = repr(float(x))
    if "e" in s:
        mantissa, exponent = s.split("e")
        if "." not in mantissa:
            mantissa += ".0"
        if exponent[0] not in "+-":
            exponent = "+" + exponent
        s = f"{mantissa}e{exponent}"
    elif "." not in s:
        s += ".0"
    return s


def flow_list(values, fmt) -> str:
    """``values`` as a YAML flow sequence, each written by ``fmt``: ``[a, b, c]``."""
    return "[" + ", ".join(fmt(v) for v in values) + "]"
