"""benchmarks.point_cost: its point caps are monovo's budget, its noise-only std is the
covariance's, and its real sequences' shares are of the points a frame used."""

from __future__ import annotations

import numpy as np

from benchmarks.point_cost import cap, median_points, noise_std
from monovo_cli.core.keyframe import point_budget
from monovo_cli.core.options import TrackOptions
from monovo_cli.geometry.camera import PinholeCamera


def test_a_share_of_one_is_monovos_default_budget():
    for w, h in ((256, 256), (512, 512), (752, 480)):
        camera = PinholeCamera(w, h, 300.0, 300.0, w / 2, h / 2)
        assert cap(1.0, w, h) == point_budget(TrackOptions(), camera)
        assert cap(0.5, w, h) == round(0.5 * point_budget(TrackOptions(), camera))


def test_noise_std_halves_its_variance_with_the_points_doubled():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(400, 8))
    full = noise_std(J, np.arange(400))
    assert np.allclose(full, np.sqrt(np.diag(np.linalg.inv(J.T @ J)))[:6])
    twice = np.vstack([J, J])
    assert np.allclose(noise_std(twice, np.arange(800)) * np.sqrt(2.0), full, rtol=1e-12)
    # a subset never knows more than the whole
    assert np.all(noise_std(J, np.arange(200)) > full)


def test_median_points_reads_the_points_a_frame_used(tmp_path):
    (tmp_path / "motion.csv").write_text(
        "frame,tx,points,status\n1,0,100,ok\n2,0,300,ok\n3,0,,lost\n4,0,200,ok\n")
    assert median_points(tmp_path) == 200
