"""Rendering textured ground seen by a pinhole camera: supersampled plane homographies, sky, noise.

An optional optical blur (:class:`PsfRenderer`, ``synth --psf``) acts before the pixel: a
Gaussian point spread function blurs the supersampled image, which is then area-averaged
into pixels. A blur applied after the pixel's area average would come too late: the
texture's grain beyond the pixel grid's Nyquist frequency has then already aliased into the
samples, and no blur of the samples takes it out again.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Protocol

import cv2
import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.synth.texture import GroundTexture

SUPERSAMPLE = 4
SKY_VALUE = 190.0
FOCAL_PER_WIDTH = 0.87
# Rows whose rays dip less than this below the horizon are left out of the ground region.
REGION_MIN_DEPRESSION_DEG = 10.0


# --------------------------------------------------------------------------- geometry


def default_camera(width: int, height: int) -> PinholeCamera:
    """The synthetic camera: ``fx = fy = 0.87 * width``, principal point at the image centre."""
    f = FOCAL_PER_WIDTH * width
    return PinholeCamera(width=int(width), height=int(height), fx=f, fy=f,
                         cx=(width - 1) / 2.0, cy=(height - 1) / 2.0)


def plane_homography(cam: PinholeCamera, g_from_cam: np.ndarray) -> np.ndarray:
    """3x3 ``H`` with ``H @ (u, v, 1) ~ (x, y, 1)``: ground point ``(u, v, 0)`` of G to pixel.

    The third homogeneous coordinate of ``H @ (u, v, 1)`` is the point's depth ``z`` in the
    camera (positive in front of it). Distortion is not modelled (synthetic cameras have none).
    """
    R = g_from_cam[:3, :3]
    t = g_from_cam[:3, 3]
    Rt = R.T
    return cam.K @ np.column_stack([Rt[:, 0], Rt[:, 1], -Rt @ t])


def ground_in_camera(g_from_cam: np.ndarray) -> tuple[np.ndarray, float]:
    """Plane ``z_G = 0`` in the camera frame: unit normal ``n`` (camera to ground), distance ``d``."""
    n = -g_from_cam[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    return n / np.linalg.norm(n), float(g_from_cam[2, 3])


def supersample_matrix(s: int) -> np.ndarray:
    """Maps original pixel coordinates to the s-times supersampled grid's coordinates."""
    c = (s - 1) / 2.0
    return np.array([[s, 0.0, c], [0.0, s, c], [0.0, 0.0, 1.0]])


def grid(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)``, each (height, width) float: every pixel's column and row (``np.meshgrid``)."""
    return np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))


