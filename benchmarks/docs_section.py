"""A benchmark's own section of docs/benchmarks.md, rewritten by the benchmark.

The section lies between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``; a benchmark run with
``--write-docs`` replaces what is between them (the page's other text is left as it is), or
appends the section under a heading when the page has none yet."""

from __future__ import annotations

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
