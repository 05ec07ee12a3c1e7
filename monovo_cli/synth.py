"""Synthetic ground sequences with exact ground truth (``monovo synth``).

A pinhole camera looks at a textured plane (the ground, ``z_G = 0`` of a ground frame G
with z up). Every frame is rendered through the exact plane-induced homography from
ground coordinates to pixels:

* the texture is a periodic (seamlessly tiling) grey image with ``metres_per_texel``
  metres per texel, sampled bilinearly with wrap-around, through a mip-map pyramid
  (trilinear, level chosen per pixel from the local footprint of the homography), so
  distant, foreshortened ground does not alias;
* each image is rendered at ``SUPERSAMPLE`` times its resolution and area-averaged down,
  which integrates every pixel over its area. Supersampled pixel ``(i, j)`` has its
  centre at original pixel coordinate ``((i + 0.5)/s - 0.5, (j + 0.5)/s - 0.5)``, so the
  top-left original pixel centre stays at (0, 0) (SPEC);
* pixels whose ray misses the plane (above the horizon) get a plain sky value;
* optional exposure change (gain, bias), then Gaussian noise, rounding, 8-bit PNG.

Poses: ``g_from_cam_k`` maps camera-k points to G. The SPEC's world frame is camera 0,
so the ground truth is ``T_0_k = inv(g_from_cam_0) @ g_from_cam_k`` and the relative
motion ``T_{k-1}_k = inv(g_from_cam_{k-1}) @ g_from_cam_k``. The plane in camera 0 is
``{X : n . X = d}`` with ``n = -R_0^T e_z`` (pointing from the camera to the ground) and
``d`` the camera height.

Presets:

* ``drive`` -- a rover camera on a 1.5 m mast pitched 45 deg down, driving ~5 cm/frame
  with smooth turns and small roll/pitch/height wobble; one sequence.
* ``pairs`` -- the paper's experiment: camera 100 m from the plane, optical axis 25 deg
  (+- 5 deg) off the plane normal, one random motion per pair (rotation +-5 deg and
  translation +-10 m per axis); one 2-frame sequence per pair in ``pair_NNNN/``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from monovo_cli import __version__
from monovo_cli.errors import InputError, OutputError
from monovo_cli.geometry import PinholeCamera, make_pose, pose_from_vectors, se3_inv, so3_exp
from monovo_cli.outputs import MotionRow, atomic_write_text, fmt, motion_csv_text, tum_text

PRESETS = ("drive", "pairs")
MIN_SIZE = 32
MAX_SIZE = 8192
SUPERSAMPLE = 4
SKY_VALUE = 190.0
FOCAL_PER_WIDTH = 0.87
# Rows whose rays dip less than this below the horizon are left out of the ground region.
REGION_MIN_DEPRESSION_DEG = 10.0

DRIVE_MAST_HEIGHT = 1.5  # m
DRIVE_PITCH_DEG = 45.0  # optical axis below the horizontal
DRIVE_STEP = 0.05  # m/frame, nominal forward speed (varies +-30 %)
DRIVE_SPEED_VARIATION = 0.3
DRIVE_MAX_YAW_RATE_DEG = 1.0  # per frame
DRIVE_WOBBLE_DEG = 1.0  # roll and pitch of the rover body
DRIVE_HEIGHT_WOBBLE = 0.02  # m

PAIR_DISTANCE = 100.0  # m, camera 0 to the plane
PAIR_TILT_DEG = 25.0  # optical axis off the plane normal
PAIR_EXTRA_TILT_DEG = 5.0  # random extra tilt per axis (about camera x and y)
PAIR_MAX_TRANSLATION = 10.0  # m per axis
PAIR_MAX_DRAWS = 1000

EXPOSURE_GAIN = 0.2  # gain in 1 +- this
EXPOSURE_BIAS = 15.0  # grey levels

TEXTURE_MEAN = 120.0
TEXTURE_STD = 45.0


@dataclass(frozen=True)
class SynthSummary:
    out_dir: Path
    sequences: int  # 1 for drive, N for pairs
    frames_per_sequence: int
    distance_m: float  # camera path length (drive) or sum of pair translations (pairs)


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


def _grid(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    return np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))


def footprint(img_from_plane: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
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
    x, y = _grid(cam.width, cam.height)
    ok = ray_depression(cam, g_from_cam, x, y) >= math.radians(min_depression_deg)
    rows_ok = ok.all(axis=1)
    if not rows_ok[-1]:
        return None
    bad = np.nonzero(~rows_ok)[0]
    y0 = int(bad[-1]) + 1 if len(bad) else 0
    return [0, y0, cam.width, cam.height]


def _corner_depressions(cam: PinholeCamera, g_from_cam: np.ndarray) -> np.ndarray:
    x = np.array([-0.5, cam.width - 0.5, -0.5, cam.width - 0.5])
    y = np.array([-0.5, -0.5, cam.height - 0.5, cam.height - 0.5])
    return ray_depression(cam, g_from_cam, x, y)


# --------------------------------------------------------------------------- texture


class GroundTexture:
    """A periodic grey texture on the ground plane, with its mip-map pyramid.

    Texel ``(i, j)`` (column i, row j) of level 0 has its centre at ground point
    ``(u, v) = (i, j) * metres_per_texel``; level ``l`` texel ``(i, j)`` sits at level-0
    coordinate ``(i, j) * 2**l`` (cv2.pyrDown alignment). The texture repeats with period
    ``shape * metres_per_texel`` in both directions.
    """

    def __init__(self, image: np.ndarray, metres_per_texel: float) -> None:
        base = np.ascontiguousarray(image, dtype=np.float32)
        if base.ndim != 2 or min(base.shape) < 2:
            raise ValueError("texture must be a 2-D array")
        self.metres_per_texel = float(metres_per_texel)
        levels = [base]
        while min(levels[-1].shape) >= 16 and all(s % 2 == 0 for s in levels[-1].shape):
            levels.append(_pyr_down_wrap(levels[-1]))
        self.levels: tuple[np.ndarray, ...] = tuple(levels)

    @property
    def shape(self) -> tuple[int, int]:
        return self.levels[0].shape  # type: ignore[return-value]

    def plane_from_texel(self, level: int = 0) -> np.ndarray:
        """3x3 map from level-``level`` texel coordinates to ground metres ``(u, v, 1)``."""
        k = self.metres_per_texel * 2.0 ** level
        return np.diag([k, k, 1.0])


def _pyr_down_wrap(img: np.ndarray) -> np.ndarray:
    """cv2.pyrDown of a periodic image (output texel j at input texel 2j), periodic too."""
    p = 4
    padded = np.pad(img, p, mode="wrap")
    small = cv2.pyrDown(padded)
    h, w = img.shape
    return np.ascontiguousarray(small[p // 2: p // 2 + h // 2, p // 2: p // 2 + w // 2])


def _periodic_gaussian_field(n: int, rng: np.random.Generator,
                             octaves: list[tuple[float, float]]) -> np.ndarray:
    """Sum of independent Gaussian-blurred white-noise fields (sigma in texels, std each),
    periodic with period n; synthesised in the Fourier domain."""
    noise = rng.standard_normal((n, n), dtype=np.float32)
    spec = np.fft.rfft2(noise)
    fy = np.fft.fftfreq(n).astype(np.float32)[:, None]
    fx = np.fft.rfftfreq(n).astype(np.float32)[None, :]
    f2 = fx * fx + fy * fy
    power = np.zeros_like(f2)
    for sigma, std in octaves:
        # A unit white field blurred by a Gaussian of std sigma has variance 1/(4 pi sigma^2).
        power += (std * std * 4.0 * np.pi * sigma * sigma) * np.exp(
            -4.0 * np.pi * np.pi * sigma * sigma * f2)
    spec *= np.sqrt(power)
    return np.fft.irfft2(spec, s=(n, n)).astype(np.float32)


_SUBPIXEL_BITS = 4  # cv2 drawing with fractional coordinates


def _ellipse_wrapped(layer: np.ndarray, cx: float, cy: float, ax: float, ay: float,
                     angle: float, value: int) -> None:
    """Filled anti-aliased ellipse on a periodic layer (drawn again across the seams)."""
    one = 1 << _SUBPIXEL_BITS
    n_y, n_x = layer.shape
    reach = max(ax, ay) + 2.0
    axes = (max(int(ax * one), 1), max(int(ay * one), 1))
    for dx in (-n_x, 0, n_x):
        if not -reach <= cx + dx < n_x + reach:
            continue
        for dy in (-n_y, 0, n_y):
            if -reach <= cy + dy < n_y + reach:
                centre = (int(round((cx + dx) * one)), int(round((cy + dy) * one)))
                cv2.ellipse(layer, centre, axes, angle, 0, 360, value, -1, cv2.LINE_AA,
                            _SUBPIXEL_BITS)


def procedural_texture(n: int, seed: int) -> np.ndarray:
    """A Mars-like periodic ground texture (n x n float32, mean ~120, std ~45 grey levels):
    multi-octave smoothed noise (soil) plus scattered shaded pebbles. Deterministic in seed."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x7E47]))
    octaves = [(1.0, 0.55), (2.0, 0.7), (4.0, 0.8), (8.0, 0.8), (16.0, 0.7), (32.0, 0.6),
               (64.0, 0.5), (128.0, 0.45), (256.0, 0.4)]
    octaves = [(s, a) for s, a in octaves if s <= n / 4]
    soil = _periodic_gaussian_field(n, rng, octaves)
    soil = (soil - soil.mean()) / max(float(soil.std()), 1e-6)

    # Pebbles: anti-aliased ellipses (alpha layer) with a per-pebble grey value, a shadow
    # towards +x+y and a highlight towards -x-y (sun from the upper left).
    alpha = np.zeros((n, n), np.uint8)
    value = np.zeros((n, n), np.uint8)
    shadow = np.zeros((n, n), np.uint8)
    light = np.zeros((n, n), np.uint8)
    count = int(0.0012 * n * n)
    radii = np.minimum(1.2 * (1.0 - rng.random(count)) ** (-1.0 / 1.6), 16.0)
    xs = rng.random(count) * n
    ys = rng.random(count) * n
    aspect = rng.uniform(0.55, 1.0, count)
    angle = rng.uniform(0.0, 180.0, count)
    grey = np.clip(rng.normal(150.0, 45.0, count), 20, 250)
    for x, y, r, asp, ang, g in zip(xs, ys, radii, aspect, angle, grey):
        ax, ay = r, r * asp
        _ellipse_wrapped(shadow, x + 0.35 * r, y + 0.35 * r, ax + 0.3, ay + 0.3, ang, 255)
        _ellipse_wrapped(alpha, x, y, ax, ay, ang, 255)
        # The value layer is drawn a little larger so the alpha edge blends to this grey.
        _ellipse_wrapped(value, x, y, ax + 1.0, ay + 1.0, ang, int(g))
        if r > 2.0:
            _ellipse_wrapped(light, x - 0.3 * r, y - 0.3 * r, ax / 3, ay / 3, ang, 255)
    inv255 = np.float32(1.0 / 255.0)
    tex = soil
    tex *= np.float32(TEXTURE_STD * 0.8)
    tex += np.float32(TEXTURE_MEAN)
    del soil
    tex *= 1.0 - np.float32(0.45 * inv255) * shadow
    del shadow
    a = alpha.astype(np.float32)
    a *= inv255
    del alpha
    tex -= value
    tex *= 1.0 - a
    tex += value  # = tex * (1 - a) + value * a
    del value
    a *= light
    a *= np.float32(35.0 * inv255)
    tex += a  # highlight, only on pebbles
    del a, light
    tex = cv2.GaussianBlur(np.pad(tex, 4, mode="wrap"), (0, 0), 0.6)[4:-4, 4:-4]
    tex = (tex - tex.mean()) * (TEXTURE_STD / max(float(tex.std()), 1e-6)) + TEXTURE_MEAN
    return np.clip(tex, 0.0, 255.0).astype(np.float32)


