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
