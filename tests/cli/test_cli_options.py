"""The CLI's options: TrackOptions is their only source of defaults; batch ships them as JobOptions.

The library calls are replaced by fakes that record what the commands pass, so these tests
check the command line itself and run in well under a second.
"""

from __future__ import annotations

import dataclasses
import inspect
import json
import pickle
from pathlib import Path
from types import SimpleNamespace

import click
import pytest
from click.testing import CliRunner

import monovo_cli.core.options as core_options
import monovo_cli.pipeline.batch as batch
import monovo_cli.pipeline.track as track
from monovo_cli.cli import main
from monovo_cli.core.options import ALL_POINTS, EstimatorOptions, TrackOptions, options_from_dict
from monovo_cli.pipeline.batch_job import JobOptions

ALL_GIVEN = ["--levels", "3", "--threshold", "5", "--max-points", "all", "--robust", "tukey",
             "--reanchor-fraction", "0.5", "--no-photometric", "--max-step", "0.5,10"]
ALL_GIVEN_OPTIONS = TrackOptions(levels=3, threshold=5.0, max_points=ALL_POINTS,
                                 reanchor_fraction=0.5, max_step_m=0.5, max_step_deg=10.0,
                                 estimator=EstimatorOptions(robust="tukey", photometric=False))


@pytest.fixture
def calls(monkeypatch):
    """Fakes of the library calls of init, track and batch; each records its arguments."""
    seen: dict[str, tuple] = {}

    def fake_track(seq, params, out_dir, options, **kw):
        seen["track"] = (options, kw)
        return SimpleNamespace(mostly_lost=False)  # with -q the command prints nothing else

    def fake_init(seq, params, out, options, **kw):
        seen["init"] = (options, kw)
        raise click.exceptions.Exit(0)  # the command would print the model's levels

    def fake_batch(root, out, options, **kw):
        seen["batch"] = (options, kw)
        return batch.BatchSummary([], 0.1, Path(out) / "summary.csv", "local", 1)

    monkeypatch.setattr(track, "track_sequence", fake_track)
    monkeypatch.setattr(track, "init_model", fake_init)
    monkeypatch.setattr(batch, "run_batch", fake_batch)
    return seen


def _run(*args: str) -> None:
    r = CliRunner().invoke(main, [*args, "-q"])
    assert r.exit_code == 0, r.output


def test_unset_tracking_options_are_exactly_the_dataclass_defaults(calls, tmp_path):
    _run("track", "seq", "-o", str(tmp_path / "o"))
    _run("init", "seq", "-o", str(tmp_path / "m.npz"))
    _run("batch", "root", "-o", str(tmp_path / "b"))
    assert calls["track"][0] == TrackOptions()
    assert calls["init"][0] == TrackOptions()
    assert calls["batch"][0] == JobOptions()


def test_given_tracking_options_set_their_fields_and_only_those(calls, tmp_path):
    _run("track", "seq", "-o", str(tmp_path / "o"), *ALL_GIVEN)
    assert calls["track"][0] == ALL_GIVEN_OPTIONS
    _run("batch", "root", "-o", str(tmp_path / "b"), *ALL_GIVEN, "--prior", "wheel.csv")
    job = calls["batch"][0]
    assert job.track == ALL_GIVEN_OPTIONS
    assert job.prior == "wheel.csv"
    # --max-step without degrees leaves max_step_deg at its default
    _run("track", "seq", "-o", str(tmp_path / "o2"), "--max-step", "0.25")
    assert calls["track"][0] == dataclasses.replace(TrackOptions(), max_step_m=0.25)
    # init takes the ground model's options only
    r = CliRunner().invoke(main, ["init", "seq", "-o", str(tmp_path / "m"), "--no-photometric"])
    assert r.exit_code == 2 and "no such option" in r.output.lower() and "--no-photometric" in r.output


def test_no_smooth_is_an_output_choice_passed_on_only_when_given(calls, tmp_path):
    assert "smooth" not in {f.name for f in dataclasses.fields(TrackOptions)}
    _run("track", "seq", "-o", str(tmp_path / "o"))
    assert "smooth" not in calls["track"][1]  # the pipeline's default applies
    _run("track", "seq", "-o", str(tmp_path / "o"), "--no-smooth")
    assert calls["track"][0] == TrackOptions() and calls["track"][1]["smooth"] is False
    _run("batch", "root", "-o", str(tmp_path / "b"), "--no-smooth")
    assert calls["batch"][0].smooth is False


def test_no_option_restates_a_library_default():
    """Every option that is not a flag defaults to None ("not given"), so the library's
    default applies; flags default to their absence."""
    for name, command in main.commands.items():
        for p in command.params:
            if isinstance(p, click.Option) and not p.is_flag and not p.required:
                assert p.default is None, f"monovo {name} {p.opts[0]}: default {p.default!r}"


