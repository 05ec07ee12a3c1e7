"""The sample sequences track to the committed outputs, byte for byte.

Refactors must not move a number. When a change to the estimator is meant to move them,
regenerate the files with `python tests/test_golden.py` and say why in the commit.
"""

import shutil
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from monovo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "data" / "golden"
SEQUENCES = ("navcam_drive", "exposure_drive", "paper_pairs/pair_0000", "paper_pairs/pair_0001",
             "paper_pairs/pair_0002")
FILES = ("motion.csv", "trajectory.csv", "trajectory.tum")


def _track(seq: str, out: Path) -> None:
    r = CliRunner().invoke(main, ["track", str(ROOT / "sample_sequences" / seq), "-o", str(out),
                                  "-q", "--overwrite"])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("seq", SEQUENCES)
def test_sample_outputs_are_byte_identical(seq, tmp_path):
    _track(seq, tmp_path)
    for name in FILES:
        want = (GOLDEN / seq.replace("/", "_") / name).read_bytes()
        assert (tmp_path / name).read_bytes() == want, f"{seq}/{name} differs from tests/data/golden"


if __name__ == "__main__":  # regenerate: python tests/test_golden.py
    for seq in SEQUENCES:
        out = GOLDEN / seq.replace("/", "_")
        tmp = out.with_name(out.name + ".tmp")
        _track(seq, tmp)
        out.mkdir(parents=True, exist_ok=True)
        for name in FILES:
            shutil.copyfile(tmp / name, out / name)
        shutil.rmtree(tmp)
    sys.exit(0)