def pixel_size_on_plane(img_from_plane: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Size of pixels ``(x, y)`` on the plane, in plane units (max column norm of the Jacobian).

    ``img_from_plane`` maps plane coordinates to pixels; ``inf`` where the ray misses the plane.
    """
    Q = np.linalg.inv(img_from_plane)
    nw = Q[2, 0] * x + Q[2, 1] * y + Q[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (Q[0, 0] * x + Q[0, 1] * y + Q[0, 2]) / nw
        b = (Q[1, 0] * x + Q[1, 1] * y + Q[1, 2]) / nw
        j00 = (Q[0, 0] - a * Q[2, 0]) / nw
        j01 = (Q[0, 1] - a * Q[2, 1]) / nw
        j10 = (Q[1, 0] - b * Q[2, 0]) / nw
        j11 = (Q[1, 1] - b * Q[2, 1]) / nw
        rho = np.maximum(np.hypot(j00, j10), np.hypot(j01, j11))
    # img_from_plane maps (a, b, 1) to z * (x, y, 1) with depth z > 0 for visible ground, so
    # the inverse gives (a, b, 1) / z: nw > 0 exactly where the ray meets the plane ahead.
    return np.where(nw > 0, rho, np.inf)


def ray_depression(cam: PinholeCamera, g_from_cam: np.ndarray, x: np.ndarray,
                   y: np.ndarray) -> np.ndarray:
    """Angle (rad) by which the rays through pixels ``(x, y)`` dip below the horizon."""
    n, _ = ground_in_camera(g_from_cam)
    rx = (x - cam.cx) / cam.fx
    ry = (y - cam.cy) / cam.fy
    s = (n[0] * rx + n[1] * ry + n[2]) / np.sqrt(rx * rx + ry * ry + 1.0)
    return np.arcsin(np.clip(s, -1.0, 1.0))


def ground_region(cam: PinholeCamera, g_from_cam: np.ndarray,
                  min_depression_deg: float = REGION_MIN_DEPRESSION_DEG) -> list[int] | None:
    """``[x0, y0, x1, y1]`` (x1, y1 exclusive): the full-width band of rows whose every pixel
    sees the ground at least ``min_depression_deg`` below the horizon; None if there is none."""
    x, y = grid(cam.width, cam.height)
    ok = ray_depression(cam, g_from_cam, x, y) >= math.radians(min_depression_deg)
    rows_ok = ok.all(axis=1)
    if not rows_ok[-1]:
        return None
    bad = np.nonzero(~rows_ok)[0]
    y0 = int(bad[-1]) + 1 if len(bad) else 0
    return [0, y0, cam.width, cam.height]


def corner_depressions(cam: PinholeCamera, g_from_cam: np.ndarray) -> np.ndarray:
    """(4,) :func:`ray_depression` of the rays through the image's outer corners (top left,
    top right, bottom left, bottom right) for the camera at ``g_from_cam`` (4x4)."""
    x = np.array([-0.5, cam.width - 0.5, -0.5, cam.width - 0.5])
    y = np.array([-0.5, -0.5, cam.height - 0.5, cam.height - 0.5])
    return ray_depression(cam, g_from_cam, x, y)


# --------------------------------------------------------------------------- rendering


class GroundRenderer:
    """Renders views of one textured ground with one camera; keeps its (large) scratch
    buffers between frames, which matters for speed where page faults are expensive."""

    def __init__(self, cam: PinholeCamera, texture: GroundTexture, *,
                 supersample: int = SUPERSAMPLE, sky: float = SKY_VALUE) -> None:
        self.cam = cam
        self.texture = texture
        self.s = int(supersample)
        self.sky = float(sky)
        W, H, s = cam.width, cam.height, self.s
        self._x, self._y = grid(W, H)
        shape = (H * s, W * s)
        self._lam_s = np.empty(shape, np.float32)
        self._w = np.empty(shape, np.float32)
        self._layer = np.empty(shape, np.float32)
        self._out = np.empty(shape, np.float32)

    def render(self, g_from_cam: np.ndarray) -> np.ndarray:
        """Noise-free float32 image (height x width) of the ground seen from ``g_from_cam``."""
        out = self.render_fine(g_from_cam)
        if self.s > 1:
            return cv2.resize(out, (self.cam.width, self.cam.height), interpolation=cv2.INTER_AREA)
        return out.copy()

    def render_fine(self, g_from_cam: np.ndarray) -> np.ndarray:
        """The supersampled image (height * s x width * s, float32) that :meth:`render`
        area-averages: the renderer's own buffer, overwritten by the next call."""
        cam, tex, s = self.cam, self.texture, self.s
        W, H = cam.width, cam.height
        sw, sh = W * s, H * s
        if g_from_cam[2, 3] <= 0:
            raise ValueError("camera must be above the ground plane")
        img_from_plane = plane_homography(cam, g_from_cam)
        S = supersample_matrix(s)
        top = len(tex.levels) - 1

        # Mip level per pixel: log2 of the size in texels of one supersampled pixel
        # (computed on the original grid, interpolated to the supersampled one).
        img_from_texel = img_from_plane @ tex.plane_from_texel(0)
        with np.errstate(divide="ignore"):
            lam = np.log2(pixel_size_on_plane(img_from_texel, self._x, self._y))
        lam -= math.log2(s)
        lam = np.where(np.isfinite(lam), lam, top)
        lam = np.clip(lam, 0.0, top).astype(np.float32)
        lam_s = self._lam_s
        if s > 1:
            cv2.resize(lam, (sw, sh), dst=lam_s, interpolation=cv2.INTER_LINEAR)
        else:
            lam_s[...] = lam

        out = self._out
        out.fill(0.0)
        lo, hi = int(math.floor(float(lam.min()))), int(math.ceil(float(lam.max())))
        for level in range(max(lo, 0), min(hi, top) + 1):
            # Trilinear weight of this level: the hat function max(0, 1 - |lam - level|).
            # Only the band of rows that uses the level is rendered (found on the original
            # grid, grown by one pixel for the interpolation of lam_s).
            rows = np.nonzero((np.abs(lam - np.float32(level)) < 1.0).any(axis=1))[0]
            if len(rows) == 0:
                continue
            r0, r1 = max(int(rows[0]) - 1, 0) * s, min(int(rows[-1]) + 2, H) * s
            n = r1 - r0
            w = self._w[:n]
            np.subtract(lam_s[r0:r1], np.float32(level), out=w)
            np.abs(w, out=w)
            np.subtract(np.float32(1.0), w, out=w)
            np.maximum(w, np.float32(0.0), out=w)
            tex_from_dst = np.linalg.inv(S @ img_from_plane @ tex.plane_from_texel(level))
            tex_from_dst = tex_from_dst @ np.array([[1.0, 0.0, 0.0], [0.0, 1.0, r0],
                                                    [0.0, 0.0, 1.0]])
            layer = cv2.warpPerspective(tex.levels[level], tex_from_dst, (sw, n),
                                        dst=self._layer[:n],
                                        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                        borderMode=cv2.BORDER_WRAP)
            np.multiply(layer, w, out=layer)
            np.add(out[r0:r1], layer, out=out[r0:r1])

        # Sky: supersamples whose ray misses the plane (the horizon is a line, corners tell).
        if np.any(corner_depressions(cam, g_from_cam) <= 0.0):
            nrm, _ = ground_in_camera(g_from_cam)
            xs = (np.arange(sw, dtype=np.float64) + 0.5) / s - 0.5
            ys = (np.arange(sh, dtype=np.float64) + 0.5) / s - 0.5
            gx = nrm[0] / cam.fx * (xs - cam.cx)
            gy = nrm[1] / cam.fy * (ys - cam.cy) + nrm[2]
            out[(gy[:, None] + gx[None, :]) <= 0.0] = self.sky
        return out


