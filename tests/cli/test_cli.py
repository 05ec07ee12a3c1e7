"""One CliRunner test per command, the documented CSV headers pinned, errors as one line with status 2."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli import __version__
from monovo_cli.cli import main
from monovo_cli.io.formats import read_tum

MOTION_HEADER = "frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status"
TRAJ_HEADER = "frame,timestamp,tx,ty,tz,qx,qy,qz,qw"


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    r = CliRunner().invoke(main, ["synth", str(root / "s"), "--frames", "12", "--size", "128x128",
                                  "--seed", "4", "-q"])
    assert r.exit_code == 0, r.output
    return root / "s"


def test_version():
    r = CliRunner().invoke(main, ["--version"])
    assert r.exit_code == 0 and __version__ in r.output


def test_synth_writes_a_sequence(seq):
    assert len(list((seq / "frames").glob("*.png"))) == 12
    for name in ("init.yaml", "groundtruth.tum", "groundtruth_motion.csv"):
        assert (seq / name).is_file()
    assert (seq / "groundtruth_motion.csv").read_text().splitlines()[0].startswith(MOTION_HEADER)


def test_track_writes_spec_outputs(seq, tmp_path):
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["track", str(seq), "-p", str(seq / "init.yaml"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "tracked 12 frames" in r.output
    motion = (out / "motion.csv").read_text().splitlines()
    assert motion[0].startswith(MOTION_HEADER + ",std_tx,std_ty,std_tz,std_rx,std_ry,std_rz")
    assert len(motion) == 12
    rows = list(csv.DictReader(motion))
    assert [int(r["frame"]) for r in rows] == list(range(1, 12))
    assert {r["status"] for r in rows} <= {"ok", "reanchored"}
    traj = (out / "trajectory.csv").read_text().splitlines()
    assert traj[0] == TRAJ_HEADER and len(traj) == 13
    ts, est = read_tum(out / "trajectory.tum")
    _, gt = read_tum(seq / "groundtruth.tum")
    np.testing.assert_allclose(ts, np.arange(12.0))
    assert np.abs(est[:, :3, 3] - gt[:, :3, 3]).max() < 0.01
    # the shared checker's rules, restated: qw >= 0, frame 0 identity, TUM = CSV
    assert all(float(line.split(",")[8]) >= 0 for line in traj[1:])
    assert traj[1].split(",")[2:] == ["0", "0", "0", "0", "0", "0", "1.0"]


def test_track_writes_run_yaml_with_options_and_input_fingerprints(seq, tmp_path):
    import dataclasses
    import hashlib
    import os

    import yaml

    from monovo_cli.core.options import TrackOptions

    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", "--max-points", "500",
                                  "--groundtruth", str(seq / "groundtruth.tum")])
    assert r.exit_code == 0, r.output
    run = yaml.safe_load((out / "run.yaml").read_text())
    assert run["monovo"] == __version__ and run["command"] == "track"
    assert run["options"]["track"] == dataclasses.asdict(TrackOptions(max_points=500))
    assert run["options"]["sequence"] == str(seq.resolve())
    assert run["options"]["skip_bad_frames"] is False and run["options"]["model"] is None

    def sha(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    inputs = run["inputs"]
    assert inputs["init_yaml"]["sha256"] == sha(seq / "init.yaml")
    assert inputs["groundtruth"]["sha256"] == sha(seq / "groundtruth.tum")
    frames = inputs["frames"]
    assert frames["count"] == 12 and frames["kind"] == "images"
    assert frames["frame0_sha256"] == sha(seq / "frames" / "frame_000000.png")
    # the frame list's fingerprint covers names, sizes and mtimes, not the contents
    last = sorted((seq / "frames").glob("*.png"))[-1]
    st = last.stat()
    try:
        os.utime(last, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        r = CliRunner().invoke(main, ["track", str(seq), "-o", str(out), "-q", "--overwrite"])
        assert r.exit_code == 0, r.output
        again = yaml.safe_load((out / "run.yaml").read_text())["inputs"]["frames"]
        assert again["list_sha256"] != frames["list_sha256"]
        assert again["frame0_sha256"] == frames["frame0_sha256"]
    finally:
        os.utime(last, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert not list(out.glob(".*tmp"))  # written atomically


def test_track_refuses_existing_results_then_overwrites(seq, tmp_path):
    out = tmp_path / "out"
    args = ["track", str(seq), "-o", str(out), "-q"]
    assert CliRunner().invoke(main, args).exit_code == 0
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2
    assert "already holds results" in r.output and "--overwrite" in r.output
    assert CliRunner().invoke(main, args + ["--overwrite"]).exit_code == 0


def test_track_streams_csv_to_stdout(seq, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "monovo_cli", "track", str(seq), "-o", "-", "-q"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert list(tmp_path.iterdir()) == []  # no files, no run.yaml
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(MOTION_HEADER) and len(lines) == 12
    assert all(line.count(",") == lines[0].count(",") for line in lines)


def test_init_then_track_with_model_gives_the_same_result(seq, tmp_path):
    model = tmp_path / "model.npz"
    r = CliRunner().invoke(main, ["init", str(seq), "-o", str(model)])
    assert r.exit_code == 0, r.output
    assert "observation points" in r.output and model.is_file()
    a, b = tmp_path / "a", tmp_path / "b"
    assert CliRunner().invoke(main, ["track", str(seq), "-o", str(a), "-q"]).exit_code == 0
    assert CliRunner().invoke(main, ["track", str(seq), "-o", str(b), "-q", "--model",
                                     str(model)]).exit_code == 0
    assert (a / "motion.csv").read_text() == (b / "motion.csv").read_text()


@pytest.mark.parametrize("args, words", [
    (["track", "{tmp}/nope", "-o", "{tmp}/o"], "nope"),
    (["track", "{seq}", "-p", "{tmp}/missing.yaml", "-o", "{tmp}/o"], "missing.yaml"),
    (["init", "{seq}", "-o", "{tmp}/m.npz", "--threshold", "1e9"], "observation points"),
    (["track", "{seq}", "-o", "{tmp}/o", "--model", "{seq}/init.yaml"], "init.yaml"),
    (["synth", "{tmp}/x", "--size", "10x10"], "--size"),
])
def test_bad_input_is_one_line_and_status_2(seq, tmp_path, args, words):
    args = [a.format(tmp=tmp_path, seq=seq) for a in args]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    err = r.output.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("Error:"), r.output
    assert words in err[0]
    assert "Traceback" not in r.output


def test_frame_size_mismatch_is_reported(seq, tmp_path):
    bad = tmp_path / "init.yaml"
    bad.write_text((seq / "init.yaml").read_text().replace("width: 128", "width: 130"))
    r = CliRunner().invoke(main, ["track", str(seq), "-p", str(bad), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "128" in r.output and "130" in r.output


def test_help_lists_commands():
    r = CliRunner().invoke(main, ["--help"])
    for cmd in ("synth", "init", "track"):
        assert cmd in r.output


def test_module_entry_point():
    proc = subprocess.run([sys.executable, "-m", "monovo_cli", "--version"], capture_output=True,
                          text=True, timeout=60, cwd=Path(__file__).parent)
    assert proc.returncode == 0 and __version__ in proc.stdout


def test_max_points_all_uses_every_pixel_above_the_threshold(tmp_path):
    """`--max-points all` (the dense setting) keeps every candidate; the default caps them."""
    from click.testing import CliRunner

    from monovo_cli.cli import main
    from monovo_cli.io.model import load_model

    runner = CliRunner()
    seq = tmp_path / "seq"
    assert runner.invoke(main, ["synth", str(seq), "--preset", "drive", "--frames", "2",
                                "--size", "160x120", "-q"]).exit_code == 0
    counts = {}
    for name, extra in (("default", []), ("all", ["--max-points", "all"])):
        res = runner.invoke(main, ["init", str(seq), "-o", str(tmp_path / f"{name}.npz"), *extra])
        assert res.exit_code == 0, res.output
        counts[name] = len(load_model(tmp_path / f"{name}.npz")[2].levels[0].points)
    assert counts["default"] == 160 * 120 // 2  # one per 2 pixels: the texture has enough
    assert counts["all"] > 1.2 * counts["default"]


def test_library_messages_get_their_flags_at_the_command_line():
    """The library names a setting by its meaning, the CLI by its flag (cli.group.FLAG_WORDS):
    each library wording is still in the library's code, outside the CLI, and becomes the
    flag's."""
    from monovo_cli.cli.group import FLAG_WORDS, with_flags

    pkg = Path(__file__).resolve().parents[2] / "monovo_cli"
    code = "".join(p.read_text() for p in pkg.rglob("*.py") if "cli" not in p.relative_to(pkg).parts)
    for library, command_line in FLAG_WORDS:
        assert library in code, library
        assert "--" not in library and "--" in command_line
        assert with_flags(f"x: {library}; y") == f"x: {command_line}; y"
