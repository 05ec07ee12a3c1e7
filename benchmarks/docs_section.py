"""A benchmark's own section of docs/benchmarks.md, rewritten by the benchmark.

The section lies between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``; a benchmark run with
``--write-docs`` replaces what is between them (the page's other text is left as it is), or
appends the section under a heading when the page has none yet.

:func:`printed_section` wraps a benchmark's run: what the run prints to stdout (its machine
line, with the commit and the date, and its tables) becomes the section, under the exact
command that ran; :func:`writes_section` does so for a ``main()`` run with ``--write-docs``."""

from __future__ import annotations

import contextlib
import functools
import io
import shlex
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"


def write_section(name: str, title: str, text: str, page: Path = DOCS) -> None:
    """Replace section ``name`` of ``page`` with ``text`` (under ``## title`` if it is new)."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    body = f"{begin}\n{text.strip()}\n{end}"
    old = page.read_text(encoding="utf-8")
    if begin in old and end in old:
        head, rest = old.split(begin, 1)
        new = head + body + rest.split(end, 1)[1]
    else:
        new = old.rstrip("\n") + f"\n\n## {title}\n\n{body}\n"
    page.write_text(new, encoding="utf-8")


class _Tee(io.TextIOBase):
    """Writes to ``out`` and keeps a copy."""

    def __init__(self, out) -> None:
        self.out, self.copy = out, io.StringIO()

    def write(self, text: str) -> int:
        self.copy.write(text)
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


def command_line(module: str, argv: Sequence[str] | None = None) -> str:
    """``python -m MODULE ARGS`` as typed (``argv``: the arguments; default this process's)."""
    args = sys.argv[1:] if argv is None else list(argv)
    return shlex.join(["python", "-m", module, *args])


@contextlib.contextmanager
def printed_section(name: str, title: str, module: str, enabled: bool = True,
                    argv: Sequence[str] | None = None, page: Path | None = None) -> Iterator[None]:
    """While open, stdout is also kept; at the close (if ``enabled``) section ``name`` of
    ``page`` (default ``DOCS``) becomes the command that ran (:func:`command_line`) and what
    it printed."""
    if not enabled:
        yield
        return
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield
    text = f"`{command_line(module, argv)}`\n\n{tee.copy.getvalue().strip()}\n"
    page = DOCS if page is None else page
    write_section(name, title, text, page)
    print(f"wrote section {name!r} of {page}")


def writes_section(name: str, title: str, module: str) -> Callable:
    """Decorate a benchmark's ``main()`` (which parses ``sys.argv`` and accepts
    ``--write-docs``): run with ``--write-docs``, what it prints becomes section ``name``."""

    def decorate(main: Callable) -> Callable:
        @functools.wraps(main)
        def run(*args, **kwargs):
            with printed_section(name, title, module, "--write-docs" in sys.argv[1:]):
                return main(*args, **kwargs)

        return run

    return decorate
