"""monovo eval's command line: its formats are the readers', its help says how it pairs."""

from click.testing import CliRunner

from monovo_cli.cli import evaluate, main
from monovo_cli.io.trajectories import FORMATS


def test_the_format_choices_are_the_readers():
    assert evaluate.FORMATS == FORMATS


def test_help_says_how_poses_without_timestamps_are_paired():
    r = CliRunner().invoke(main, ["eval", "--help"])
    assert r.exit_code == 0
    text = " ".join(r.output.split())
    for words in ("KITTI poses", "EuRoC CSV", "by frame: pose i of the estimate with pose i of "
                  "the truth", "--partial", "[default: 1,5,10 m]", "--plots DIR", "--json [FILE]"):
        assert words in text, words
