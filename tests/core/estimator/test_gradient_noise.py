"""The keyframe gradients' noise in the estimate's std (core/estimator/gradient_noise.py)."""

from __future__ import annotations

import numpy as np
import pytest

from monovo_cli.core.estimator.estimate import estimate_motion
from monovo_cli.core.estimator.gradient_noise import noise_factor
from monovo_cli.core.keyframe import build_keyframe
from monovo_cli.core.options import TrackOptions
from monovo_cli.geometry.lie import se3_inv, so3_log
from monovo_cli.image.pyramid import build_pyramid
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum
from monovo_cli.io.sources import open_frames

DRAWS = 8


def _pair(synth_drive):
    seq = synth_drive(preset="drive", frames=2, size=(256, 256), seed=3, noise_var=0.0)
    cfg = load_init(seq / "init.yaml")
    imgs = [f.image.astype(np.float64) for f in open_frames(seq / "frames")]
    _, gt = read_tum(seq / "groundtruth.tum")
    return cfg, imgs, se3_inv(gt[1]) @ gt[0]


def _fits(cfg, imgs, contrast: float, sigma: float):
    """Per noise draw of the pair at ``contrast`` under noise ``sigma``: the fit of frame 1
    from the identity, the keyframe on frame 0, frame 1's pyramid."""
    opts = TrackOptions()
    rng = np.random.default_rng(5)
    out = []
    for _ in range(DRAWS):
        a, b = ((128.0 + contrast * (im - 128.0) + rng.normal(0.0, sigma, im.shape)
                 ).astype(np.float32) for im in imgs)
        key = build_keyframe(0, a, cfg.camera, cfg.plane, cfg.region or (0, 0, 256, 256),
                             np.eye(4), opts)
        pyr = build_pyramid(b, len(key.levels))
        est = estimate_motion(key.levels, pyr, np.eye(4), options=opts.estimator)
        assert est.converged
        out.append((est, key, pyr))
    return out


def test_textured_frames_keep_their_std(synth_drive):
    """The drive's texture at noise variance 10: the keyframe's gradients are the texture's,
    and the factor is 1 on every draw; with the second frame at half the contrast too (its
    gradients are halved, not noisier: without the intensity spreads' ratio the factor read
    1.74 on the first draw)."""
    cfg, imgs, _ = _pair(synth_drive)
    for est, key, pyr in _fits(cfg, imgs, 1.0, np.sqrt(10.0)):
        assert noise_factor(key.levels[0], key.plane, pyr[0], est.cur_from_key, est.weights) == 1.0
    darker = [imgs[0], 0.5 * imgs[1] + 64.0]
    for est, key, pyr in _fits(cfg, darker, 1.0, np.sqrt(10.0)):
        assert est.gain == pytest.approx(0.5, abs=0.02)
        assert noise_factor(key.levels[0], key.plane, pyr[0], est.cur_from_key, est.weights) == 1.0


def test_low_texture_under_heavy_noise_widens_the_std_to_the_errors(synth_drive):
    """The same frames at a tenth and a twentieth of their contrast under noise of sigma 5:
    the points' gradients are mostly noise, and the fits' errors spread 3.3-6.5 and 14-18
    times their noise-only std per axis over the draws. The factor (measured 3.8-4.2 and
    22-47) brings the spread to 0.82-1.58 and 0.42-0.83 on every axis."""
    cfg, imgs, truth = _pair(synth_drive)
    for contrast, least in ((0.1, 3.0), (0.05, 10.0)):
        z, zf = [], []
        for est, key, pyr in _fits(cfg, imgs, contrast, 5.0):
            D = est.cur_from_key @ se3_inv(truth)
            e = np.r_[D[:3, 3], so3_log(D[:3, :3])]
            std = np.sqrt(np.diag(est.covariance))
            f = noise_factor(key.levels[0], key.plane, pyr[0], est.cur_from_key, est.weights)
            z.append(e / std)
            zf.append(e / (f * std))
        spread, widened = np.std(z, axis=0), np.std(zf, axis=0)
        assert np.all(spread > least), (contrast, spread)
        assert np.all((widened > 0.3) & (widened < 2.0)), (contrast, widened)
