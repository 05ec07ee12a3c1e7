"""The commands the documents give run as written."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from tests.helpers.cli import run

ROOT = Path(__file__).resolve().parents[1]


def test_sample_sequences_readme_commands_run_after_the_quickstart(tmp_path, monkeypatch):
    """The commands of sample_sequences/README.md, in order, into tmp_path instead of out/;
    twice, as after the guide's quickstart, which writes the same outputs."""
    text = (ROOT / "sample_sequences" / "README.md").read_text()
    block = text.split("```")[-2]
    commands = [shlex.split(line) for line in block.strip().splitlines()]
    assert commands and all(c[0] == "monovo" for c in commands)
    monkeypatch.chdir(ROOT)
    for _ in range(2):
        for c in commands:
            args = [a.replace("out/", f"{tmp_path}/out/") for a in c[1:]]
            code, output = run(*args, "-q")
            assert code == 0, (c, output)
    assert (tmp_path / "out" / "navcam_drive" / "overlay.mp4").is_file()


def test_architecture_five_lines_track_the_sample_drive(monkeypatch, capsys):
    """docs/architecture.md's "From Python" block, run as written from the repository root:
    five lines that track the sample drive and print its 60 frames."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = text.split("```python\n")[1].split("```")[0]
    assert len([line for line in block.splitlines() if line.strip()]) == 5
    monkeypatch.chdir(ROOT)
    exec(compile(block, "architecture.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:2] == ["60", "0"] and lines[0].endswith(" m")
    assert len(lines) == 61 and lines[1].startswith("0 ok")


RESULTS = ROOT / "docs" / "benchmarks.md"
SECTION = re.compile(r"<!-- ([\w-]+):begin -->\n(.*?)<!-- \1:end -->", re.S)


def test_the_results_page_is_short_and_every_table_is_written_by_a_benchmark():
    """docs/benchmarks.md reads in five minutes; each of its tables sits in a section a
    benchmark rewrites, the section names the command that wrote it, and that module exists."""
    text = RESULTS.read_text(encoding="utf-8")
    assert len(text.splitlines()) < 600
    sections = SECTION.findall(text)
    assert {"soak", "honesty", "checkpoint", "real-split", "real-sequences", "drives", "terrain",
            "paper-tables", "crb", "peers", "speed", "memory", "batch"} <= {n for n, _ in sections}
    outside = SECTION.sub("", text)
    assert not [line for line in outside.splitlines() if line.lstrip().startswith("|")]
    for name, body in sections:
        modules = re.findall(r"`python -m benchmarks\.(\w+)", body)
        assert modules, f"section {name!r} names no `python -m benchmarks.X` command"
        for module in modules:
            assert (ROOT / "benchmarks" / f"{module}.py").is_file(), (name, module)
    assert "diagnostic run" not in text.lower()


def _slug(heading: str) -> str:
    """A heading's anchor as GitHub renders it."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_links_between_the_documents_reach_a_file_and_a_heading():
    """Every relative link of README.md and docs/*.md names a file that exists and, with a
    ``#fragment``, a heading of that file."""
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            path, _, fragment = target.partition("#")
            file = (doc.parent / path).resolve() if path else doc
            assert file.exists(), (doc.name, target)
            if fragment and file.suffix == ".md":
                headings = re.findall(r"^#+ (.+)$", file.read_text(encoding="utf-8"), re.M)
                assert fragment in {_slug(h) for h in headings}, (doc.name, target)


def test_the_method_page_holds_no_run_figure_and_links_the_results():
    """docs/algorithm.md explains the method; what a run measured is on the results page."""
    text = (ROOT / "docs" / "algorithm.md").read_text(encoding="utf-8")
    assert "](benchmarks.md)" in text
    for pattern in (r"diagnostic", r"we measured", r"frames/s", r"\d ?ms\b", r"\d ?ns\b",
                    r"\d\.\d{2,} ?%", r"\d(\.\d+)? ?% off", r"\dx ECC",
                    r"std of error", r"of (its|their) std", r"docs/benchmarks\.md[,\"]"):
        found = re.search(pattern, text, re.I)
        assert found is None, (pattern, text[max(0, found.start() - 80):found.end() + 80])
