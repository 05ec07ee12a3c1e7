"""What track writes at the end: the plots' titles and the height map's reference plane."""

from __future__ import annotations

import shutil

import numpy as np

from monovo_cli.core.options import TrackOptions
from monovo_cli.mapping.terrain_map import HeightGrid, heights_off_best_plane
from monovo_cli.pipeline import products
from monovo_cli.pipeline.track import track_sequence


def _titles(monkeypatch) -> dict[str, str]:
    """Record the titles the plots are drawn with."""
    import monovo_cli.viz.heightmap as heightmap
    import monovo_cli.viz.plots as plots

    seen: dict[str, str] = {}
    for module, name in ((plots, "plot_trajectory"), (heightmap, "plot_height_map")):
        draw = getattr(module, name)

        def spy(*args, _draw=draw, _name=name, **kwargs):
            seen[_name] = kwargs["title"]
            return _draw(*args, **kwargs)

        monkeypatch.setattr(module, name, spy)
    return seen


def test_the_plots_are_titled_with_the_sequence_not_the_output_folder(small_drive, tmp_path,
                                                                      monkeypatch):
    seq = tmp_path / "sol0042_navcam"
    shutil.copytree(small_drive, seq)
    seen = _titles(monkeypatch)
    track_sequence(seq, None, tmp_path / "out", TrackOptions(), terrain_out=True)
    assert seen["plot_trajectory"].startswith("sol0042_navcam: 10 frames")
    assert seen["plot_height_map"].startswith("sol0042_navcam: heights above the best-fit plane")
    seen.clear()
    track_sequence(seq / "frames", seq / "init.yaml", tmp_path / "out2", TrackOptions())
    assert seen["plot_trajectory"].startswith("sol0042_navcam: ")


def test_sequence_name_of_a_folder_its_frames_and_a_video(tmp_path):
    assert products.sequence_name(tmp_path / "drive" / "frames") == "drive"
    assert products.sequence_name(tmp_path / "drive") == "drive"
    assert products.sequence_name(tmp_path / "sol1" / "drive.mp4") == "drive.mp4"


def _rolling_on_a_ramp() -> tuple[HeightGrid, np.ndarray]:
    """±4 cm rolling terrain (period 1 m) seen from a ground frame tilted by 4 deg, offset
    1 cm: the grid and the relief alone."""
    cell = 0.05
    jj, ii = np.indices((60, 20))
    x, y = -0.5 + (ii + 0.5) * cell, 0.5 + (jj + 0.5) * cell
    relief = 0.04 * np.sin(2 * np.pi * y) * np.cos(np.pi * x)
    height = relief + np.tan(np.radians(4.0)) * y + 0.01
    count = np.full(height.shape, 7)
    count[::5, ::3] = 0
    height[count == 0] = np.nan
    # the relief alone: what is left of it after its own least-squares plane (all cells
    # weigh the same)
    ok = count > 0
    A = np.stack([x[ok], y[ok], np.ones(ok.sum())], axis=1)
    coef = np.linalg.lstsq(A, relief[ok], rcond=None)[0]
    relief = relief - (coef[0] * x + coef[1] * y + coef[2])
    return HeightGrid(-0.5, 0.5, cell, height, count), relief


def test_height_map_png_shows_the_relief_not_frame_0s_tilt():
    grid, relief = _rolling_on_a_ramp()
    off = heights_off_best_plane(grid)
    ok = grid.count > 0
    assert np.array_equal(np.isnan(off.height), ~ok)
    assert np.nanmax(np.abs(grid.height)) > 0.2  # the ramp: -0.2 .. +0.2 m from frame 0's ground
    np.testing.assert_allclose(off.height[ok], relief[ok], atol=1e-9)
    assert np.nanmax(np.abs(off.height)) < 0.05


def test_height_map_png_is_drawn_off_the_best_fit_plane(tmp_path, monkeypatch):
    """write_terrain draws heights off the best-fit plane; heightmap.csv keeps frame 0's."""
    grid, relief = _rolling_on_a_ramp()

    class Terrain:  # what write_terrain asks of a TerrainMap
        def points(self, drive):
            return np.zeros((3, 3)), np.zeros(3, np.float32)

        def height_grid(self, drive):
            return grid

        def ground_from_world(self, drive):
            return np.eye(4)

    import monovo_cli.viz.heightmap as heightmap

    drawn = {}
    draw = heightmap.plot_height_map

    def spy(g, **kwargs):
        drawn["grid"] = g
        return draw(g, **kwargs)

    monkeypatch.setattr(heightmap, "plot_height_map", spy)
    products.write_terrain(tmp_path, Terrain(), np.eye(4)[None], None, "seq")
    ok = grid.count > 0
    np.testing.assert_allclose(drawn["grid"].height[ok], relief[ok], atol=1e-9)
    cells = np.loadtxt(tmp_path / "heightmap.csv", delimiter=",", skiprows=1, ndmin=2)
    assert np.nanmax(cells[:, 2]) > 0.2  # the CSV: heights above frame 0's ground, as before
