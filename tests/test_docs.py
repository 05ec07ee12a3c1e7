"""The commands the documents give run as written."""

from __future__ import annotations

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
