"""A procedural gravel texture: densely packed small pebbles, shaded, with sand and fine grain.

Its statistics differ from :func:`~monovo_cli.synth.texture.procedural_texture` (smooth
multi-octave soil with sparse pebbles): here the ground is mostly pebbles of one size class
(about ``GRAVEL_PEBBLE`` m apart), each a rounded dome lit from the upper left, with sand in
the gaps and a fine grain over everything. The layout is the Voronoi tessellation of jittered
seed points (one per cell of a grid, some cells left out so sizes vary); a pebble is a dome
around its cell's seed, clipped by a random gap to the cell's edge. Periodic (tiles
seamlessly) and deterministic in the seed.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from monovo_cli.synth.texture import TEXTURE_MEAN

GRAVEL_PEBBLE = 0.025  # m, seed spacing (a pebble and its share of sand)
GRAVEL_MIN_CELL = 4  # texels: pebbles are at least this large
GRAVEL_STD = 40.0  # grey levels
_LIGHT = np.array([-1.0, -1.0, 1.2]) / math.sqrt(3.44)  # from the upper left, ~40 deg high


def gravel_texture(n: int, seed: int, *, metres_per_texel: float) -> np.ndarray:
    """Periodic gravel, n x n float32 grey levels (mean ~120, std ~40), pebbles about
    ``GRAVEL_PEBBLE`` m apart at ``metres_per_texel`` (and at least GRAVEL_MIN_CELL texels)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x67A7E1]))
    cells = max(1, int(round(n / max(GRAVEL_PEBBLE / metres_per_texel, GRAVEL_MIN_CELL))))
    pitch = n / cells
    # Jittered seeds, one per grid cell; 20 % left out so that neighbours grow larger.
    gi, gj = np.meshgrid(np.arange(cells), np.arange(cells))
    sx = np.floor((gi + rng.uniform(0.15, 0.85, gi.shape)) * pitch).astype(np.int64).ravel()
    sy = np.floor((gj + rng.uniform(0.15, 0.85, gj.shape)) * pitch).astype(np.int64).ravel()
    keep = rng.random(sx.size) >= 0.2
    sx, sy = sx[keep], sy[keep]
    count = sx.size
    albedo = np.clip(rng.lognormal(0.0, 0.25, count), 0.5, 1.8)
    gap = rng.uniform(0.5, 1.5, count)  # texels of sand around each pebble
    flat = rng.uniform(0.5, 0.9, count)  # height / radius of the dome
    swell = rng.uniform(1.4, 2.0, count)  # dome radius / the cell's inscribed radius

    # Voronoi cells on a periodic canvas: padded so that cells near the seams are whole.
    pad = int(math.ceil(3 * pitch)) + 2
    size = n + 2 * pad
    canvas = np.full((size, size), 255, np.uint8)
    offsets = [(dx, dy) for dx in (-n, 0, n) for dy in (-n, 0, n)]
    px = np.concatenate([sx + pad + dx for dx, _ in offsets])
    py = np.concatenate([sy + pad + dy for _, dy in offsets])
    inside = (px >= 0) & (px < size) & (py >= 0) & (py < size)
    seed_id = np.tile(np.arange(count), len(offsets))[inside]
    px, py = px[inside], py[inside]
    canvas[py, px] = 0
    to_seed, labels = cv2.distanceTransformWithLabels(canvas, cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    lut = np.zeros(int(labels.max()) + 1, np.int32)
    lut[labels[py, px]] = seed_id
    cell = lut[labels]
    del labels, canvas
    edge = np.zeros((size, size), bool)
    edge[:, 1:] |= cell[:, 1:] != cell[:, :-1]
    edge[1:, :] |= cell[1:, :] != cell[:-1, :]
    to_edge = cv2.distanceTransform(np.where(edge, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
    del edge
    radius = np.zeros(count, np.float32)
    radius[seed_id] = to_edge[py, px]  # the seed sits near its cell's middle

    # Rounded pebbles: a dome around the seed, a little wider than the cell's inscribed
    # circle (so neighbours flatten each other's sides), kept a random gap off the cell edge.
    R = (radius * swell)[cell]
    inner = np.minimum(R - to_seed, to_edge - gap[cell].astype(np.float32))
    height = flat[cell].astype(np.float32) * np.sqrt(np.maximum(R * R - to_seed * to_seed, 0.0))
    height = cv2.GaussianBlur(np.where(inner > 0, height, 0.0).astype(np.float32), (0, 0), 0.7)
    gy, gx = np.gradient(height)
    shade = (_LIGHT[2] - _LIGHT[0] * gx - _LIGHT[1] * gy) / np.sqrt(1.0 + gx * gx + gy * gy)
    shade = 0.35 + 0.65 * np.maximum(shade, 0.0) / _LIGHT[2]
    pebble = np.clip(inner, 0.0, 1.0)  # soft edge, one texel wide
    grain = np.pad(rng.standard_normal((n, n), dtype=np.float32), pad, mode="wrap")
    grain = cv2.GaussianBlur(grain, (0, 0), 0.6)  # periodic (the padding wraps)
    sand = 0.55 + 0.1 * grain
    tex = pebble * albedo[cell].astype(np.float32) * shade + (1.0 - pebble) * sand
    tex *= 1.0 + 0.12 * grain
    tex = tex[pad:pad + n, pad:pad + n]
    tex = (tex - tex.mean()) * (GRAVEL_STD / max(float(tex.std()), 1e-6)) + TEXTURE_MEAN
    return np.clip(tex, 0.0, 255.0).astype(np.float32)
