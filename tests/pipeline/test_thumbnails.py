"""Keyframe thumbnails: kept small and bounded during the run, drawn with the region and
the glued triangle."""

import numpy as np

from monovo_cli.core.options import TrackOptions
from monovo_cli.pipeline.tracking import Tracking, open_sequence
from monovo_cli.viz.overlay import OverlayStyle, default_triangle_pixels


def test_thumbnails_are_bounded_and_spread(small_drive):
    opts = TrackOptions(reanchor_fraction=0.95)  # a keyframe on most frames
    tracking = Tracking(open_sequence(small_drive), opts, thumbnails=3, thumbnail_side=40)
    for _ in tracking:
        pass
    keys = [k.index for k in tracking.result().keyframes]
    assert len(keys) > 3
    kept = sorted(tracking.thumbnails)
    assert 2 <= len(kept) <= 3 and kept[0] == 0 and set(kept) <= set(keys)
    assert all(t.dtype == np.uint8 and max(t.shape) <= 40 for t in tracking.thumbnails.values())
    assert not Tracking(open_sequence(small_drive)).thumbnails  # none unless asked


def test_thumbnail_shows_the_triangle_where_it_was_placed(small_drive):
    from monovo_cli.viz.thumbnails import REGION, keyframe_thumbnails

    seq = open_sequence(small_drive)
    tracking = Tracking(seq, thumbnails=4, thumbnail_side=64)
    for _ in tracking:
        pass
    run = tracking.result()
    cfg = seq.config
    drawn = keyframe_thumbnails(tracking.thumbnails, cfg.camera, cfg.plane, cfg.region,
                                run.index, run.trajectory, run.status)
    assert sorted(drawn) == sorted(tracking.thumbnails)
    img = drawn[0]
    assert img.shape == (*tracking.thumbnails[0].shape, 3) and img.dtype == np.uint8
    s = img.shape[0] / cfg.camera.height
    cx, cy = (default_triangle_pixels(cfg.region).mean(axis=0) + 0.5) * s - 0.5
    b, g, r = (int(v) for v in img[int(round(cy)), int(round(cx))])
    fill = OverlayStyle().fill
    assert r > b + 40 and abs(r - g) > 20, (b, g, r, fill)  # orange over grey ground
    x0, y0, _, _ = cfg.region
    assert tuple(img[int(round(y0 * s)), int(round(x0 * s)) + 3]) == REGION  # the region's edge
