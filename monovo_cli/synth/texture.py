"""Ground textures: the procedural one (periodic, no external data) and one read from a file.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.io.grey import read_gray

TEXTURE_MEAN = 120.0
TEXTURE_STD = 45.0


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
        """``(rows, columns)`` of texels at level 0."""
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
    """A user's image as a periodic grey float32 texture: decoded as frames are
    (:func:`~monovo_cli.io.grey.read_gray`: grey levels 0..255 whatever the depth or colour),
    resized to multiples of 32 px per side and mirrored (image | flipped) both ways, so it
    tiles seamlessly."""
    path = Path(path)
    try:
        img = read_gray(path)
    except InputError as exc:
        detail = str(exc).removeprefix(f"{path}: ")
        raise InputError(f"{path}: cannot read texture ({detail})") from None
    h, w = img.shape
    if min(h, w) < 16:
        raise InputError(f"{path}: texture is {w}x{h} px, need at least 16x16")
    h2, w2 = max(32, int(round(h / 32.0)) * 32), max(32, int(round(w / 32.0)) * 32)
    if (h2, w2) != (h, w):
        img = cv2.resize(img, (w2, h2), interpolation=cv2.INTER_AREA if w2 < w else cv2.INTER_LINEAR)
    top = np.concatenate([img, img[:, ::-1]], axis=1)
    return np.ascontiguousarray(np.concatenate([top, top[::-1]], axis=0))