def procedural_texture_size(width: int, height: int) -> int:
    """Side of the procedural texture: a power of two, ~8 image widths, 1024..4096."""
    want = 8 * max(width, height)
    n = 1024
    while n < want and n < 4096:
        n *= 2
    return n


def load_texture(path: Path) -> np.ndarray:
    """A user's image as a periodic grey float32 texture: resized to multiples of 32 px per
    side and mirrored (image | flipped) both ways, so it tiles seamlessly."""
    path = Path(path)
    try:
        data = np.fromfile(str(path), dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"{path}: cannot read texture ({exc.strerror or exc})") from None
    img = cv2.imdecode(data, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR) if data.size else None
    if img is None:
        raise InputError(f"{path}: cannot read texture (not an image format OpenCV can decode)")
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    if img.dtype == np.uint16:
        img = img.astype(np.float32) / 257.0
    elif img.dtype != np.uint8:
        img = img.astype(np.float32)
        lo, hi = float(img.min()), float(img.max())
        img = (img - lo) * (255.0 / (hi - lo)) if hi > lo else np.zeros_like(img)
    img = img.astype(np.float32)
    h, w = img.shape
    if min(h, w) < 16:
        raise InputError(f"{path}: texture is {w}x{h} px, need at least 16x16")
    h2, w2 = max(32, int(round(h / 32.0)) * 32), max(32, int(round(w / 32.0)) * 32)
    if (h2, w2) != (h, w):
        img = cv2.resize(img, (w2, h2), interpolation=cv2.INTER_AREA if w2 < w else cv2.INTER_LINEAR)
    top = np.concatenate([img, img[:, ::-1]], axis=1)
    return np.ascontiguousarray(np.concatenate([top, top[::-1]], axis=0))


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
        self._x, self._y = _grid(W, H)
        shape = (H * s, W * s)
        self._lam_s = np.empty(shape, np.float32)
        self._w = np.empty(shape, np.float32)
        self._layer = np.empty(shape, np.float32)
        self._out = np.empty(shape, np.float32)

    def render(self, g_from_cam: np.ndarray) -> np.ndarray:
        """Noise-free float32 image (height x width) of the ground seen from ``g_from_cam``."""
        cam, tex, s = self.cam, self.texture, self.s
        W, H = cam.width, cam.height
        sw, sh = W * s, H * s
        if g_from_cam[2, 3] <= 0:
            raise ValueError("camera must be above the ground plane")
        img_from_plane = plane_homography(cam, g_from_cam)
        S = supersample_matrix(s)
        top = len(tex.levels) - 1

        # Mip level per pixel: log2 of the texel footprint of one supersampled pixel
        # (computed on the original grid, interpolated to the supersampled one).
        with np.errstate(divide="ignore"):
            lam = np.log2(footprint(img_from_plane @ tex.plane_from_texel(0), self._x, self._y))
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
        if np.any(_corner_depressions(cam, g_from_cam) <= 0.0):
            nrm, _ = ground_in_camera(g_from_cam)
            xs = (np.arange(sw, dtype=np.float64) + 0.5) / s - 0.5
            ys = (np.arange(sh, dtype=np.float64) + 0.5) / s - 0.5
            gx = nrm[0] / cam.fx * (xs - cam.cx)
            gy = nrm[1] / cam.fy * (ys - cam.cy) + nrm[2]
            out[(gy[:, None] + gx[None, :]) <= 0.0] = self.sky
        if s > 1:
            return cv2.resize(out, (W, H), interpolation=cv2.INTER_AREA)
        return out.copy()


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


