"""Running the CLI in-process, as the tests of its checks do."""

from __future__ import annotations

from click.testing import CliRunner

from monovo_cli.cli import main


def run(*args) -> tuple[int, str]:
    r = CliRunner().invoke(main, [str(a) for a in args])
    return r.exit_code, r.output


def one_error_line(output: str) -> str:
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: "), output
    return lines[0]


