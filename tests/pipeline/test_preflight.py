"""What ``monovo init`` and ``monovo track`` check before they write anything
(pipeline/preflight.py): ``--covariance``'s path, the results already in the output folder,
``--groundtruth`` against the frames, ``--model`` against the sequence, init.yaml and options.
Each check was added for a problem users met in the trial (issue 15.7), and each test
failed before its fix."""

from __future__ import annotations

import csv
import logging

import cv2
import numpy as np
import pytest

from monovo_cli.io.model import load_model
from tests.helpers.cli import one_error_line, run


@pytest.fixture
def seq(small_drive):
    """The 10-frame drive of seed 4 (shared: the tests write only into tmp_path)."""
    return small_drive


# ----------------------------------------------------------------------------- --covariance


def test_covariance_into_a_missing_directory_writes_nothing_and_the_rerun_runs(seq, tmp_path):
    out = tmp_path / "out"
    code, output = run("track", seq, "-o", out, "--covariance", tmp_path / "no" / "cov.csv")
    assert code == 2 and "no/cov.csv" in one_error_line(output) and "no such directory" in output
    assert not out.exists()  # nothing written before the check
    code, output = run("track", seq, "-o", out, "-q", "--covariance", out / "cov.csv")
    assert code == 0, output  # inside OUTDIR, which track creates
    assert (out / "cov.csv").is_file()


def test_a_partial_output_of_a_failed_run_does_not_refuse_the_rerun(seq, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "motion.csv").write_text("frame,tx,ty,tz,rx,ry,rz,msd,iterations,points,status\n")
    (out / "trajectory.csv").write_text("frame,timestamp,tx,ty,tz,qx,qy,qz,qw\n"
                                        "0,0,0,0,0,0,0,0,1.0\n")
    (out / "trajectory.tum").write_text("0 0 0 0 0 0 0 1.0\n")
    code, output = run("track", seq, "-o", out, "-q")  # frame 0 only: no result to keep
    assert code == 0, output
    code, output = run("track", seq, "-o", out, "-q")  # real results are still kept
    assert code == 2 and "already holds results" in one_error_line(output)


def test_covariance_dash_is_refused_not_a_file_named_dash(seq, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, output = run("track", seq, "-o", "out", "--covariance", "-")
    assert code == 2 and "--covariance -" in one_error_line(output)
    assert not (tmp_path / "-").exists() and not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- --groundtruth


def test_groundtruth_of_another_sequence_is_refused(seq, tmp_path, caplog):
    gt = tmp_path / "gt.tum"
    gt.write_text("".join(f"{float(line.split()[0]) + 50} {line.split(' ', 1)[1]}"
                          for line in (seq / "groundtruth.tum").read_text().splitlines(True)))
    code, output = run("track", seq, "-o", tmp_path / "o", "--groundtruth", gt)
    line = one_error_line(output)
    assert code == 2 and "gt.tum" in line and "timestamps" in line
    assert not (tmp_path / "o").exists()
    half = tmp_path / "half.tum"
    half.write_text("".join((seq / "groundtruth.tum").read_text().splitlines(True)[:5]))
    with caplog.at_level(logging.WARNING, logger="monovo_cli"):
        code, output = run("track", seq, "-o", tmp_path / "o2", "--groundtruth", half)
    assert code == 0, output
    assert "half.tum: matches only 5 of the 10 frames" in caplog.text


# ----------------------------------------------------------------------------- --model


def test_a_model_of_another_sequence_is_refused(small_drive, other_small_drive, tmp_path):
    a, b = small_drive, other_small_drive
    model = tmp_path / "b.npz"
    assert run("init", b, "-o", model, "-q")[0] == 0
    code, output = run("track", a, "-o", tmp_path / "out", "--model", model)
    line = one_error_line(output)
    assert code == 2 and "b.npz" in line and "frame 0" in line and "monovo init" in line


def test_a_model_of_another_init_yaml_is_refused(seq, tmp_path):
    model = tmp_path / "m.npz"
    assert run("init", seq, "-o", model, "-q")[0] == 0
    other = tmp_path / "init.yaml"
    other.write_text((seq / "init.yaml").read_text().replace("distance: 1.5", "distance: 1.6"))
    code, output = run("track", seq, "-p", other, "-o", tmp_path / "out", "--model", model)
    line = one_error_line(output)
    assert code == 2 and "m.npz" in line and "plane" in line and "init.yaml" in line


def test_model_with_a_mask_uses_the_mask_from_frame_1(seq, tmp_path):
    mask = np.zeros((128, 128), np.uint8)
    mask[:, :64] = 255  # the left half is never used
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    model = tmp_path / "m.npz"
    assert run("init", seq, "-o", model, "-q")[0] == 0

    def first_points(*extra):
        out = tmp_path / f"out{len(list(tmp_path.iterdir()))}"
        code, output = run("track", seq, "-o", out, "-q", *extra)
        assert code == 0, output
        with (out / "motion.csv").open() as f:
            return int(next(csv.DictReader(f))["points"])

    plain = first_points("--model", model)
    masked = first_points("--model", model, "--mask", tmp_path / "mask.png")
    assert masked < 0.9 * plain, (masked, plain)  # equal before: the mask waited for a keyframe
    # the model's points on masked pixels are gone, at every level
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.preflight import model_keyframe
    from monovo_cli.pipeline.tracking import open_sequence

    key = model_keyframe(model, open_sequence(seq), TrackOptions(), mask == 0)
    full = load_model(model)[2]
    for lv, (kl, before) in enumerate(zip(key.levels, full.levels)):
        u = kl.points.uv[:, 0] * 2 ** lv  # level-lv pixels at full resolution
        assert u.min() >= 63 and 0.4 < len(u) / len(before.points.uv) < 0.6, lv


def test_init_takes_a_mask_and_refuses_to_overwrite(seq, tmp_path):
    mask = np.zeros((128, 128), np.uint8)
    mask[64:] = 255
    cv2.imwrite(str(tmp_path / "mask.png"), mask)
    model = tmp_path / "m.npz"
    code, output = run("init", seq, "-o", model, "-q", "--mask", tmp_path / "mask.png")
    assert code == 0, output
    _, _, key = load_model(model)
    assert key.levels[0].points.uv[:, 1].max() < 64
    before = model.read_bytes()
    code, output = run("init", seq, "-o", model)
    assert code == 2 and "--overwrite" in one_error_line(output) and "m.npz" in output
    assert model.read_bytes() == before
    assert run("init", seq, "-o", model, "-q", "--overwrite")[0] == 0
    assert load_model(model)[2].levels[0].points.uv[:, 1].max() > 64


def test_model_options_given_to_track_must_be_the_models(seq, tmp_path):
    model = tmp_path / "m.npz"
    assert run("init", seq, "-o", model, "-q", "--max-points", "500", "--threshold", "4")[0] == 0
    same = ("--model", model, "--max-points", "500", "--threshold", "4")
    assert run("track", seq, "-o", tmp_path / "ok", "-q", *same)[0] == 0
    for opt, value in (("--max-points", "600"), ("--threshold", "5"), ("--levels", "2")):
        code, output = run("track", seq, "-o", tmp_path / "o", "--model", model, opt, value)
        line = one_error_line(output)
        assert code == 2 and opt in line and "monovo init" in line, line
