"""A library default read from the library's source, so that help imports no numpy or OpenCV.

``monovo --help`` and each command's help show defaults written in the library only
(:class:`~monovo_cli.cli.options.LibraryDefault`). Importing the modules that hold them
would load numpy and OpenCV, the synthetic drives, the evaluation: most of a second before
a line of help. :func:`library_value` reads the value from the module's source instead when
it is written there as a literal, or as a name bound to one; anything else is imported.
"""

from __future__ import annotations

import ast
import functools
import importlib
import inspect
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


class _NotLiteral(LookupError):
    """The default is not a literal the source shows (an expression, a call): import it."""


def library_value(module: str, function: str | None, name: str) -> Any:
    """The default of the keyword argument ``name`` of ``module.function``, or the
    module-level constant ``module.name`` when ``function`` is None.

    Read from the module's source when it is written there as a literal, or as a name bound
    to one (in the module, or imported into it from another monovo_cli module), so that help
    imports neither the module nor what it needs (numpy, OpenCV); imported otherwise, and
    when the module is loaded already (e.g. changed by a test), which gives the same value.
    """
    if module not in sys.modules:
        try:
            return _source_value(module, function, name)
        except _NotLiteral:
            pass
    loaded = importlib.import_module(module)
    if function is None:
        return getattr(loaded, name)
    return inspect.signature(getattr(loaded, function)).parameters[name].default


@functools.cache
def _source_tree(module: str) -> ast.Module:
    """The parsed source of the monovo_cli module ``module``, found beside this package."""
    root, *parts = module.split(".")
    if root != "monovo_cli" or not parts:
        raise _NotLiteral(module)
    base = Path(__file__).resolve().parents[1].joinpath(*parts)
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return ast.parse(path.read_text(encoding="utf-8"), str(path))
    raise _NotLiteral(module)


def _source_value(module: str, function: str | None, name: str, depth: int = 0) -> Any:
    """:func:`library_value` from the source only; _NotLiteral when it does not say."""
    if depth > 8:
        raise _NotLiteral(f"{module}.{name}")
    tree = _source_tree(module)
    if function is None:
        return _bound_value(module, tree, name, depth)
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == function:
            a = node.args
            positional = [*a.posonlyargs, *a.args]
            defaults = dict(zip([p.arg for p in positional[len(positional) - len(a.defaults):]],
                                a.defaults))
            defaults.update((p.arg, d) for p, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None)
            if name not in defaults:
                raise _NotLiteral(f"{module}.{function}({name})")
            return _literal(module, defaults[name], depth)
    raise _NotLiteral(f"{module}.{function}")


def _literal(module: str, node: ast.expr, depth: int) -> Any:
    if isinstance(node, ast.Name):
        return _source_value(module, None, node.id, depth + 1)
    try:
        return ast.literal_eval(node)
    except ValueError:
        raise _NotLiteral(ast.dump(node)) from None


def _bound_value(module: str, tree: ast.Module, name: str, depth: int) -> Any:
    """The value the top-level statements of ``module`` last bind ``name`` to: a literal, or
    a name imported from another module (absolute imports only)."""
    found: Callable[[], Any] | None = None
    for node in tree.body:
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if node.value is not None and any(isinstance(t, ast.Name) and t.id == name
                                              for t in targets):
                found = functools.partial(_literal, module, node.value, depth)
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    if node.level or not node.module:
                        raise _NotLiteral(f"{module}.{name}")
                    found = functools.partial(_source_value, node.module, None, alias.name,
                                              depth + 1)
        elif getattr(node, "name", None) == name:  # a def or class of that name
            found = None
    if found is None:
        raise _NotLiteral(f"{module}.{name}")
    return found()
