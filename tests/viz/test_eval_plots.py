"""The eval plots: the right size, the paths, the series and the band drawn where they belong."""

import numpy as np

from monovo_cli.viz.eval_plots import (
    BAND,
    OUTSIDE,
    plane_of_drive,
    plot_axis_errors,
    plot_errors_over,
    plot_paths_from_above,
)
from monovo_cli.viz.plots import BACKGROUND, ESTIMATE, TRUTH


def _has(img, colour, at_least=50):
    return int(np.all(img == np.array(colour, np.uint8), axis=2).sum()) >= at_least


def _colours(img):
    """The distinct colours of an (H, W, 3) uint8 image, each pixel packed into one integer
    (``np.unique(..., axis=0)`` counts the same rows but sorts them as records, 100x slower)."""
    return len(np.unique((img[..., 0].astype(np.uint32) << 16)
                         | (img[..., 1].astype(np.uint32) << 8) | img[..., 2]))


def _circle(n=80):
    a = np.linspace(0, np.pi, n)
    return np.stack([np.cos(a), 0.1 * np.sin(3 * a), np.sin(a)], 1) * 2.0  # in the x-z plane


def test_paths_from_above_in_the_drives_plane():
    gt = _circle()
    origin, along, across = plane_of_drive(gt)
    assert abs(along @ [0, 1, 0]) < 0.2 and abs(across @ [0, 1, 0]) < 0.2  # y is "up"
    assert (gt[-1] - gt[0]) @ along > 0
    img = plot_paths_from_above(gt + 0.05, gt, title="t", size=(640, 480))
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    assert _has(img, TRUTH) and _has(img, ESTIMATE, 20)
    assert (img != np.array(BACKGROUND, np.uint8)).any(axis=2).mean() > 0.03


def test_errors_over_time_and_distance():
    x = np.arange(50.0)
    rng = np.random.default_rng(0)
    img = plot_errors_over(x, rng.random(50), rng.random(49), rng.random(49), xlabel="time (s)",
                           segments=(x[:30], rng.random(30), np.r_[[1.0] * 15, [5.0] * 15]))
    assert img.shape == (900, 1000, 3)
    rows = (img != np.array(BACKGROUND, np.uint8)).any(axis=2).mean(axis=1)
    assert (rows > 0.3).sum() > 8  # four panels' frames and grids
    assert _colours(img) > 50


def test_axis_errors_show_the_band_and_the_errors_outside_it():
    rng = np.random.default_rng(1)
    std = np.tile([0.001, 0.001, 0.001, 0.01, 0.01, 0.01], (60, 1))
    err = rng.normal(0, 1, (60, 6)) * std
    err[10, 2] = 8 * std[10, 2]
    img = plot_axis_errors(np.arange(60.0), err, std, xlabel="frame", size=(900, 1000))
    assert img.shape == (1000, 900, 3)
    assert _has(img, BAND, 10000) and _has(img, OUTSIDE, 10)
    honest = plot_axis_errors(np.arange(60.0), np.clip(err, -std, std), std, xlabel="frame")
    assert not _has(honest, OUTSIDE, 1)