# --------------------------------------------------------------------------- motion


def _smooth(rng: np.random.Generator, n: int, periods: tuple[float, float], *, count: int = 3,
            zero_start: bool = False) -> np.ndarray:
    """A smooth random signal in [-1, 1] over frames 0..n-1 (sum of sinusoids)."""
    k = np.arange(n, dtype=float)
    omega = 2.0 * np.pi / rng.uniform(periods[0], periods[1], count)
    amp = rng.uniform(0.5, 1.0, count)
    amp /= amp.sum()
    if zero_start:  # exactly 0 at frame 0, random sign per component
        amp *= rng.choice([-1.0, 1.0], count)
        phase = np.zeros(count)
    else:
        phase = rng.uniform(0.0, 2.0 * np.pi, count)
    return (amp[None, :] * np.sin(omega[None, :] * k[:, None] + phase[None, :])).sum(axis=1)


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def body_from_camera(pitch_rad: float) -> np.ndarray:
    """Rotation of a camera pitched down by ``pitch_rad`` in a body frame (x forward, y left,
    z up). Columns are the camera axes: x right, y down, z along the optical axis."""
    c, s = math.cos(pitch_rad), math.sin(pitch_rad)
    x_cam = np.array([0.0, -1.0, 0.0])
    z_cam = np.array([c, 0.0, -s])
    y_cam = np.cross(z_cam, x_cam)
    return np.column_stack([x_cam, y_cam, z_cam])


