"""Start-up: each command imports what it needs, no more (issue 26, "Start fast").

Help and --version load neither numpy nor OpenCV (their defaults are read from the
library's source, see monovo_cli.cli.library_source.library_value); tracking loads neither the
synthetic drives nor the drawing code. Each check runs in a fresh interpreter, whose
``sys.modules`` holds only what the command imported.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import monovo_cli.cli.library_source as library_source
from monovo_cli.cli import main

ROOT = Path(__file__).resolve().parents[2]

#: ``monovo ARGS`` whose output is help or the version.
HELP_ARGS = [["--help"], ["--version"], *([name, "--help"] for name in sorted(main.commands))]

# Runs ``python -m monovo_cli ARGS`` for each ARGS of argv[1] (JSON) in this one interpreter,
# then prints {"outputs": [...], "loaded": [numpy/cv2 if loaded]} as JSON.
_RUN_HELP = """
import contextlib, io, json, runpy, sys
outputs = []
for args in json.loads(sys.argv[1]):
    sys.argv, out = ["monovo", *args], io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            runpy.run_module("monovo_cli", run_name="__main__")
        except SystemExit as exc:
            assert exc.code in (0, None), (args, exc.code)
    outputs.append(out.getvalue())
print(json.dumps({"outputs": outputs,
                  "loaded": sorted({"numpy", "cv2"} & set(sys.modules))}))
"""


def _python(code: str, *args: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "100"}
    run = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return run.stdout


@pytest.fixture(scope="module")
def fresh_help() -> dict:
    """The help and version outputs of a fresh ``python -m monovo_cli``, and what it loaded."""
    return json.loads(_python(_RUN_HELP, json.dumps(HELP_ARGS)))


def test_help_and_version_load_neither_numpy_nor_opencv(fresh_help):
    assert fresh_help["loaded"] == []
    for args, text in zip(HELP_ARGS, fresh_help["outputs"]):
        assert ("monovo, version" if args == ["--version"] else "Usage:") in text, args


def test_help_read_from_the_source_is_the_help_of_the_imported_library(fresh_help,
                                                                       monkeypatch):
    """The defaults help reads from the library's source are the values the library has
    when imported: every help text, read both ways, is the same."""

    def import_it(*args, **kwargs):
        raise library_source._NotLiteral("import it")

    monkeypatch.setattr(library_source, "_source_value", import_it)
    monkeypatch.setenv("COLUMNS", "100")
    for args, text in zip(HELP_ARGS, fresh_help["outputs"]):
        out = io.StringIO()
        with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as exit_:
            main.main(args=args, prog_name="monovo")
        assert exit_.value.code in (0, None)
        assert out.getvalue() == text, args


def test_a_library_default_is_read_through_the_names_it_is_bound_to():
    """A default written as a name (here imported from another module) is followed to its
    literal; one that is not a literal is left to the import."""
    assert (library_source._source_value("monovo_cli.evaluation.metrics", None, "MAX_DT")
            == __import__("monovo_cli.evaluation.sync").evaluation.sync.MAX_DT)
    with pytest.raises(library_source._NotLiteral):
        library_source._source_value("monovo_cli.cli.options", None, "seq_argument")


def test_tracking_loads_neither_synth_nor_viz(small_drive):
    """track_frames and ``monovo track SEQ -o -`` track the whole drive (made beforehand, in
    this process) without the synthetic drives or the drawing code."""
    code = (
        "import contextlib, io, runpy, sys, monovo_cli\n"
        "run = monovo_cli.track_frames(sys.argv[1])\n"
        "assert run.frames == 10, run.frames\n"
        "sys.argv = ['monovo', 'track', sys.argv[1], '-o', '-', '-q']\n"
        "with contextlib.redirect_stdout(io.StringIO()) as rows:\n"
        "    try:\n"
        "        runpy.run_module('monovo_cli', run_name='__main__')\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code in (0, None), exc.code\n"
        "assert len(rows.getvalue().splitlines()) >= 10, rows.getvalue()\n"
        "print(sorted(m for m in sys.modules\n"
        "            if m.startswith(('monovo_cli.synth', 'monovo_cli.viz'))))\n"
    )
    assert _python(code, str(small_drive)).strip() == "[]"
