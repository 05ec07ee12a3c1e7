"""The tracker against synthetic ground truth (fixed seeds, explicit tolerances).

Tolerances come from the noise: on 100 pairs at noise variance 10 the absolute errors have
std ~0.0013 m and ~0.0007 deg per axis (docs/benchmarks.md); the bounds below are ~10 std,
so a pass is not luck and a broken estimator (errors of pixels, i.e. ~0.1 deg) fails.
"""

from pathlib import Path

import numpy as np
import pytest

from monovo_cli import iter_track
from monovo_cli.core.estimator.ground import barycentric
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_motion_csv, read_tum
from monovo_cli.io.sources import open_frames
from monovo_cli.synth.write import synthesize


def _run(seq: Path, options: TrackOptions | None = None):
    return list(iter_track(seq, options=options))


@pytest.fixture(scope="module")
def pairs(synth_drive):
    return sorted(synth_drive(preset="pairs", frames=4, noise_var=10.0, seed=11).glob("pair_*"))


def test_pairs_recovered_within_noise_tolerance(pairs):
    assert len(pairs) == 4
    for pair in pairs:
        res = _run(pair)
        _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
        est = res[1].prev_from_cur
        assert res[1].status == FrameStatus.OK
        dt = est[:3, 3] - gt[0][:3, 3]
        dr = np.degrees(so3_log(est[:3, :3]) - so3_log(gt[0][:3, :3]))
        assert np.abs(dt).max() < 0.015, (pair.name, dt)
        assert np.abs(dr).max() < 0.008, (pair.name, dr)
        # the reported std is of the right size: errors within 6 reported sigmas
        assert np.all(np.abs(np.r_[dt, np.radians(dr)]) < 6 * res[1].std + 1e-9), (dt, dr, res[1].std)


def test_noise_free_pair_is_recovered_almost_exactly(tmp_path):
    synthesize(tmp_path / "p", preset="pairs", frames=1, noise_var=0.0, seed=5)
    pair = tmp_path / "p" / "pair_0000"
    res = _run(pair)
    _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
    err = se3_inv(gt[0]) @ res[1].prev_from_cur
    # Without noise what is left is the renderer's own floor (each view is a box-filtered
    # 4x supersample, so the two frames are not exact warps of each other at the finest
    # scale): measured 0.0008 m / 0.0005 deg mean over 20 pairs at a 100 m ground distance.
    assert np.linalg.norm(err[:3, 3]) < 5e-3
    assert np.degrees(np.linalg.norm(so3_log(err[:3, :3]))) < 2e-3


def test_noisy_frame_after_a_clean_keyframe_is_not_lost(tmp_path):
    """A noise-free keyframe (the paper's known texture) and a frame with noise variance 100:
    the loss checks allow for the current frame's own noise, not only the keyframe's (they
    used to call 30 of 30 such pairs lost at variance 100, and half of them at 50)."""
    synthesize(tmp_path / "p", preset="pairs", frames=2, noise_var=100.0, seed=2,
               clean_frame0=True)
    pairs = sorted((tmp_path / "p").glob("pair_*"))
    assert len(pairs) == 2
    for pair in pairs:
        res = _run(pair)
        _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
        err = se3_inv(gt[0]) @ res[1].prev_from_cur
        assert res[1].status == FrameStatus.OK, res[1].reason
        assert np.linalg.norm(err[:3, 3]) < 0.03
        assert np.degrees(np.linalg.norm(so3_log(err[:3, :3]))) < 0.015


def test_a_first_mer_step_from_a_crest_is_re_estimated_on_the_corrected_plane(tmp_path):
    """MER seed 2 at 1024x1024: frame 0 at a crest of the bobbing (init.yaml's nominal plane
    2.8 deg off the true ground), frame 1 a 0.76 m step. The fit over the nominal plane is
    1.1 deg off; the plane test corrects the plane, and the frame re-estimated from level 2
    diverged (so the frame kept its 1.1 deg and the drive its heading error: 1.1 % of the
    distance after 60 frames). Re-estimated from the top, it lands within 1 cm and 0.05 deg."""
    synthesize(tmp_path / "m", preset="mer", frames=2, noise_var=10.0, seed=2)
    res = _run(tmp_path / "m")
    _, gt = read_tum(tmp_path / "m" / "groundtruth.tum")
    err = se3_inv(gt[1]) @ res[1].world_from_cam
    assert res[1].status == FrameStatus.REANCHORED
    assert np.linalg.norm(err[:3, 3]) < 0.01
    assert np.degrees(np.linalg.norm(so3_log(err[:3, :3]))) < 0.05


