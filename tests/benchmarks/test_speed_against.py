"""``benchmarks.speed --against REV``: the earlier commit's package is the one its child
process runs, and a commit git does not know is a clear exit."""

from __future__ import annotations

import subprocess
import sys

import pytest

from benchmarks.speed import ROOT, _child_env, package_at


def test_the_child_runs_the_package_of_the_commit_named(tmp_path):
    tree = package_at("HEAD", tmp_path / "base")
    assert (tree / "monovo_cli" / "__init__.py").is_file()
    head = subprocess.run(["git", "-C", str(ROOT), "show", "HEAD:monovo_cli/version.py"],
                          capture_output=True, check=True).stdout
    assert (tree / "monovo_cli" / "version.py").read_bytes() == head
    env = _child_env(tree)
    where = subprocess.run([sys.executable, "-c", "import monovo_cli; print(monovo_cli.__file__)"],
                           env=env, cwd=tree.parent, capture_output=True, text=True,
                           check=True).stdout.strip()
    assert where.startswith(str(tree))


def test_a_tree_without_the_package_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SystemExit, match="imports monovo_cli from"):
        _child_env(tmp_path / "empty")


def test_an_unknown_commit_is_a_clear_exit(tmp_path):
    with pytest.raises(SystemExit, match="git archive no-such-commit"):
        package_at("no-such-commit", tmp_path / "base")
