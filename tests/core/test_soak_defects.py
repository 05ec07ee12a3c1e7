"""Defects the scenario soak found (benchmarks/soak.py) and issue 40 reported, each reproduced
on a drive of our own synth. Each test failed before its fix (or, where the fix came first,
with it taken out); its docstring names the defect."""

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


def _untrusted(seq, out, t_off=0.05, r_off_deg=1.0):
    """The rows more than ``t_off`` m or ``r_off_deg`` deg off the truth whose std does not
    cover the error within 4 std on every axis (the soak's integrity invariant)."""
    axes = ["tx", "ty", "tz", "rx", "ry", "rz"]
    with open(seq / "groundtruth_motion.csv", newline="") as f:
        truth = {int(r["frame"]): r for r in csv.DictReader(f)}
    with open(out / "motion.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    bad = []
    for r in rows:
        e = np.array([float(r[a]) - float(truth[int(r["frame"])][a]) for a in axes])
        if np.linalg.norm(e[:3]) <= t_off and np.linalg.norm(e[3:]) <= r_off_deg:
            continue
        std = np.array([float(r["std_" + a]) for a in axes])
        if not np.all(np.abs(e) <= 4 * std):
            bad.append((int(r["frame"]), r["status"], np.round(e / std, 1).tolist()))
    return rows, bad


def test_an_unreadable_frame_where_a_turn_in_place_begins_states_a_whole_step(synth_drive,
                                                                              tmp_path):
    """A MER drive (0.6-0.75 m steps, turns in place) whose frame 7, the first of a turn in
    place, is unreadable. Its lost row predicted another 0.7 m step with the std of the recent
    steps' changes (about 0.1 m), and was off by the whole step, 5-6 of its std; the next row,
    measured from that prediction, inherited the error. The lost row's std now covers a whole
    step (the last accepted motion's size)."""
    seq = synth_drive(preset="mer", frames=12, size=(256, 256), seed=3)
    work = tmp_path / "seq"
    shutil.copytree(seq, work)
    (work / "frames" / sorted(p.name for p in (work / "frames").glob("*.png"))[7]).write_bytes(
        b"not a png")
    code, out = run("track", work, "-o", tmp_path / "out", "-q", "--skip-bad-frames")
    assert code == 0, out
    rows, bad = _untrusted(work, tmp_path / "out")
    assert rows[6]["frame"] == "7" and rows[6]["status"] == "lost"
    assert bad == []


def test_a_mirrored_minimum_at_mer_spacing_is_not_written_as_the_frames_motion(synth_drive,
                                                                              monkeypatch):
    """Issue 40's second defect: at MER spacing one frame in about 330 converged to a
    mirrored translation ((ty, tz) (0.90, -0.92) m where the truth was (-0.53, 0.51)) at 31x
    the drive's median msd, and was written `reanchored` 2.05 m off with a std of 0.33 m.
    The spontaneous convergence was never reproduced on our synth, so here the fit from the
    prediction is made to converge to it: started at the true step times -1.7 on frame 6 of
    a 512² MER drive (seed 3), it stops at the mirrored minimum, (0.12, 0.91, -1.00) m
    against (-0.07, -0.53, 0.59), at an msd of about 1510 where the drive's rows sit near
    30. Such a fit is not the frame's motion: it is no better than chance, its robust msd
    rose 50x over the recent rows' and a capture finds a closer fit; any one of the three
    keeps it out of the row. With none of them (chance share 1.0, msd factor and retry ratio
    infinite) the mirrored step was written `ok`, 2.2 m off (its std widened to 0.5-1.2 m by
    the change from the prediction)."""
    from monovo_cli import iter_track
    from monovo_cli.core import checks
    from monovo_cli.core.odometry import Odometry
    from monovo_cli.core.status import FrameStatus
    from monovo_cli.geometry.lie import se3_inv
    from monovo_cli.io.formats import read_motion_csv

    seq = synth_drive(preset="mer", frames=8, size=(512, 512), seed=3, noise_var=10.0)
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")  # row k-1: frame k
    K, seen = 6, {}
    step, fit = Odometry.step, checks.estimate_motion

    def watched_step(self, index, *args, **kwargs):
        seen.update(index=index, prev=self._world_from_prev, key=self._key)
        return step(self, index, *args, **kwargs)

    def mirrored_first_fit(levels, pyramid, guess, **kwargs):
        if seen["index"] != K or "mirrored" in seen:
            return fit(levels, pyramid, guess, **kwargs)
        mirrored = gt[K - 1].copy()
        mirrored[:3, 3] *= -1.7
        prev_from_key = se3_inv(seen["prev"]) @ seen["key"].world_from_key
        est = fit(levels, pyramid, se3_inv(mirrored) @ prev_from_key,
                  **{**kwargs, "first_level": 0})
        seen["mirrored"] = est, (prev_from_key @ se3_inv(est.cur_from_key))[:3, 3]
        return est

    monkeypatch.setattr(Odometry, "step", watched_step)
    monkeypatch.setattr(checks, "estimate_motion", mirrored_first_fit)
    rows = list(iter_track(seq))
    truth = gt[K - 1][:3, 3]
    est, t = seen["mirrored"]
    assert est.converged and np.dot(t, truth) < 0 and np.linalg.norm(t - truth) > 1.0, t
    accepted = [r for r in rows[1:] if r.status in (FrameStatus.OK, FrameStatus.REANCHORED)]
    assert len(accepted) == len(rows) - 1
    assert np.linalg.norm(rows[K].prev_from_cur[:3, 3] - truth) < 0.02, (rows[K].status, rows[K].std)
    msd = np.array([r.msd for r in accepted])
    assert est.msd > 20 * np.median(msd) and msd.max() < 3 * np.median(msd), msd
