"""Keyframe thumbnails: a keyframe's image, small, with the ground region and the glued
triangle (:mod:`monovo_cli.viz.overlay`) as the run left it on that frame.

The triangle is glued to the ground from frame 0 and re-placed at keyframes, as the overlay
places it; a thumbnail shows it as carried to its keyframe by the poses just *before* it is
re-placed there, so how far it slid since the last keyframe can be seen frame by frame.

Pure: arrays in, BGR uint8 images out.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.viz.draw import draw_polygon, to_bgr
from monovo_cli.viz.overlay import OverlayRenderer, OverlayStyle, default_triangle_pixels, triangle_on_ground

REGION = (255, 255, 0)  # cyan


def keyframe_thumbnails(images: Mapping[int, np.ndarray], camera: PinholeCamera, plane: Plane,
                        region: tuple[int, int, int, int], index: Sequence[int],
                        world_from_cam: np.ndarray, status: Sequence[str], *,
                        style: OverlayStyle | None = None) -> dict[int, np.ndarray]:
    """Each thumbnail of ``images`` (frame index -> (h, w) uint8 grey, the frame scaled
    down by ``h / camera.height``) drawn as BGR uint8 (h, w, 3) with the ground ``region``
    (x0, y0, x1, y1 px of the full frame; x1, y1 exclusive) and the glued triangle.

    ``plane`` the ground in camera-0 coordinates; ``index`` (N,), ``world_from_cam``
    (N, 4, 4) T_0_k and ``status`` (N,) of the run's frames, in order. A frame of
    ``images`` that is not in ``index`` is left out.
    """
    style = style or OverlayStyle()
    pixels = default_triangle_pixels(region)
    renderer = OverlayRenderer(camera, plane, triangle_on_ground(camera, plane, pixels),
                               region=region, pixels=pixels)
    out: dict[int, np.ndarray] = {}
    W = np.asarray(world_from_cam, dtype=float)
    for k, pose, st in zip(index, W, status):
        k = int(k)
        if k in images:
            thumb = np.asarray(images[k])
            s = thumb.shape[0] / camera.height
            img = to_bgr(thumb)
            x0, y0, x1, y1 = region
            cv2.rectangle(img, (int(round(x0 * s)), int(round(y0 * s))),
                          (int(round((x1 - 1) * s)), int(round((y1 - 1) * s))), REGION, 1)
            uv = renderer.triangle_outline(pose)
            if len(uv) >= 3:
                # pixel centres are integers at both scales
                draw_polygon(img, (uv + 0.5) * s - 0.5, fill=style.fill, outline=style.outline,
                             alpha=style.alpha, thickness=1)
            out[k] = img
        if k > 0:
            renderer.advance(pose, st)
    return out