class FineRenderer(Protocol):
    """What :class:`PsfRenderer` wraps: GroundRenderer, raycast.TerrainRenderer."""

    s: int

    def render_fine(self, g_from_cam: np.ndarray) -> np.ndarray: ...


MAX_PSF = 10.0  # px; wider is no longer a focused camera (and the margins grow with it)


def psf_margin(sigma: float) -> int:
    """Pixels rendered beyond each edge of the image for a PSF of ``sigma`` px: the reach
    of OpenCV's Gaussian kernel (4 sigma), so that the image's border pixels are blurred
    with the ground outside the field of view, as a lens does."""
    return int(math.ceil(4.0 * sigma))


def padded_camera(cam: PinholeCamera, margin: int) -> PinholeCamera:
    """``cam`` with ``margin`` more pixels on every side (the same rays for the same pixels)."""
    return replace(cam, width=cam.width + 2 * margin, height=cam.height + 2 * margin,
                   cx=cam.cx + margin, cy=cam.cy + margin)


class PsfRenderer:
    """A camera whose optics blur before the pixel: a Gaussian PSF of standard deviation
    ``sigma`` px applied to the supersampled image (``sigma * s`` supersamples), which is
    then area-averaged into pixels, as the renderer does without it.

    ``make(camera)`` builds the wrapped renderer (GroundRenderer, TerrainRenderer) for a
    camera padded by :func:`psf_margin` on every side; the padding is cropped after the
    blur. ``render`` = ``pixels(render_fine(g))``; between the two a caller may change the
    supersampled image (``fine_row`` maps an image row to the first of its supersample rows),
    e.g. to shade the ground before the optics see it.
    """

    def __init__(self, cam: PinholeCamera, make: Callable[[PinholeCamera], FineRenderer],
                 sigma: float) -> None:
        if not (math.isfinite(sigma) and 0.0 < sigma <= MAX_PSF):
            raise ValueError(f"PSF sigma {sigma!r} px: must be in (0, {MAX_PSF:g}]")
        self.cam, self.sigma = cam, float(sigma)
        self.margin = psf_margin(self.sigma)
        self.inner = make(padded_camera(cam, self.margin))
        self.s = int(self.inner.s)

    def fine_row(self, row: int) -> int:
        """The first supersample row of image row ``row`` in :meth:`render_fine`'s image."""
        return (row + self.margin) * self.s

    def render_fine(self, g_from_cam: np.ndarray) -> np.ndarray:
        """The padded supersampled image before the optics (the wrapped renderer's buffer)."""
        return self.inner.render_fine(g_from_cam)

    def pixels(self, fine: np.ndarray) -> np.ndarray:
        """The blurred, area-averaged and cropped float32 image (height x width)."""
        s, m, cam = self.s, self.margin, self.cam
        blurred = cv2.GaussianBlur(fine, (0, 0), self.sigma * s, borderType=cv2.BORDER_REPLICATE)
        if s > 1:
            blurred = cv2.resize(blurred, (cam.width + 2 * m, cam.height + 2 * m),
                                 interpolation=cv2.INTER_AREA)
        return np.ascontiguousarray(blurred[m:m + cam.height, m:m + cam.width])

    def render(self, g_from_cam: np.ndarray) -> np.ndarray:
        """Noise-free float32 image (height x width) seen through the blurring optics."""
        return self.pixels(self.render_fine(g_from_cam))