def drive_poses(n_frames: int, rng: np.random.Generator, *, peak_step: float,
                origin: tuple[float, float] = (0.0, 0.0)) -> list[np.ndarray]:
    """``g_from_cam_k`` of a rover drive: mast camera (1.5 m, pitched 45 deg down) moving
    forward ``peak_step / 1.3 * (1 +- 0.3)`` m per frame with a smooth yaw rate of up to
    1 deg/frame about the ground normal, +-1 deg roll/pitch and +-2 cm height wobble.
    Frame 0 is exactly on the nominal mast pose."""
    speed = (peak_step / (1.0 + DRIVE_SPEED_VARIATION)) * (
        1.0 + DRIVE_SPEED_VARIATION * _smooth(rng, n_frames, (40.0, 250.0)))
    bias = rng.uniform(-1.0, 1.0)
    yaw_rate = math.radians(DRIVE_MAX_YAW_RATE_DEG) * (
        0.4 * bias + 0.6 * _smooth(rng, n_frames, (60.0, 400.0)))
    roll = math.radians(DRIVE_WOBBLE_DEG) * _smooth(rng, n_frames, (15.0, 60.0), zero_start=True)
    pitch = math.radians(DRIVE_WOBBLE_DEG) * _smooth(rng, n_frames, (15.0, 60.0),
                                                     zero_start=True)
    height = DRIVE_MAST_HEIGHT + DRIVE_HEIGHT_WOBBLE * _smooth(rng, n_frames, (20.0, 80.0),
                                                               zero_start=True)
    heading = rng.uniform(0.0, 2.0 * np.pi)
    R_body_cam = body_from_camera(math.radians(DRIVE_PITCH_DEG))
    pos = np.array(origin, dtype=float)
    poses = []
    for k in range(n_frames):
        if k > 0:
            mid = heading + 0.5 * yaw_rate[k]
            pos = pos + speed[k] * np.array([math.cos(mid), math.sin(mid)])
            heading += yaw_rate[k]
        R = _rot_z(heading) @ _rot_y(pitch[k]) @ _rot_x(roll[k]) @ R_body_cam
        poses.append(make_pose(R, np.array([pos[0], pos[1], height[k]])))
    return poses


