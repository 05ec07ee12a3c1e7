"""benchmarks.crb's bound from the rendered frames: frame 0's band-limited reconstruction and
its gradient, and the information it gives against the former bound (the texture known).
"""

from __future__ import annotations

import numpy as np

from benchmarks.common import pair_renderer, pair_scenes
from benchmarks.crb import BandLimited, information, sampled_model
from monovo_cli.synth.render import PsfRenderer
from monovo_cli.synth.write import synthesize


def _dct_image(h: int, w: int, rng):
    """A sum of the half-sample-symmetric cosines below 0.42 cycles/px, and its gradient:
    band-limited exactly in the sense of the reconstruction."""
    K = 40
    kx, ky = rng.integers(1, int(0.84 * w), K), rng.integers(1, int(0.84 * h), K)
    amp = rng.uniform(5.0, 20.0, K)

    def value(x, y):
        return sum(a * np.cos(np.pi * i * (x + 0.5) / w) * np.cos(np.pi * j * (y + 0.5) / h)
                   for a, i, j in zip(amp, kx, ky))

    def grad(x, y):
        gx = sum(-a * np.pi * i / w * np.sin(np.pi * i * (x + 0.5) / w)
                 * np.cos(np.pi * j * (y + 0.5) / h) for a, i, j in zip(amp, kx, ky))
        gy = sum(-a * np.pi * j / h * np.cos(np.pi * i * (x + 0.5) / w)
                 * np.sin(np.pi * j * (y + 0.5) / h) for a, i, j in zip(amp, kx, ky))
        return gx, gy

    return value, grad


def test_band_limited_gradient_is_the_analytic_one():
    rng = np.random.default_rng(0)
    h, w = 60, 80
    value, grad = _dct_image(h, w, rng)
    y, x = np.mgrid[0:h, 0:w].astype(float)
    rec = BandLimited(value(x, y))
    # through the samples
    v, _, _ = rec.at(x.ravel(), y.ravel())
    np.testing.assert_allclose(v, value(x, y).ravel(), atol=0.05)
    # between them, up to the borders
    px, py = rng.uniform(0, w - 1, 5000), rng.uniform(0, h - 1, 5000)
    v, gx, gy = rec.at(px, py)
    tx, ty = grad(px, py)
    energy = np.mean(tx ** 2 + ty ** 2)
    assert np.sqrt(np.mean((gx - tx) ** 2 + (gy - ty) ** 2) / energy) < 0.01
    assert abs(np.mean(gx ** 2 + gy ** 2) / energy - 1.0) < 0.005
    assert np.sqrt(np.mean((v - value(px, py)) ** 2)) < 0.01 * np.std(value(x, y))


def test_band_limited_frames_give_the_former_bound(tmp_path):
    """Where the renders do not alias (a PSF of 0.8 px), frame 0's samples predict frame 1:
    the bound from the rendered frames is the one with the texture known, and the
    prediction's mismatch is small."""
    root = tmp_path / "pairs"
    synthesize(root, preset="pairs", frames=2, size=(96, 80), noise_var=0.0, seed=3, psf=0.8)
    cam, tex, scenes = pair_scenes(root)
    renderer = pair_renderer(root, cam, tex)
    assert isinstance(renderer, PsfRenderer) and renderer.sigma == 0.8
    for sc in scenes:
        former = information(cam, tex, sc, renderer)[0]
        model = sampled_model(cam, sc, renderer)
        ratio = np.sqrt(np.diag(np.linalg.inv(model.info)) / np.diag(np.linalg.inv(former)))
        assert np.all(np.abs(ratio - 1.0) < 0.05), ratio
        assert np.sqrt(model.mismatch_ms) < 1.0
