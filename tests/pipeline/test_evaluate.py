"""monovo eval on a tracked synthetic drive: the reported std's ±3σ band, plots, JSON, inputs."""

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from monovo_cli.cli import main
from monovo_cli.errors import OutputError
from monovo_cli.geometry.lie import quat_from_matrix
from monovo_cli.io.formats import read_tum
from monovo_cli.pipeline.evaluate import (
    PLOT_NAMES,
    EvalOptions,
    eval_plot_images,
    evaluate_files,
    run_eval,
    write_eval_plots,
)


@pytest.fixture(scope="module")
def tracked(synth_drive, tmp_path_factory):
    """A 60-frame 192x192 planar drive and its tracked output folder."""
    seq = synth_drive(preset="drive", frames=60, size=(192, 192), seed=4)
    out = tmp_path_factory.mktemp("eval") / "out"
    r = CliRunner().invoke(main, ["-q", "track", str(seq), "-o", str(out)])
    assert r.exit_code == 0, r.output
    return seq, out


def test_the_three_sigma_band_holds_99_percent_where_the_std_is_honest(tracked):
    seq, out = tracked
    result = evaluate_files(out, seq / "groundtruth.tum")
    band = result.drive.band
    assert band is not None and len(band.pose) == 59  # every frame's motion T_{k-1}_k
    total, by_axis = band.fraction_inside()
    assert total >= 0.99, (total, by_axis)
    d = result.as_dict()["std_band"]
    assert d["inside_fraction"] == total and set(d["normalised_std"]) == {
        "tx", "ty", "tz", "rx", "ry", "rz"}


def _colours(img: np.ndarray) -> int:
    """The distinct colours of an (H, W, 3) uint8 image, each pixel packed into one integer
    (``np.unique(..., axis=0)`` counts the same rows but sorts them as records, 100x slower)."""
    return len(np.unique((img[..., 0].astype(np.uint32) << 16)
                         | (img[..., 1].astype(np.uint32) << 8) | img[..., 2]))


def test_plots_and_json_are_written(tracked, tmp_path):
    seq, out = tracked
    result = run_eval(out, seq / "groundtruth.tum", EvalOptions(align="se3"),
                      plots_dir=tmp_path / "plots", json_path=tmp_path / "eval.json")
    assert [p.name for p in result.plots] == list(PLOT_NAMES)
    sizes = {}
    for p in result.plots:
        img = cv2.imread(str(p))
        assert img is not None, p
        sizes[p.name] = img.shape
        assert _colours(img) > 30, p  # more than a blank frame
        assert (img != 255).any(axis=2).mean() > 0.03, p
    assert sizes == {"eval_trajectory.png": (800, 800, 3), "eval_errors_time.png": (900, 1000, 3),
                     "eval_errors_distance.png": (900, 1000, 3),
                     "eval_axes_std.png": (1200, 1000, 3)}
    d = json.loads((tmp_path / "eval.json").read_text())
    assert d == json.loads(json.dumps(result.as_dict()))
    assert set(d) == {  # stable keys: scripts read them (docs/guide.md "monovo eval")
        "poses", "estimate_poses", "groundtruth_poses", "max_dt_s", "alignment", "scale",
        "relative_motions", "relative_errors", "translation_average", "rotation_average",
        "ate_rmse_m", "ate_max_m", "ate_rmse_aligned_m", "distance_m", "final_drift_m",
        "final_drift_pct", "final_rotation_error_deg", "rotation_drift_deg_per_m", "pairing",
        "partial", "ape", "rpe", "segments", "std_band", "inputs"}
    assert set(d["segments"]) == {"step_poses", "segments", "translation_pct",
                                  "rotation_deg_per_m", "by_length"}
    assert set(d["rpe"]) == {"delta_poses", "translation_m", "rotation_deg"}
    assert d["inputs"]["estimate"]["format"] == "folder" and d["alignment"] == "se3"
    # an estimate without motion.csv has no band and no band plot
    plain = tmp_path / "plain.tum"
    shutil.copy(out / "trajectory.tum", plain)
    plain_result = evaluate_files(plain, seq / "groundtruth.tum")
    written = write_eval_plots(plain_result, tmp_path / "p2")
    assert [p.name for p in written] == list(PLOT_NAMES[:3])
    images = eval_plot_images(result)  # in memory, for a page that embeds them
    assert list(images) == list(PLOT_NAMES) and images[PLOT_NAMES[0]].shape == (800, 800, 3)
    with pytest.raises(OutputError, match="plain.tum: is a file; the plots need a folder"):
        write_eval_plots(plain_result, plain)


