"""The timeline drawing: one image, lost and re-initialised frames marked through the panels."""

import numpy as np
import pytest

from monovo_cli.core.status import FrameStatus
from monovo_cli.viz.timeline import STATUS_COLOURS, plot_timeline


def _run(n=40):
    rng = np.random.default_rng(1)
    status = [FrameStatus.OK] * n
    status[10] = FrameStatus.REANCHORED
    status[20] = status[21] = FrameStatus.LOST
    status[22] = FrameStatus.REINIT
    std = np.abs(rng.normal(1e-4, 2e-5, (n, 6)))
    std[[0, 20, 21]] = np.nan  # no estimate
    msd = rng.uniform(20, 30, n)
    points = rng.integers(1000, 2000, n)
    return np.arange(n), status, msd, points, std


def _column_has(img, x, colour):
    return np.any(np.all(img[:, x - 1:x + 2] == np.array(colour, np.uint8), axis=2))


def test_timeline_marks_lost_and_reinitialised_frames():
    index, status, msd, points, std = _run()
    img = plot_timeline(index, status, msd, points, std, size=(800, 480))
    assert img.shape == (480, 800, 3) and img.dtype == np.uint8
    h = img.shape[0]
    # the marks run through the panels below the status strip
    lower = img[h // 2:]

    def x_of(k):  # as the drawing maps frames: left 9 %, right 2 % margins
        x0, x1 = int(0.09 * 800), 800 - int(0.02 * 800)
        return int(round(x0 + k / 39 * (x1 - x0)))

    assert _column_has(lower, x_of(20), STATUS_COLOURS[FrameStatus.LOST])
    assert _column_has(lower, x_of(22), STATUS_COLOURS[FrameStatus.REINIT])
    assert not _column_has(lower, x_of(10), STATUS_COLOURS[FrameStatus.LOST])
    assert not _column_has(lower, x_of(5), STATUS_COLOURS[FrameStatus.REINIT])


def test_timeline_of_one_frame_and_bad_input():
    img = plot_timeline([0], [FrameStatus.OK], [0.0], [0], np.full((1, 6), np.nan))
    assert img.ndim == 3
    with pytest.raises(ValueError, match="expected N >= 1 frames with N statuses, got 2 and 1"):
        plot_timeline([0, 1], ["ok"], [0.0, 1.0], [0, 1], np.zeros((2, 6)))


def test_a_frame_fitted_on_no_point_leaves_gaps_not_a_perfect_fit(small_drive, tmp_path):
    """An unreadable frame skipped with --skip-bad-frames: motion.csv keeps its msd,
    iterations and points 0 (whole numbers, as the contract asks), the timeline draws none."""
    import shutil

    from monovo_cli.pipeline.tracking import track_frames
    from monovo_cli.viz.timeline import timeline_curves

    seq = tmp_path / "seq"
    shutil.copytree(small_drive, seq)
    (seq / "frames" / "frame_000004.png").write_bytes(b"not a png")
    run = track_frames(seq, skip_bad_frames=True)
    assert run.status[4] == FrameStatus.LOST and run.reason[4] == "unreadable frame"
    assert (run.msd[4], run.iterations[4], run.points[4]) == (0, 0, 0)
    curves = dict(timeline_curves(run.msd, run.points, run.std))
    for name in ("msd (grey levels^2)", "points"):
        assert np.isnan(curves[name][[0, 4]]).all(), name  # gaps, not 0
        assert np.isfinite(curves[name][[1, 2, 3, 5, 6, 7, 8, 9]]).all(), name
        assert np.nanmin(curves[name]) > 1.0, name  # nothing dips to a perfect fit
    np.testing.assert_allclose(curves["msd (grey levels^2)"][5:], run.msd[5:], rtol=0)
    # the prediction's std of the lost frame is a stated value: drawn
    assert np.isfinite(curves["std translation (mm)"][4])
    # the drawing is the one of the same run with no values there at all
    gap = np.asarray(run.msd, float).copy(), np.asarray(run.points, float).copy()
    gap[0][4] = gap[1][4] = np.nan
    drawn = plot_timeline(run.index, run.status, run.msd, run.points, run.std, size=(600, 400))
    np.testing.assert_array_equal(
        drawn, plot_timeline(run.index, run.status, *gap, run.std, size=(600, 400)))
