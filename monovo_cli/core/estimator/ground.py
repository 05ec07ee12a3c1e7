"""The planar ground model of section 10.2.5 and its observation points.

The model is a rectangle of two triangles lying on the ground plane, expressed in the
camera frame of the keyframe it was built on (x right, y down, z forward, metres). An
observation point is a keyframe pixel inside the model's image with a Sobel gradient
magnitude above ``threshold`` (the paper's delta_1), lifted onto the plane by
intersecting its viewing ray with the plane; it carries its intensity and gradient. How
many points each level keeps and why: docs/algorithm.md section 3, "Observation points".
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import sobel_gradient, spline_gradient


@dataclass(frozen=True)
class LevelPoints:
    """Observation points of one pyramid level, in the keyframe camera.

    ``uv`` (N, 2) float64 px of that level; ``X`` (N, 3) float64 m; ``intensity`` (N,)
    float32 grey levels; ``grad`` (N, 2) float32 grey levels per px; ``corners`` (4, 3) the
    model rectangle the points are glued to. ``tri`` (N,) int8 the triangle (0 or 1) and
    ``bary`` (N, 3) float32 the barycentric coordinates on it are worked out when first
    asked for (tracking never needs them; the saved model carries them).
    """

    level: int
    camera: PinholeCamera
    uv: np.ndarray
    X: np.ndarray
    intensity: np.ndarray
    grad: np.ndarray
    corners: np.ndarray

    def __len__(self) -> int:
        return len(self.uv)

    @cached_property
    def _triangles(self) -> tuple[np.ndarray, np.ndarray]:
        tri, bary = barycentric(self.X, self.corners)
        return tri, bary.astype(np.float32)

    @property
    def tri(self) -> np.ndarray:
        """(N,) int8: the model triangle (0 or 1) each point lies on."""
        return self._triangles[0]

    @property
    def bary(self) -> np.ndarray:
        """(N, 3) float32: each point's barycentric coordinates on its triangle."""
        return self._triangles[1]


def default_threshold(noise_sigma: float) -> float:
    """Default delta_1 (grey levels per px) for image noise ``noise_sigma`` (grey levels):
    three times the std of one Sobel component of pure noise (0.433 sigma), at least 1
    (docs/algorithm.md section 3, "Observation points")."""
    return max(1.0, 3.0 * 0.433 * noise_sigma)


def rectangle_corners(camera: PinholeCamera, plane: Plane,
                      region: tuple[int, int, int, int]) -> np.ndarray:
    """The model rectangle's 4 corners (4, 3) m: the region's corner pixels lifted onto the plane.

    Order: top-left, top-right, bottom-right, bottom-left; triangles (0, 1, 2) and (0, 2, 3).
    """
    x0, y0, x1, y1 = region
    uv = np.array([[x0 - 0.5, y0 - 0.5], [x1 - 0.5, y0 - 0.5],
                   [x1 - 0.5, y1 - 0.5], [x0 - 0.5, y1 - 0.5]], dtype=float)
    return plane.intersect(camera.rays(uv))


def in_front(points: np.ndarray) -> bool:
    """Whether rays met the plane in front of the camera: ``points`` (N, 3), their
    intersections (:func:`rectangle_corners`', ``Plane.intersect``'s; a ray that misses the
    plane gives NaN)."""
    return bool(np.all(np.isfinite(points)) and np.all(points[:, 2] > 0))


TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])


