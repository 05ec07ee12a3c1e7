"""The feature hypothesis on the current frame seen from the reference: the current image
warped into the reference camera by the predicted motion over the ground plane, its features
matched there and mapped back (docs/algorithm.md section 8, "Capture search").

Two or three MER steps on, the ground a reference saw far ahead lies under the current
camera: its features have grown one and a half to two times and turned with the perspective,
and on a texture of look-alike grains (gravel) few matches survive the ratio test. Warped into
the reference's view by the prediction, the current image differs from the reference by the
prediction's error only, a small shift and turn, which ORB matches as it matches consecutive
frames. The keypoints found in the warped image are mapped back to the current frame's own
pixels, so the hypothesis is computed as for unwarped images
(:func:`~monovo_cli.core.recovery.features.motion_from_features`) and takes nothing from the
prediction but where to look.
"""

from __future__ import annotations

import cv2
import numpy as np

from monovo_cli.core.options import FeatureOptions
from monovo_cli.core.recovery.features import (
    MASK_GRID_PX,
    FeatureMotion,
    Features,
    detect_features,
    ground_mask,
    motion_from_features,
)
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane

MIN_DEPTH = 1e-3  # m: a ground point closer to the current camera's image plane is not mapped


def view_map(camera: PinholeCamera, plane: Plane, cur_from_ref: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(map_x, map_y)`` (H, W) float32: the current frame's full-resolution pixel of the ground
    point seen at each reference pixel, ``plane`` (reference camera) moved by ``cur_from_ref``
    (4x4); -1 where the ray misses the plane or the point is behind the current camera.

    Evaluated on a grid of MASK_GRID_PX pixels (rays, lens model) and interpolated
    bilinearly: the map is smooth where the ground is seen.
    """
    w, h = camera.width, camera.height
    xs = np.unique(np.append(np.arange(0, w, MASK_GRID_PX), w - 1)).astype(float)
    ys = np.unique(np.append(np.arange(0, h, MASK_GRID_PX), h - 1)).astype(float)
    gx, gy = np.meshgrid(xs, ys)
    X = plane.intersect(camera.rays(np.stack([gx.ravel(), gy.ravel()], axis=1)))
    Xc = X @ cur_from_ref[:3, :3].T + cur_from_ref[:3, 3]
    ok = np.all(np.isfinite(Xc), axis=1) & (np.nan_to_num(Xc[:, 2], nan=-1.0) > MIN_DEPTH)
    uv = np.full((len(X), 2), -1.0)
    if ok.any():
        uv[ok] = camera.project(Xc[ok])
    coarse = np.concatenate([uv.reshape(len(ys), len(xs), 2),
                             ok.reshape(len(ys), len(xs), 1)], axis=2).astype(np.float32)
    mx = np.interp(np.arange(w, dtype=float), xs, np.arange(len(xs), dtype=float)).astype(np.float32)
    my = np.interp(np.arange(h, dtype=float), ys, np.arange(len(ys), dtype=float)).astype(np.float32)
    fine = cv2.remap(coarse, np.broadcast_to(mx, (h, w)).copy(),
                     np.broadcast_to(my[:, None], (h, w)).copy(), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)
    valid = fine[..., 2] >= 1.0 - 1e-6  # every grid node around it mapped
    map_x = np.where(valid, fine[..., 0], -1.0).astype(np.float32)
    map_y = np.where(valid, fine[..., 1], -1.0).astype(np.float32)
    return map_x, map_y


def predicted_view_motion(ref_image: np.ndarray, cur_image: np.ndarray, camera: PinholeCamera,
                          plane: Plane, cur_from_ref: np.ndarray, *,
                          mask: np.ndarray | None = None,
                          region: tuple[int, int, int, int] | None = None,
                          options: FeatureOptions = FeatureOptions()) -> FeatureMotion | None:
    """Motion hypothesis ``cur_from_ref`` between two grey frames (H, W) over the known ground,
    matched in the reference's view (module docstring).

    ``plane`` is the ground in the reference camera, ``cur_from_ref`` (4x4) the predicted
    motion that warps the current frame into the reference's view; ``mask`` (H, W, non-zero
    = usable, in either frame), ``region`` (``[x0, y0, x1, y1]`` px, the reference's) and
    ``options`` as for :func:`~monovo_cli.core.recovery.features.feature_motion`. None when
    there is too little to go on; deterministic.
    """
    h, w = ref_image.shape
    map_x, map_y = view_map(camera, plane, cur_from_ref)
    inside = (map_x >= 0) & (map_x <= w - 1) & (map_y >= 0) & (map_y <= h - 1)
    warped = cv2.remap(np.asarray(cur_image, dtype=np.float32), map_x, map_y, cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    usable = inside
    if mask is not None:
        m = (np.asarray(mask) != 0).astype(np.uint8)
        usable = usable & (m != 0) & (cv2.remap(m, map_x, map_y, cv2.INTER_NEAREST,
                                                  borderMode=cv2.BORDER_CONSTANT) != 0)
    level = options.level_for(camera)
    both = ground_mask(camera, plane, level=level, min_depression_deg=options.min_depression_deg,
                       region=region, usable=usable)
    if not both.any():
        return None
    ref = detect_features(ref_image, camera, mask=both, options=options)
    seen = detect_features(warped, camera, mask=both, options=options)
    if not len(seen):
        return None
    X = plane.intersect(seen.rays)
    Xc = X @ cur_from_ref[:3, :3].T + cur_from_ref[:3, 3]
    ok = np.all(np.isfinite(Xc), axis=1) & (np.nan_to_num(Xc[:, 2], nan=-1.0) > MIN_DEPTH)
    if not ok.any():
        return None
    uv = camera.project(Xc[ok])
    cur = Features(uv, camera.rays(uv), seen.descriptors[ok])
    return motion_from_features(ref, cur, camera, plane, options=options)
