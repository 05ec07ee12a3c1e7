"""Defects the scenario soak found (benchmarks/soak.py), each reproduced on a drive of our own
synth. Each test failed before its fix; its docstring names the defect."""

import csv
import shutil

import cv2
import numpy as np

from tests.helpers.cli import run


def _dim(seq, tmp_path, gains):
    """A copy of ``seq`` with frame k's contrast scaled by ``gains[k]`` about its mean."""
    work = tmp_path / "seq"
    shutil.copytree(seq, work)
    frames = sorted((work / "frames").glob("*.png"))
    for k, g in gains.items():
        img = cv2.imread(str(frames[k]), cv2.IMREAD_GRAYSCALE).astype(float)
        m = img.mean()
        cv2.imwrite(str(frames[k]), np.clip((img - m) * g + m, 0, 255).astype(np.uint8))
    return work


def test_a_gap_resolved_from_a_frame_with_more_pyramid_levels_than_the_keyframe(synth_drive,
                                                                                 tmp_path):
    """Frames 5-24 of a rock field dimmed to 3 % of their contrast, the light coming back over
    frames 25-29: a keyframe anchored in the dim stretch drops its sparse coarsest level, the
    frames of the ramp are lost, and the gap is re-solved from the last good frame, whose
    keyframe has every level, against the current frame's pyramid built for the fewer. It
    stopped with ``internal error: IndexError`` (exit 1) in ``_reinit -> _resolve_gap ->
    estimate_motion``, nothing after frame 27 written."""
    seq = synth_drive(preset="drive", terrain="rocks", frames=30, size=(128, 128), seed=1)
    gains = {k: 0.03 for k in range(5, 25)}
    gains.update({25: 0.045, 26: 0.07, 27: 0.1, 28: 0.15, 29: 0.22})
    work = _dim(seq, tmp_path, gains)
    code, out = run("track", work, "-o", tmp_path / "out", "-q")
    assert code == 0, out
    with open(tmp_path / "out" / "motion.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["frame"]) for r in rows] == list(range(1, 30))
    assert any(r["status"] == "reinit" for r in rows)  # (the path that failed was taken)
