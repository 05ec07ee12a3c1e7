"""The finest level's stretched steps reach the fixed point of the unstretched ones, sooner."""

from __future__ import annotations

import numpy as np

from monovo_cli.core.estimator.estimate import estimate_motion
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.geometry.lie import se3_inv, se3_log
from monovo_cli.image.pyramid import build_pyramid
from monovo_cli.io.config import load_init
from monovo_cli.io.sources import open_frames


def _frames_against_frame0(seq, options: EstimatorOptions) -> list:
    """The estimates of frames 1.. against a keyframe on frame 0, each from the identity."""
    cfg = load_init(seq / "init.yaml")
    imgs = [f.image for f in open_frames(seq / "frames")]
    key = build_keyframe(0, imgs[0], cfg.camera, cfg.plane, cfg.region, np.eye(4),
                         TrackOptions(estimator=options))
    return [estimate_motion(key.levels, build_pyramid(img, len(key.levels)), np.eye(4),
                            options=options) for img in imgs[1:]]


def test_stretched_steps_end_where_plain_ones_do_in_fewer_steps(synth_drive):
    """A 256² plane drive, frames 1-7 against frame 0 (up to 28 cm of baseline), each from
    the identity. Solved to 1e-6 px, stretched steps (1.15) and plain ones land within half a
    std of each other on every axis (measured 0.48 at most, on the farthest frame; at that
    tolerance the iterations stop where the robust cost stops falling, which moves by that
    much with the path); so do the defaults (1.15, 6e-3 px) and the former ones (1, 3e-3 px)
    (measured 0.42 and 0.36), the defaults in fewer finest-level steps in all (measured 15
    against 21)."""
    seq = synth_drive(preset="drive", frames=8, size=(256, 256), seed=3, noise_var=10.0)
    tight = dict(step_tolerance_px=1e-6, max_iterations=100)
    fixed = _frames_against_frame0(seq, EstimatorOptions(relaxation=1.0, **tight))
    stretched = _frames_against_frame0(seq, EstimatorOptions(relaxation=1.15, **tight))
    default = _frames_against_frame0(seq, EstimatorOptions())
    former = _frames_against_frame0(seq, EstimatorOptions(relaxation=1.0, step_tolerance_px=3e-3))
    for ref, *others in zip(fixed, stretched, default, former):
        std = np.sqrt(np.diag(ref.covariance))
        for est in others:
            off = np.abs(se3_log(est.cur_from_key @ se3_inv(ref.cur_from_key))) / std
            assert np.all(off < 0.5), off
    assert sum(e.finest_iterations for e in default) < sum(e.finest_iterations for e in former)