def ground_renderer(cam: PinholeCamera, texture: GroundTexture, *, psf: float = 0.0,
                    supersample: int = SUPERSAMPLE) -> GroundRenderer | PsfRenderer:
    """GroundRenderer of ``cam``, behind a Gaussian PSF of ``psf`` px when ``psf > 0``."""
    if psf > 0:
        return PsfRenderer(cam, lambda c: GroundRenderer(c, texture, supersample=supersample), psf)
    return GroundRenderer(cam, texture, supersample=supersample)


def render_shaded(renderer, g_from_cam: np.ndarray, shadow_row: int | None) -> np.ndarray:
    """The noise-free float image of one frame of ``renderer`` (GroundRenderer,
    TerrainRenderer or PsfRenderer), its rows from ``shadow_row`` on darkened (x0.5): a
    shadow on the ground, fixed to the camera. Behind a PSF the shadow darkens the ground
    before the optics blur it; without one the rendered pixels are darkened."""
    if isinstance(renderer, PsfRenderer):
        fine = renderer.render_fine(g_from_cam)
        if shadow_row is not None:
            fine[renderer.fine_row(shadow_row):] *= np.float32(0.5)
        return renderer.pixels(fine)
    ground = renderer.render(g_from_cam)
    if shadow_row is not None:
        ground[shadow_row:] *= np.float32(0.5)
    return ground


def render_ground(cam: PinholeCamera, g_from_cam: np.ndarray, texture: GroundTexture, *,
                  supersample: int = SUPERSAMPLE, sky: float = SKY_VALUE) -> np.ndarray:
    """Noise-free float32 image (height x width) of the textured ground seen by ``cam``."""
    return GroundRenderer(cam, texture, supersample=supersample, sky=sky).render(g_from_cam)


def finish_frame(image: np.ndarray, rng: np.random.Generator, noise_var: float,
                 gain: float = 1.0, bias: float = 0.0) -> np.ndarray:
    """Exposure (gain, bias), Gaussian noise of variance ``noise_var``, round, clip to uint8."""
    img = image.astype(np.float64) * gain + bias
    if noise_var > 0:
        img = img + rng.normal(0.0, math.sqrt(noise_var), img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)