def pair_poses(cam: PinholeCamera, rng: np.random.Generator, *, max_translation: float,
               max_rotation_deg: float, origin: tuple[float, float] = (0.0, 0.0),
               min_depression_deg: float = REGION_MIN_DEPRESSION_DEG,
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(g_from_cam_0, g_from_cam_1)`` of one pair: camera 0 100 m from the plane with its
    optical axis 25 deg (+- 5 deg about camera x and y) off the normal, random azimuth;
    ``T_0_1`` with rotation vector and translation uniform per axis in
    ``+-max_rotation_deg`` / ``+-max_translation``, redrawn until frame 1 sees only ground."""
    extra = np.radians(rng.uniform(-PAIR_EXTRA_TILT_DEG, PAIR_EXTRA_TILT_DEG, 2))
    R_extra = so3_exp(np.array([extra[0], extra[1], 0.0]))
    azimuth = rng.uniform(0.0, 2.0 * np.pi)
    R0 = _rot_z(azimuth) @ body_from_camera(math.radians(90.0 - PAIR_TILT_DEG)) @ R_extra.T
    g0 = make_pose(R0, np.array([origin[0], origin[1], PAIR_DISTANCE]))
    margin = math.radians(min_depression_deg)
    for _ in range(PAIR_MAX_DRAWS):
        t = rng.uniform(-max_translation, max_translation, 3)
        r = np.radians(rng.uniform(-max_rotation_deg, max_rotation_deg, 3))
        g1 = g0 @ pose_from_vectors(t, r)
        if g1[2, 3] > 0.05 * PAIR_DISTANCE and np.all(_corner_depressions(cam, g1) >= margin):
            return g0, g1
    raise InputError(f"max_rotation_deg {max_rotation_deg:g}, max_translation {max_translation:g}: "
                     "motions this large keep showing the horizon in frame 1")


# --------------------------------------------------------------------------- outputs


def _init_yaml(cam: PinholeCamera, g_from_cam0: np.ndarray, region: list[int]) -> str:
    n, d = ground_in_camera(g_from_cam0)
    data = {
        "camera": {"width": int(cam.width), "height": int(cam.height), "fx": float(cam.fx),
                   "fy": float(cam.fy), "cx": float(cam.cx), "cy": float(cam.cy)},
        "ground": {"normal": [float(v) + 0.0 for v in n], "distance": float(d),
                   "region": [int(v) for v in region]},
    }
    return yaml.safe_dump(data, default_flow_style=None, sort_keys=False)


def _write_sequence(seq_dir: Path, cam: PinholeCamera, poses: list[np.ndarray],
                    region: list[int], params: dict,
                    photometric: list[tuple[float, float]] | None) -> None:
    """init.yaml, ground truth, synth.yaml (+ photometric.csv) of one sequence; frames are
    written by the caller as they are rendered."""
    inv0 = se3_inv(poses[0])
    traj = [np.eye(4)] + [inv0 @ g for g in poses[1:]]
    rows = [MotionRow(frame=k, prev_from_cur=se3_inv(poses[k - 1]) @ poses[k], msd=0.0,
                      iterations=0, points=0, status="ok") for k in range(1, len(poses))]
    atomic_write_text(seq_dir / "init.yaml", _init_yaml(cam, poses[0], region))
    atomic_write_text(seq_dir / "groundtruth.tum", tum_text([float(k) for k in range(len(poses))],
                                                            traj))
    atomic_write_text(seq_dir / "groundtruth_motion.csv", motion_csv_text(rows))
    atomic_write_text(seq_dir / "synth.yaml",
                      yaml.safe_dump(params, default_flow_style=None, sort_keys=False))
    if photometric is not None:
        lines = ["frame,gain,bias"] + [f"{k},{fmt(g)},{fmt(b)}"
                                       for k, (g, b) in enumerate(photometric)]
        atomic_write_text(seq_dir / "photometric.csv", "\n".join(lines) + "\n")


def _write_png(path: Path, img: np.ndarray) -> None:
    try:
        ok = cv2.imwrite(str(path), img)
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"{path}: cannot write PNG")


def _make_dir(path: Path) -> None:
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create directory ({exc.strerror or exc})") from None


# --------------------------------------------------------------------------- entry point


def _check_number(name: str, value, *, low: float, high: float = math.inf,
                  integer: bool = False) -> None:
    kind = "a whole number" if integer else "a number"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} {value!r}: must be {kind}")
    if integer and int(value) != value:
        raise InputError(f"{name} {value!r}: must be {kind}")
    if not math.isfinite(float(value)) or not (low <= float(value) <= high):
        rng = f">= {low:g}" if high == math.inf else f"between {low:g} and {high:g}"
        raise InputError(f"{name} {value!r}: must be {kind} {rng}")


def synthesize(out_dir: Path, *, preset: str = "drive", frames: int | None = None,
               size: tuple[int, int] | None = None, noise_var: float = 10.0, seed: int = 0,
               texture: Path | None = None, max_translation: float | None = None,
               max_rotation_deg: float = 5.0, exposure: bool = False, shadow: float = 0.0,
               low_texture: bool = False, clean_frame0: bool = False,
               progress: Callable[[int, int], None] | None = None) -> SynthSummary:
    """Write a synthetic sequence (``drive``) or set of 2-frame sequences (``pairs``).

    ``frames``: frames of the drive (default 300) or number of pairs (default 100).
    ``size``: ``(width, height)`` px (default 512x512 drive, 688x544 pairs).
    ``max_translation``: pairs -- per-axis translation bound, m (default 10);
    drive -- peak forward step per frame, m (default 0.065 = 0.05 * 1.3).
    ``max_rotation_deg``: pairs -- per-axis bound of the rotation vector, degrees; the
    drive's turns are fixed (yaw rate up to 1 deg/frame) and ignore it.
    ``exposure``: vary gain (0.8..1.2) and bias (+-15 grey levels) per frame (smoothly along
    a drive, independently per pair frame); written to ``photometric.csv``.
    ``shadow``: darken (x0.5) this fraction of the image's bottom rows in every frame, a
    shadow fixed to the camera like the rover's own. ``low_texture``: a smooth ground with
    a quarter of the contrast and no fine detail. ``clean_frame0``: frame 0 (of the drive,
    of every pair) without noise, only rounded -- the paper's synthetic experiment, where the
    ground's texture is exactly known; the other frames' noise is the same as without it.
    ``progress(done, total)`` is called after each drive frame / each pair.
    Raises InputError for bad arguments, OutputError if ``out_dir`` exists and is not empty
    or cannot be written.
    """
    out_dir = Path(out_dir)
    if preset not in PRESETS:
        raise InputError(f"--preset {preset!r}: unknown preset, choose one of {', '.join(PRESETS)}")
    drive = preset == "drive"
    if frames is None:
        frames = 300 if drive else 100
    _check_number("--frames", frames, low=2 if drive else 1, integer=True)
    frames = int(frames)
    if size is None:
        size = (512, 512) if drive else (688, 544)
    if (not isinstance(size, (tuple, list)) or len(size) != 2
            or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in size)):
        raise InputError(f"--size {size!r}: must be two whole numbers WIDTHxHEIGHT")
    width, height = int(size[0]), int(size[1])
    if min(width, height) < MIN_SIZE or max(width, height) > MAX_SIZE:
        raise InputError(f"--size {width}x{height}: width and height must be between "
                         f"{MIN_SIZE} and {MAX_SIZE} px")
    _check_number("--noise-var", noise_var, low=0.0)
    _check_number("--seed", seed, low=0, high=2**63 - 1, integer=True)
    seed = int(seed)
    if max_translation is None:
        max_translation = DRIVE_STEP * (1.0 + DRIVE_SPEED_VARIATION) if drive else PAIR_MAX_TRANSLATION
    _check_number("max_translation", max_translation, low=0.0,
                  high=1.0 if drive else 0.5 * PAIR_DISTANCE)
    _check_number("max_rotation_deg", max_rotation_deg, low=0.0, high=30.0)
    _check_number("--shadow", shadow, low=0.0, high=1.0)
    if out_dir.exists():
        if not out_dir.is_dir():
            raise OutputError(f"{out_dir}: exists and is not a directory")
        if any(out_dir.iterdir()):
            raise OutputError(f"{out_dir}: already exists and is not empty")

    cam = default_camera(width, height)
    ss = np.random.SeedSequence(seed)
    motion_rng, noise_rng, photo_rng = (np.random.default_rng(s) for s in ss.spawn(3))

    # Texture scale: a texel is ~0.85 px at the nearest visible ground of the nominal view.
    if drive:
        nominal = make_pose(body_from_camera(math.radians(DRIVE_PITCH_DEG)),
                            np.array([0.0, 0.0, DRIVE_MAST_HEIGHT]))
    else:
        nominal = make_pose(body_from_camera(math.radians(90.0 - PAIR_TILT_DEG)),
                            np.array([0.0, 0.0, PAIR_DISTANCE]))
    x, y = _grid(width, height)
    metres_per_texel = 0.85 * float(np.min(footprint(plane_homography(cam, nominal), x, y)))
    if texture is not None:
        tex_image = load_texture(Path(texture))
        texture_desc = str(Path(texture).resolve())
    else:
        tex_image = procedural_texture(procedural_texture_size(width, height), seed)
        texture_desc = None
    if low_texture:
        n_pad = 16
        smooth = cv2.GaussianBlur(np.pad(tex_image, n_pad, mode="wrap"), (0, 0), 4.0)
        smooth = smooth[n_pad:-n_pad, n_pad:-n_pad]
        tex_image = ((smooth - smooth.mean()) * (0.25 * TEXTURE_STD / max(float(smooth.std()), 1e-6))
                     + TEXTURE_MEAN).astype(np.float32)
    tex = GroundTexture(tex_image, metres_per_texel)
    period = np.array(tex.shape[::-1], dtype=float) * metres_per_texel  # (u, v) metres

    params = {
        "generator": f"monovo {__version__} synth",
        "preset": preset, "seed": seed, "frames": frames, "size": [width, height],
        "noise_var": float(noise_var), "max_translation": float(max_translation),
        "max_rotation_deg": float(max_rotation_deg), "exposure": bool(exposure),
        "texture": texture_desc, "shadow": float(shadow), "low_texture": bool(low_texture),
        "clean_frame0": bool(clean_frame0),
        "texture_texels": [int(tex.shape[1]), int(tex.shape[0])],
        "metres_per_texel": metres_per_texel, "supersample": SUPERSAMPLE,
    }
    # All geometry first (it can still reject the arguments), then write.
    sequences: list[tuple[Path, list[np.ndarray], list[tuple[float, float]] | None, dict]] = []
    if drive:
        origin = tuple(motion_rng.uniform(0.0, 1.0, 2) * period)
        poses = drive_poses(frames, motion_rng, peak_step=float(max_translation), origin=origin)
        photometric = None
        if exposure:
            gains = 1.0 + EXPOSURE_GAIN * _smooth(photo_rng, frames, (30.0, 200.0))
            biases = EXPOSURE_BIAS * _smooth(photo_rng, frames, (30.0, 200.0))
            photometric = [(float(g), float(b)) for g, b in zip(gains, biases)]
        params.update(mast_height=DRIVE_MAST_HEIGHT, pitch_deg=DRIVE_PITCH_DEG)
        sequences.append((out_dir, poses, photometric, params))
    else:
        params.update(plane_distance=PAIR_DISTANCE, tilt_deg=PAIR_TILT_DEG,
                      extra_tilt_deg=PAIR_EXTRA_TILT_DEG)
        for i in range(frames):
            origin = tuple(motion_rng.uniform(0.0, 1.0, 2) * period)
            g0, g1 = pair_poses(cam, motion_rng, max_translation=float(max_translation),
                                max_rotation_deg=float(max_rotation_deg), origin=origin)
            photometric = None
            if exposure:
                photometric = [(float(photo_rng.uniform(1 - EXPOSURE_GAIN, 1 + EXPOSURE_GAIN)),
                                float(photo_rng.uniform(-EXPOSURE_BIAS, EXPOSURE_BIAS)))
                               for _ in range(2)]
            sequences.append((out_dir / f"pair_{i:04d}", [g0, g1], photometric,
                              dict(params, pair=i)))
    regions = []
    for _, poses, _, _ in sequences:
        region = ground_region(cam, poses[0])
        if region is None:
            raise InputError(f"--size {width}x{height}: the camera sees no ground at frame 0")
        regions.append(region)

    _make_dir(out_dir)
    if not drive:
        atomic_write_text(out_dir / "synth.yaml",
                          yaml.safe_dump(params, default_flow_style=None, sort_keys=False))
    renderer = GroundRenderer(cam, tex)
    distance = 0.0
    for i, ((seq_dir, poses, photometric, seq_params), region) in enumerate(
            zip(sequences, regions)):
        frames_dir = seq_dir / "frames"
        _make_dir(frames_dir)
        for k, g in enumerate(poses):
            gain, bias = photometric[k] if photometric else (1.0, 0.0)
            ground = renderer.render(g)
            if shadow > 0:
                ground[int(round(height * (1.0 - shadow))):] *= np.float32(0.5)
            img = finish_frame(ground, noise_rng, float(noise_var), gain, bias)
            if clean_frame0 and k == 0:  # (the noise was still drawn: frame 1's stays the same)
                img = finish_frame(ground, noise_rng, 0.0, gain, bias)
            _write_png(frames_dir / f"frame_{k:06d}.png", img)
            if drive and progress is not None:
                progress(k + 1, frames)
        _write_sequence(seq_dir, cam, poses, region, seq_params, photometric)
        distance += float(sum(np.linalg.norm(poses[k][:3, 3] - poses[k - 1][:3, 3])
                              for k in range(1, len(poses))))
        if not drive and progress is not None:
            progress(i + 1, frames)
    return SynthSummary(out_dir=out_dir, sequences=len(sequences),
                        frames_per_sequence=len(sequences[0][1]), distance_m=distance)


__all__ = [
    "GroundRenderer", "GroundTexture", "SynthSummary", "default_camera", "drive_poses",
    "finish_frame", "footprint", "ground_in_camera", "ground_region", "load_texture", "pair_poses",
    "plane_homography", "procedural_texture", "render_ground", "supersample_matrix",
    "synthesize",
]