def test_every_input_of_one_run_gives_the_same_figures(tracked, tmp_path):
    seq, out = tracked
    ref = evaluate_files(out / "trajectory.tum", seq / "groundtruth.tum").as_dict()
    ts, gt = read_tum(seq / "groundtruth.tum")
    euroc = tmp_path / "data.csv"
    euroc.write_text("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],"
                     "q_RS_x [],q_RS_y [],q_RS_z []\n" + "".join(
                         ",".join([str(round(t * 1e9)), *(repr(float(v)) for v in T[:3, 3]),
                                   *(repr(float(q[i])) for i in (3, 0, 1, 2))]) + "\n"
                         for t, T, q in ((t, T, quat_from_matrix(T[:3, :3])) for t, T in zip(ts, gt))))
    kitti = tmp_path / "gt_poses.txt"
    kitti.write_text("".join(" ".join(repr(float(v)) for v in T[:3].ravel()) + "\n" for T in gt))
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(out / "motion.csv", alone / "motion.csv")
    for est, truth, pairing in ((out / "trajectory.csv", euroc, "time"),
                                (out, kitti, "frame"),
                                (out / "trajectory.tum", kitti, "frame")):
        d = evaluate_files(est, truth).as_dict()
        assert d["pairing"] == pairing and d["poses"] == 60
        assert d["ate_rmse_m"] == pytest.approx(ref["ate_rmse_m"], abs=1e-9), (est, truth)
        assert d["segments"]["segments"] == ref["segments"]["segments"]
        assert d["segments"]["translation_pct"] == pytest.approx(
            ref["segments"]["translation_pct"], rel=1e-6)
    # motion.csv alone (no trajectory.csv beside it): the tracked motions composed, by frame
    d = evaluate_files(alone / "motion.csv", seq / "groundtruth.tum").as_dict()
    assert d["pairing"] == "frame" and d["poses"] == 60 and d["std_band"]["motions"] == 59


def test_the_command(tracked, tmp_path):
    seq, out = tracked
    gt = seq / "groundtruth.tum"
    r = CliRunner().invoke(main, ["eval", str(out), str(gt), "--plots",
                                    str(tmp_path / "plots"), "--json"])
    assert r.exit_code == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["poses"] == 60 and d["segments"]["by_length"][0]["segments"] > 0
    assert "wrote 4 plots to" in r.stderr
    r = CliRunner().invoke(main, ["eval", str(out), str(gt), "--json", str(tmp_path / "e.json")])
    assert r.exit_code == 0, r.output
    assert "Errors by travelled distance (KITTI-style" in r.output
    assert "Reported std: errors inside ±3 std (59 relative motions)" in r.output
    assert json.loads((tmp_path / "e.json").read_text())["poses"] == 60
    # a sparse truth: one line, exit 2, then --partial
    (tmp_path / "sparse.tum").write_text("".join(gt.read_text().splitlines(keepends=True)[::10]))
    r = CliRunner().invoke(main, ["eval", str(out), str(tmp_path / "sparse.tum")])
    assert r.exit_code == 2 and r.output.count("\n") == 1, r.output
    assert "only 6 of its 60 poses match" in r.output and "give --partial" in r.output
    r = CliRunner().invoke(main, ["eval", str(out), str(tmp_path / "sparse.tum"), "--partial"])
    assert r.exit_code == 0 and "6 poses matched" in r.output
    r = CliRunner().invoke(main, ["eval", str(out), str(gt), "--segments", "1,x"])
    assert r.exit_code == 2 and "expected positive lengths" in r.output


def test_a_run_in_memory_evaluates_as_its_files_do(tmp_path):
    """evaluate_run on the TrackRun gives eval's figures on the files the run wrote (up to
    their printed precision), so report.html needs no file read back."""
    from monovo_cli.core.options import TrackOptions
    from monovo_cli.pipeline.evaluate import EvalOptions, evaluate_files, evaluate_run
    from monovo_cli.pipeline.track import track_sequence

    seq = Path(__file__).resolve().parents[2] / "sample_sequences" / "navcam_drive"
    run = track_sequence(seq, None, tmp_path / "o", TrackOptions(), report=False)
    opts = EvalOptions(align="se3")
    mem = evaluate_run(run, seq / "groundtruth.tum", opts).as_dict()
    files = evaluate_files(tmp_path / "o", seq / "groundtruth.tum", opts).as_dict()
    mem.pop("inputs"), files.pop("inputs")
    flat_mem, flat_files = _flat(mem), _flat(files)
    assert flat_mem.keys() == flat_files.keys() and len(flat_mem) > 20
    for key, value in flat_mem.items():
        assert value == pytest.approx(flat_files[key], rel=1e-4, abs=1e-6), key


def _flat(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        elif isinstance(v, (int, float)) and v is not None:
            out[prefix + k] = v
        elif isinstance(v, list) and all(isinstance(x, (int, float)) for x in v):
            for i, x in enumerate(v):
                out[f"{prefix}{k}.{i}"] = x
    return out