def test_help_reads_the_defaults_from_the_library(monkeypatch):
    r = CliRunner().invoke(main, ["track", "--help"], terminal_width=200)
    assert r.exit_code == 0
    d = TrackOptions()
    assert f"[default: {d.estimator.robust}]" in r.output
    assert f"[default: {d.reanchor_fraction}; 0.0<=x<1.0]" in r.output
    assert f"[default: one per {d.pixels_per_point} pixels]" in r.output

    @dataclasses.dataclass(frozen=True)
    class Changed(TrackOptions):
        reanchor_fraction: float = 0.45
        pixels_per_point: int = 3

    monkeypatch.setattr(core_options, "TrackOptions", Changed)
    r = CliRunner().invoke(main, ["batch", "--help"], terminal_width=200)
    assert "[default: 0.45; 0.0<=x<1.0]" in r.output and "one per 3 pixels" in r.output

    from monovo_cli.synth.write import synthesize

    r = CliRunner().invoke(main, ["synth", "--help"], terminal_width=200)
    noise_var = inspect.signature(synthesize).parameters["noise_var"].default
    assert f"Variance of the added Gaussian noise (grey levels^2).  [default: {noise_var};" in r.output


def test_batch_options_pickle_and_their_record_survives_json():
    job = JobOptions(track=ALL_GIVEN_OPTIONS, mask="/m.png")
    assert pickle.loads(pickle.dumps(job)) == job  # as they travel to the workers
    record = dataclasses.asdict(job)
    assert json.loads(json.dumps(record)) == record  # done.json compares equal on a rerun
    assert options_from_dict(JobOptions, record) == job


def test_options_from_dict_keeps_the_fields_not_given():
    assert options_from_dict(TrackOptions, {"estimator": {"robust": "none"}}) == (
        TrackOptions(estimator=EstimatorOptions(robust="none")))
    # a nested field keeps TrackOptions' default for it, not its class's
    features = options_from_dict(TrackOptions, {"features": {"seed": 3}}).features
    assert features == dataclasses.replace(TrackOptions().features, seed=3)
    with pytest.raises(ValueError, match="unknown option.*robustt of EstimatorOptions"):
        options_from_dict(TrackOptions, {"estimator": {"robustt": "none"}})
    with pytest.raises(ValueError, match="unknown option.*robust of TrackOptions"):
        options_from_dict(TrackOptions, {"robust": "none"})


# ----------------------------------------------------------------------------- -q / -v


@pytest.fixture
def summary_track(monkeypatch):
    """track_sequence replaced by a fake returning a summary (printed without -q)."""

    def fake(*a, **kw):
        return SimpleNamespace(frames=2, seconds=1.0, fps=2.0, mean_msd=0.5, reanchored=0,
                               reinit=0, lost=0, path_length=0.1, mostly_lost=False)

    monkeypatch.setattr(track, "track_sequence", fake)


@pytest.mark.parametrize("where", ["before", "after", "both"])
def test_quiet_before_or_after_the_command(summary_track, tmp_path, where):
    args = ["track", "seq", "-o", str(tmp_path / "o")]
    loud = CliRunner().invoke(main, args)
    assert loud.exit_code == 0 and "tracked 2 frames" in loud.output
    args = {"before": ["-q", *args], "after": [*args, "--quiet"], "both": ["-q", *args, "-q"]}[where]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert r.output == ""


@pytest.mark.parametrize("where", ["before", "after"])
def test_verbose_before_or_after_the_command(monkeypatch, tmp_path, where):
    def boom(*a, **kw):
        raise RuntimeError("simulated fault")

    monkeypatch.setattr(track, "track_sequence", boom)
    args = ["track", "seq", "-o", str(tmp_path / "o")]
    plain = CliRunner().invoke(main, args)
    assert plain.exit_code == 1 and "(run with -v for the traceback)" in plain.output
    r = CliRunner().invoke(main, ["-v", *args] if where == "before" else [*args, "-v"])
    # with -v the internal error is not turned into one line: its traceback is shown
    assert r.exit_code == 1 and isinstance(r.exception, RuntimeError), r.output
    assert "run with -v" not in r.output


@pytest.mark.parametrize("command", ["synth", "init", "track", "overlay", "eval", "batch"])
def test_every_command_takes_q_and_v_in_both_places(command):
    for args in (["-q", "-v", command, "--help"], [command, "-q", "-v", "--help"]):
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 0 and "-q, --quiet" in r.output, (args, r.output)


