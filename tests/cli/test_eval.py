"""monovo eval's command line: its formats are the readers', its help says how it pairs."""

from types import SimpleNamespace

from click.testing import CliRunner

from monovo_cli.cli import evaluate, main
from monovo_cli.io.trajectories import FORMATS
from monovo_cli.pipeline.evaluate import PLOT_NAMES


def test_the_format_choices_are_the_readers():
    assert evaluate.FORMATS == FORMATS


def test_help_says_how_poses_without_timestamps_are_paired():
    r = CliRunner().invoke(main, ["eval", "--help"])
    assert r.exit_code == 0
    text = " ".join(r.output.split())
    for words in ("KITTI poses", "EuRoC CSV", "by frame: pose i of the estimate with pose i of "
                  "the truth", "--partial", "[default: 1,5,10 m]", "--plots DIR", "--json [FILE]"):
        assert words in text, words


def test_json_file_is_refused_if_it_exists_unless_overwrite(monkeypatch, tmp_path):
    import monovo_cli.pipeline.evaluate as evaluate_pipeline

    seen = []

    def fake_run_eval(estimate, groundtruth, options, *, plots_dir=None, json_path=None):
        seen.append(json_path)
        json_path.write_text("{}\n")
        return SimpleNamespace(plots=(), text=lambda: "ATE 0.1 m", as_dict=lambda: {})

    monkeypatch.setattr(evaluate_pipeline, "run_eval", fake_run_eval)
    out = tmp_path / "errors.json"
    out.write_text("kept\n")
    args = ["eval", "est.tum", "gt.tum", "--json", str(out)]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2 and not seen, r.output
    assert r.output.strip().splitlines() == [
        f"Error: {out}: already exists; use --overwrite or another --json FILE"]
    assert out.read_text() == "kept\n"
    r = CliRunner().invoke(main, [*args, "--overwrite"])
    assert r.exit_code == 0, r.output
    assert seen == [out] and out.read_text() == "{}\n"
    plots = tmp_path / "plots"
    plots.mkdir()
    (plots / PLOT_NAMES[0]).write_bytes(b"kept")
    r = CliRunner().invoke(main, ["eval", "est.tum", "gt.tum", "--plots", str(plots)])
    assert r.exit_code == 2 and f"already holds plots ({PLOT_NAMES[0]})" in r.output, r.output
    assert seen == [out] and (plots / PLOT_NAMES[0]).read_bytes() == b"kept"
