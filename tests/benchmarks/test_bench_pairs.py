"""benchmarks.common.pair_scenes replays the pairs synth wrote, whatever their texture.

The Cramér–Rao bound of benchmarks.crb (and issue 13's pairs on three textures in
benchmarks.real_synth) re-renders each pair from these poses and this texture, so both must be
exactly synth's: the noise-free frames re-rendered from them must equal the PNGs.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from benchmarks.common import pair_renderer, pair_scenes
from monovo_cli.synth.write import synthesize


@pytest.mark.parametrize("texture, psf", [(None, 0.0), ("gravel", 0.0), ("image", 0.0),
                                          ("gravel", 0.5)])
def test_pair_scenes_rerender_the_frames(tmp_path, texture, psf):
    if texture == "image":
        rng = np.random.default_rng(5)
        img = cv2.resize(rng.uniform(0, 255, (40, 40)), (256, 256), interpolation=cv2.INTER_CUBIC)
        texture = tmp_path / "ground.png"
        cv2.imwrite(str(texture), np.clip(img, 0, 255).astype(np.uint8))
    root = tmp_path / "pairs"
    synthesize(root, preset="pairs", frames=2, size=(96, 80), noise_var=0.0, seed=3,
               texture=texture, psf=psf)
    cam, tex, scenes = pair_scenes(root)
    renderer = pair_renderer(root, cam, tex)  # the optics too (synth.yaml's psf)
    assert len(scenes) == 2
    for sc in scenes:
        for k, g in enumerate((sc.g_from_cam0, sc.g_from_cam1)):
            png = cv2.imread(str(sc.directory / "frames" / f"frame_{k:06d}.png"), cv2.IMREAD_GRAYSCALE)
            again = renderer.render(g)
            # noise-free frames are the render rounded to whole grey levels
            assert np.abs(again - png.astype(np.float32)).max() <= 0.5 + 1e-3


def test_pair_scenes_refuses_exposure_changes(tmp_path):
    root = tmp_path / "pairs"
    synthesize(root, preset="pairs", frames=1, size=(96, 80), noise_var=0.0, seed=3, exposure=True)
    with pytest.raises(ValueError, match="exposure"):
        pair_scenes(root)