# ----------------------------------------------------------------------------- --config


def _config(tmp_path: Path, text: str, name: str = "monovo.yaml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("where", ["before", "after"])
def test_config_file_sets_options_and_the_command_line_wins(calls, tmp_path, where):
    cfg = _config(tmp_path, "threshold: 5\nno-photometric: true\nmax_step: [0.5, 10]\n"
                            "quiet: true\ntrack:\n  robust: tukey\n  threshold: 7\n"
                            f"  output: {tmp_path / 'from_config'}\n"
                            "overlay:\n  fps: 15\n")
    args = ["track", "seq", "--max-points", "all"]
    r = CliRunner().invoke(main, ["--config", cfg, *args] if where == "before"
                           else [*args, "--config", cfg])
    assert r.exit_code == 0 and r.output == "", r.output  # quiet: true
    options, _ = calls["track"]
    # the track section wins over the top level, the command line over both
    assert options == TrackOptions(threshold=7.0, max_points=ALL_POINTS, max_step_m=0.5,
                                   max_step_deg=10.0, estimator=EstimatorOptions(
                                       robust="tukey", photometric=False))
    _run("track", "seq", "--config", cfg, "--threshold", "9", "-o", str(tmp_path / "o"))
    assert calls["track"][0].threshold == 9.0
    # top-level keys apply to every command that has the option; init has no --no-photometric
    _run("init", "seq", "--config", cfg, "-o", str(tmp_path / "m.npz"))
    assert calls["init"][0] == TrackOptions(threshold=5.0, max_step_m=None)


@pytest.mark.parametrize(("text", "words"), [
    ("thresold: 5\n", ["unknown key 'thresold'", "did you mean 'threshold'"]),
    ("track:\n  fps: 15\n", ["unknown key 'track.fps'"]),
    ("track: 5\n", ["track: expected a mapping"]),
    ("threshold: abc\n", ["threshold:", "'abc'"]),
    ("track:\n  max-points: 10\n", ["track.max-points:", "minimum 50"]),
    ("overwrite: 3\n", ["overwrite:", "expected true or false"]),
    ("- threshold\n", ["expected a mapping of option names"]),
    ("threshold: [1\n", ["not valid YAML", "line 2"]),
])
def test_config_file_problems_are_one_line_naming_file_and_key(calls, tmp_path, text, words):
    cfg = _config(tmp_path, text, "bad.yaml")
    for args in (["--config", cfg, "track", "seq", "-o", "x"],
                 ["track", "seq", "-o", "x", "--config", cfg]):
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 2, r.output
        assert r.output.startswith(f"Error: {cfg}: ") and r.output.count("\n") == 1, r.output
        for w in words:
            assert w in r.output
    assert "track" not in calls
    r = CliRunner().invoke(main, ["track", "seq", "-o", "x", "--config", str(tmp_path / "no.yaml")])
    assert r.exit_code == 2 and "no.yaml: cannot read the config file" in r.output


def test_verbose_says_what_a_healthy_run_does(small_drive, tmp_path):
    """-v: the keyframes, the ground measured against init.yaml's, the timing (INFO); no
    debug lines, which -vv adds."""
    r = CliRunner().invoke(main, ["track", str(small_drive), "-o", str(tmp_path / "o"), "-v"])
    assert r.exit_code == 0, r.output
    assert "frame 0: keyframe of " in r.output
    assert "its ground pitch 45.00 deg, roll 0.00 deg, 1.500 m below the camera" in r.output
    assert "as the whole drive measured it: pitch " in r.output and "init.yaml gave" in r.output
    assert "tracked 10 frames in " in r.output and "frames/s)\n" in r.output
    assert "trajectory.png written in " in r.output
    assert "DEBUG" not in r.output and "no BLAS library" not in r.output
    r = CliRunner().invoke(main, ["track", str(small_drive), "-o", str(tmp_path / "o2")])
    assert r.exit_code == 0 and "keyframe of" not in r.output


def test_batch_passes_terrain_out_threads_and_checkpoint_every_on(calls, tmp_path):
    _run("batch", "root", "-o", str(tmp_path / "b"))
    job = calls["batch"][0]
    assert (job.terrain_out, job.threads, job.checkpoint_every) == (False, 1, None)
    _run("batch", "root", "-o", str(tmp_path / "b"), "--terrain-out", "--threads", "2",
         "--checkpoint-every", "25")
    job = calls["batch"][0]
    assert (job.terrain_out, job.threads, job.checkpoint_every) == (True, 2, 25)
    r = CliRunner().invoke(main, ["batch", "root", "-o", str(tmp_path / "b"), "--threads", "0"])
    assert r.exit_code == 2 and "--threads" in r.output