def barycentric(X: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangle index (N,) and barycentric coordinates (N, 3) of plane points ``X`` (N, 3).

    Points outside both triangles get triangle -1.
    """
    tri = np.full(len(X), -1, dtype=np.int8)
    bary = np.zeros((len(X), 3))
    for k, (i, j, m) in enumerate(TRIANGLES):
        a, b, c = corners[i], corners[j], corners[m]
        v0, v1, v2 = b - a, c - a, X - a
        d00, d01, d11 = v0 @ v0, v0 @ v1, v1 @ v1
        d20, d21 = v2 @ v0, v2 @ v1
        den = d00 * d11 - d01 * d01
        lb = (d11 * d20 - d01 * d21) / den
        lc = (d00 * d21 - d01 * d20) / den
        la = 1.0 - lb - lc
        inside = (tri < 0) & (la >= -1e-9) & (lb >= -1e-9) & (lc >= -1e-9)
        tri[inside] = k
        bary[inside] = np.stack([la, lb, lc], 1)[inside]
    return tri, bary


def _even_spread(score: np.ndarray, cap: int, area: int, per_block: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of at most ``cap`` pixels with ``score > 0``, spread over the image.

    The image is cut into square blocks sized so that ``per_block`` points per block fill the
    cap over ``area`` pixels; each block keeps its ``per_block`` strongest candidates, and if
    that is still more than ``cap`` the strongest overall are kept (of equal ones, the first
    in row-major order). Blocks of ``per_block`` pixels or fewer (with 4 per block, a cap of
    more than 4/9 of the area: the finest level's) would keep every candidate, so the
    strongest are then taken directly.
    Rows and columns come back in row-major order.
    """
    positive = score > 0
    if np.count_nonzero(positive) <= cap:
        return np.nonzero(positive)
    h, w = score.shape
    s = max(2, int(np.sqrt(per_block * area / cap)))
    if per_block >= s * s:  # every block would keep all its candidates: the strongest overall
        flat = score.ravel()  # (flat indices: half the time of np.nonzero's row/column pairs)
        at = np.flatnonzero(positive.ravel())
        vals = flat[at]
        kth = len(vals) - cap
        threshold = np.partition(vals, kth)[kth]  # the cap-th largest
        keep = vals > threshold
        ties = np.flatnonzero(vals == threshold)[:cap - int(np.count_nonzero(keep))]
        keep[ties] = True  # (those equal to it first in row-major order)
        return np.divmod(at[keep], w)
    hb, wb = -(-h // s), -(-w // s)
    padded = np.zeros((hb * s, wb * s), np.float32)
    padded[:h, :w] = score
    blocks = padded.reshape(hb, s, wb, s).transpose(0, 2, 1, 3).reshape(hb * wb, s * s)
    q = min(per_block, s * s)
    top = np.argpartition(-blocks, q - 1, axis=1)[:, :q]
    vals = np.take_along_axis(blocks, top, axis=1)
    b, j = np.nonzero(vals > 0)  # (block, rank) of the candidates, block by block
    top, vals = top[b, j], vals[b, j]
    if len(vals) > cap:
        best = np.argpartition(-vals, cap - 1)[:cap]
        top, b = top[best], b[best]
    # row-major order, as np.nonzero gives it (the pixels are distinct)
    chosen = np.zeros((hb * s, wb * s), bool)
    chosen[(b // wb) * s + top // s, (b % wb) * s + top % s] = True
    return np.nonzero(chosen[:h, :w])


def select_points(image: np.ndarray, camera: PinholeCamera, plane: Plane, corners: np.ndarray,
                  *, level: int, threshold: float, max_points: int,
                  mask: np.ndarray | None = None, border: int = 2,
                  spline: bool = False) -> LevelPoints:
    """Observation points of one pyramid level (section 10.2.5, step 4).

    ``image`` (H, W) float32 is the keyframe at this level, ``camera`` its camera, ``corners``
    the model rectangle (4, 3) in the keyframe camera, ``mask`` (H, W) bool of usable pixels.
    Pixels inside the projected rectangle with ``|Sobel| > threshold`` are kept, at most
    ``max_points`` of them spread evenly over the image. Their gradients are the Sobel ones,
    or with ``spline`` the exact derivatives of the cubic B-spline interpolating the level
    (a better estimate of the gradient of the sampled image than Sobel's).
    """
    h, w = image.shape
    gx, gy = sobel_gradient(image)
    mag = np.hypot(gx, gy)
    poly = camera.project(corners)
    inside = np.zeros((h, w), np.uint8)
    if np.all(np.isfinite(poly)):
        cv2.fillConvexPoly(inside, np.round(poly * 16).astype(np.int32), 1, shift=4)
    ok = (mag > threshold) & inside.astype(bool)
    ok[:border] = ok[-border:] = False
    ok[:, :border] = ok[:, -border:] = False
    if mask is not None:
        ok &= mask
    ys, xs = _even_spread(np.where(ok, mag, 0.0).astype(np.float32), max_points,
                          max(int(np.count_nonzero(inside)), 1))
    uv = np.stack([xs, ys], 1).astype(np.float64)
    X = plane.intersect(camera.rays(uv))
    good = X[:, 2] > 1e-6  # (rays have z = 1: a ray that misses the plane is NaN here)
    if not np.all(good):
        uv, X, ys, xs = uv[good], X[good], ys[good], xs[good]
    if spline:
        gx, gy = spline_gradient(image)
    at = ys * w + xs  # (one flat index for the three gathers)
    return LevelPoints(level=level, camera=camera, uv=uv, X=X,
                       intensity=image.ravel()[at].astype(np.float32),
                       grad=np.stack([gx.ravel()[at], gy.ravel()[at]], 1).astype(np.float32),
                       corners=corners)


def require_points(points: LevelPoints, *, minimum: int, threshold: float,
                   textured: int | None = None) -> None:
    """Raise TrackingError when ``points`` (a keyframe level's) are fewer than ``minimum``,
    too few to estimate 6 DoF; the message names the gradient ``threshold`` they passed.

    ``textured``: the points any gradient at all would give (those of a threshold of 0), or
    None when not known. When they are fewer than ``minimum`` too, no threshold helps (a
    blank, saturated or black region) and the message says so instead of suggesting a
    lower threshold.
    """
    if len(points) >= minimum:
        return
    found = (f"only {len(points)} observation points with gradient > {threshold:.3g} in the "
             f"ground region (need {minimum})")
    if textured is not None and textured < minimum:
        raise TrackingError(
            f"{found}, and no threshold would give enough: only {textured} of its pixels "
            "have any gradient (a blank, over- or under-exposed frame?); check the frame or "
            "choose another region")
    raise TrackingError(f"{found}; lower the gradient threshold or choose another region")