@pytest.fixture(scope="module")
def drive(synth_drive):
    return synth_drive(preset="drive", frames=60, size=(256, 256), noise_var=10.0, seed=3)


def test_short_drive_tracks_against_ground_truth(drive):
    res = _run(drive)
    _, gt = read_tum(drive / "groundtruth.tum")
    assert [r.status for r in res].count(FrameStatus.LOST) == 0
    est = np.array([r.world_from_cam for r in res])
    dist = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1).sum()
    err = np.linalg.norm(est[-1][:3, 3] - gt[-1][:3, 3])
    assert dist > 2.0
    assert err < 0.01 * dist, (err, dist)
    heading = np.degrees(np.linalg.norm(so3_log(est[-1][:3, :3].T @ gt[-1][:3, :3])))
    assert heading < 0.5
    # every frame's relative motion is close to the truth, not only the end point
    for k in range(1, len(res)):
        d = se3_inv(gt[k - 1]) @ gt[k]
        assert np.linalg.norm(res[k].prev_from_cur[:3, 3] - d[:3, 3]) < 0.003


def test_keyframe_points_lie_on_the_plane_with_valid_barycentrics(drive):
    cfg = load_init(drive / "init.yaml")
    img = open_frames(drive / "frames").read(0).image
    plane = cfg.plane
    key = build_keyframe(0, img, cfg.camera, plane, cfg.region, np.eye(4),
                         TrackOptions(max_points=3000))
    pts = key.levels[0].points
    assert 1000 < len(pts) <= 3000
    np.testing.assert_allclose(pts.X @ plane.normal, plane.distance, rtol=1e-9)
    np.testing.assert_allclose(cfg.camera.project(pts.X), pts.uv, atol=1e-6)
    assert np.all(pts.tri >= 0)
    np.testing.assert_allclose(pts.bary.sum(axis=1), 1.0, atol=1e-5)
    tri, bary = barycentric(pts.X, key.corners)
    assert np.array_equal(tri, pts.tri)
    mag = np.hypot(pts.grad[:, 0], pts.grad[:, 1])
    assert mag.min() > key.threshold
    # the cap spreads points evenly: every quarter of the image holds a fair share
    h, w = img.shape
    quads = (pts.uv[:, 0] > w / 2).astype(int) + 2 * (pts.uv[:, 1] > h / 2)
    assert np.bincount(quads, minlength=4).min() > 0.15 * len(pts)


def test_standing_start_at_the_corner_of_the_rotation_grid():
    """Pair 250 of the paper protocol (``synth --preset pairs --frames 1000 --seed 1
    --noise-var 10 --clean-frame0``, kept in tests/data): a rotation of (-4.9, 4.8, 0.5) deg
    from a standing start, between the search's grid points. It was called lost while
    O^T W O was formed once per level: from a far-off hypothesis the weights change with
    every step, and the right one had not converged within the search's iterations."""
    pair = Path(__file__).parents[1] / "data" / "pair_large_rotation"
    res = _run(pair)
    _, gt, _ = read_motion_csv(pair / "groundtruth_motion.csv")
    assert np.degrees(np.abs(so3_log(gt[0][:3, :3]))).min() > 0.4  # a real 3-axis rotation
    assert res[1].status == FrameStatus.OK, res[1].reason
    err = se3_inv(gt[0]) @ res[1].prev_from_cur
    assert np.linalg.norm(err[:3, 3]) < 0.02
    assert np.degrees(np.linalg.norm(so3_log(err[:3, :3]))) < 0.01
