"""heightmap.png's drawing: sparse far cells neither set the colours nor the picture, and the
colour bar has several labelled ticks with their unit."""

import cv2
import numpy as np

from monovo_cli.mapping.terrain_map import HeightGrid
from monovo_cli.viz.heightmap import (
    SPARSE,
    cell_colours,
    colour_bar_ticks,
    drawn_extent,
    height_range,
    plot_height_map,
)


def _strip(seed=3):
    """40 x 30 cells of 5 cm: the 20 near rows seen often (12 points each) on a 3 cm ramp, one
    hole in them seen once; the 20 far rows seen once each, heights +-30 cm of noise."""
    rng = np.random.default_rng(seed)
    height = np.empty((40, 30))
    height[:20] = np.linspace(0.0, 0.03, 20)[:, None]
    height[20:] = rng.uniform(-0.3, 0.3, (20, 30))
    count = np.full((40, 30), 12)
    count[20:] = 1
    height[5, 7], count[5, 7] = 0.3, 1  # a sparse cell among the near ones
    return HeightGrid(-0.75, 0.4, 0.05, height, count)


def _viridis(v: float) -> np.ndarray:
    return cv2.applyColorMap(np.array([[round(255 * v)]], np.uint8), cv2.COLORMAP_VIRIDIS)[0, 0]


def test_sparse_cells_set_neither_the_colour_range_nor_the_picture():
    grid = _strip()
    lo, hi = height_range(grid)
    assert -1e-3 < lo < 2e-3 and 0.028 < hi < 0.0305  # the near ramp's, not +-30 cm
    colours = cell_colours(grid)
    np.testing.assert_array_equal(colours[20:].reshape(-1, 3), np.tile(SPARSE, (600, 1)))
    np.testing.assert_array_equal(colours[5, 7], SPARSE)
    # the well-observed ramp spans the colour map: its low end to its high end
    assert np.abs(colours[0, 0].astype(int) - _viridis(0.0)).max() <= 8
    assert np.abs(colours[19, 0].astype(int) - _viridis(1.0)).max() <= 8
    assert drawn_extent(grid) == (slice(0, 20), slice(0, 30))  # the far rows are not drawn
    img = plot_height_map(grid, size=(600, 500))
    assert img.shape == (500, 600, 3)
    top = np.all(np.abs(img.astype(int) - _viridis(1.0)) <= 8, axis=2).sum()
    grey = np.all(img == np.array(SPARSE, np.uint8), axis=2).sum()
    assert top > 500 and 0 < grey < 0.1 * top  # the ramp fills the map; one grey cell and the key


def test_colour_bar_has_several_labelled_ticks_in_one_unit():
    for lo, hi, unit in ((-6e-5, 5e-5, "mm"), (0.0003, 0.0297, "cm"), (-0.004, 0.0085, "cm"),
                         (-0.8, 1.3, "m")):
        got, ticks = colour_bar_ticks(lo, hi)
        assert got == unit, (lo, hi)
        assert 4 <= len(ticks) <= 10, ticks
        assert all(lo - 1e-12 <= v <= hi + 1e-12 for v, _ in ticks)
        decimals = {len(t.split(".")[1]) if "." in t else 0 for _, t in ticks}
        assert len(decimals) == 1, ticks  # one format
        scale = {"mm": 1e3, "cm": 100.0, "m": 1.0}[unit]
        for v, t in ticks:
            assert abs(float(t) - v * scale) < 1e-9 * scale + 10.0 ** -max(decimals) / 2, (v, t)
        assert "-0" not in [t.rstrip("0").rstrip(".") for _, t in ticks]
