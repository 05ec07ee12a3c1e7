"""Terrain for the ray-cast synthetic drives: a height field ``z(x, y)`` over the ground frame G.

G has z up and metres as units. The surface is ``z = max(base(x, y), rock tops)``:

* ``base(x, y) = gx * x + gy * y + swell(x, y)``: a plane of gradient ``(gx, gy)`` (the
  ``slope`` terrain tilts it by 6 deg) plus a smooth swell, a periodic grid of heights
  (``SWELL_TILE`` m period, ``SWELL_SPACING`` m spacing) interpolated bilinearly; the swell
  is band-limited white noise whose wavelengths lie between 2 and 5 m;
* rocks: ellipsoids with a vertical axis, sunk into the base (their centre lies below the
  lowest base point under them, so only the cap above the ground shows and no rock floats);
  the surface over a rock is the higher of the base and the ellipsoid's upper half. Rocks
  occlude whatever lies behind them.

The four kinds of ``terrain`` (the drives of ``benchmarks/terrain.py``): ``flat`` (z = 0),
``rolling`` (+-5 cm swell over 2-5 m wavelengths), ``slope`` (a 6 deg slope and a +-3 cm
swell), ``rocks`` (flat ground and scattered rocks a few cm to ~20 cm high).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass

import numpy as np

from monovo_cli.errors import InputError

TERRAINS = ("flat", "rolling", "slope", "rocks")

SWELL_TILE = 40.96  # m, period of the swell in x and y
SWELL_SPACING = 0.04  # m between swell samples (1024 x 1024 grid)
SWELL_WAVELENGTHS = (2.0, 5.0)  # m
ROLLING_AMPLITUDE = 0.05  # m, peak |swell| of `rolling`
SLOPE_DEG = 6.0
SLOPE_AMPLITUDE = 0.03  # m, peak |swell| of `slope`
ROCK_DENSITY = 0.8  # rocks per m^2
ROCK_HEIGHTS = (0.03, 0.20)  # m above the ground, power law ~ h^-ROCK_POWER
ROCK_POWER = 2.5
ROCK_SPREAD = (1.2, 2.0)  # long horizontal semi-axis / visible height
ROCK_EMBED = 0.25  # fraction of the vertical semi-axis below the ground
ROCK_ALBEDO = (0.75, 1.25)  # multiplier of the draped texture
HEIGHTS_SPACING = 0.05  # m, the convenience grid written to terrain.npz


@dataclass(frozen=True)
class Rocks:
    """Ellipsoidal rocks with vertical axes (K rocks).

    ``centre`` (K, 3) m in G (z below the ground under the rock); ``axes`` (K, 3) semi-axes
    ``a, b`` (horizontal) and ``c`` (vertical), m; ``angle`` (K,) rad, the direction of
    axis ``a`` from G's x axis; ``albedo`` (K,) multiplies the texture draped on the rock.
    """

    centre: np.ndarray
    axes: np.ndarray
    angle: np.ndarray
    albedo: np.ndarray

    def __len__(self) -> int:
        return len(self.angle)

    @staticmethod
    def none() -> Rocks:
        """No rocks."""
        return Rocks(np.zeros((0, 3)), np.ones((0, 3)), np.zeros(0), np.ones(0))

    def tops(self, x: np.ndarray, y: np.ndarray, indices: np.ndarray) -> np.ndarray:
        """Upper surface of rocks ``indices`` above points ``(x, y)`` (P,) -> (P, k) m,
        ``-inf`` outside a rock's ellipse."""
        dx = x[:, None] - self.centre[None, indices, 0]
        dy = y[:, None] - self.centre[None, indices, 1]
        c, s = np.cos(self.angle[indices]), np.sin(self.angle[indices])
        u = (c * dx + s * dy) / self.axes[indices, 0]
        v = (-s * dx + c * dy) / self.axes[indices, 1]
        q = 1.0 - u * u - v * v
        with np.errstate(invalid="ignore"):
            top = self.centre[indices, 2] + self.axes[indices, 2] * np.sqrt(q)
        return np.where(q >= 0.0, top, -np.inf)


@dataclass(frozen=True)
class Terrain:
    """The height field: ``max(gx x + gy y + swell(x, y), rock tops)`` (module docstring).

    ``swell`` (N, N) float32 m: sample ``[j, i]`` is the height at ``(x, y) = (i, j) *
    spacing``, periodic with period ``N * spacing`` (all zeros for flat ground).
    """

    kind: str
    gradient: tuple[float, float]
    swell: np.ndarray
    spacing: float
    rocks: Rocks

    @property
    def period(self) -> float:
        """The swell's period (m) in x and y."""
        return self.swell.shape[0] * self.spacing

    def swell_range(self) -> tuple[float, float]:
        """Lowest and highest swell height, m (bounds of the bilinear interpolant)."""
        return float(self.swell.min()), float(self.swell.max())

    def swell_slope(self) -> float:
        """An upper bound of ``|grad swell|`` over the plane (bilinear interpolant)."""
        gx = np.abs(np.diff(self.swell, axis=1, append=self.swell[:, :1])).max() / self.spacing
        gy = np.abs(np.diff(self.swell, axis=0, append=self.swell[:1, :])).max() / self.spacing
        return float(math.hypot(gx, gy))

    def base_height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ground without rocks at ``(x, y)`` (any shape, m) -> same shape, m (float64)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        n = self.swell.shape[0]
        u, v = x / self.spacing, y / self.spacing
        i0, j0 = np.floor(u), np.floor(v)
        fu, fv = u - i0, v - j0
        i0 = i0.astype(np.int64) % n
        j0 = j0.astype(np.int64) % n
        i1, j1 = (i0 + 1) % n, (j0 + 1) % n
        z = self.swell.astype(np.float64)
        swell = ((1 - fv) * ((1 - fu) * z[j0, i0] + fu * z[j0, i1])
                 + fv * ((1 - fu) * z[j1, i0] + fu * z[j1, i1]))
        return self.gradient[0] * x + self.gradient[1] * y + swell

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The true surface ``z(x, y)`` with rocks, m (float64, the shape of ``x``)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        shape = np.broadcast(x, y).shape
        x, y = np.broadcast_to(x, shape).ravel(), np.broadcast_to(y, shape).ravel()
        z = self.base_height(x, y)
        if len(self.rocks) == 0 or z.size == 0:
            return z.reshape(shape)
        reach = float(self.rocks.axes[:, :2].max())
        # Points in 1 m cells, row by row: a chunk of them covers a thin strip.
        order = np.lexsort((np.floor(x), np.floor(y)))
        rx, ry = self.rocks.centre[:, 0], self.rocks.centre[:, 1]
        for start in range(0, len(order), 2048):
            idx = order[start:start + 2048]
            px, py = x[idx], y[idx]
            near = np.nonzero((rx > px.min() - reach) & (rx < px.max() + reach)
                              & (ry > py.min() - reach) & (ry < py.max() + reach))[0]
            if len(near):
                z[idx] = np.maximum(z[idx], self.rocks.tops(px, py, near).max(axis=1))
        return z.reshape(shape)


# --------------------------------------------------------------------------- generation


def _swell(rng: np.random.Generator, amplitude: float) -> np.ndarray:
    """Periodic band-limited noise (wavelengths SWELL_WAVELENGTHS), peak |z| = amplitude."""
    n = int(round(SWELL_TILE / SWELL_SPACING))
    fx = np.fft.rfftfreq(n, d=SWELL_SPACING)[None, :]  # cycles per metre
    fy = np.fft.fftfreq(n, d=SWELL_SPACING)[:, None]
    f = np.hypot(fx, fy)
    band = (f >= 1.0 / SWELL_WAVELENGTHS[1]) & (f <= 1.0 / SWELL_WAVELENGTHS[0])
    spec = (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape)) * band
    z = np.fft.irfft2(spec, s=(n, n))
    return (z * (amplitude / np.abs(z).max())).astype(np.float32)


def _rocks(rng: np.random.Generator, base: Terrain, bounds: tuple[float, float, float, float]
           ) -> Rocks:
    x0, y0, x1, y1 = bounds
    count = int(rng.poisson(ROCK_DENSITY * (x1 - x0) * (y1 - y0)))
    x = rng.uniform(x0, x1, count)
    y = rng.uniform(y0, y1, count)
    lo, hi = ROCK_HEIGHTS
    p = 1.0 - ROCK_POWER  # inverse CDF of the truncated power law
    visible = (lo ** p + rng.random(count) * (hi ** p - lo ** p)) ** (1.0 / p)
    a = visible * rng.uniform(*ROCK_SPREAD, count)
    b = a * rng.uniform(0.6, 1.0, count)
    c = visible / (1.0 - ROCK_EMBED)
    angle = rng.uniform(0.0, math.pi, count)
    albedo = rng.uniform(*ROCK_ALBEDO, count)
    # The centre sits ROCK_EMBED * c below the lowest base point of the rock's ellipse.
    phi = np.linspace(0.0, 2.0 * math.pi, 16, endpoint=False)
    ca, sa = np.cos(angle)[:, None], np.sin(angle)[:, None]
    ex = a[:, None] * np.cos(phi)[None, :]
    ey = b[:, None] * np.sin(phi)[None, :]
    px = np.concatenate([x[:, None], x[:, None] + ca * ex - sa * ey], axis=1)
    py = np.concatenate([y[:, None], y[:, None] + sa * ex + ca * ey], axis=1)
    ground = base.base_height(px, py).min(axis=1)
    centre = np.column_stack([x, y, ground - ROCK_EMBED * c])
    return Rocks(centre, np.column_stack([a, b, c]), angle, albedo)


def make_terrain(kind: str, rng: np.random.Generator,
                 bounds: tuple[float, float, float, float]) -> Terrain:
    """A terrain of ``kind`` (one of TERRAINS), deterministic in ``rng``; rocks (``rocks``
    only) are scattered over ``bounds = (x0, y0, x1, y1)`` m of G, nowhere else."""
    if kind not in TERRAINS:
        raise InputError(f"--terrain {kind!r}: unknown terrain, choose one of {', '.join(TERRAINS)}")
    n = int(round(SWELL_TILE / SWELL_SPACING))
    gradient = (0.0, 0.0)
    swell = np.zeros((n, n), np.float32)
    if kind == "rolling":
        swell = _swell(rng, ROLLING_AMPLITUDE)
    elif kind == "slope":
        downhill = rng.uniform(0.0, 2.0 * math.pi)
        g = math.tan(math.radians(SLOPE_DEG))
        gradient = (g * math.cos(downhill), g * math.sin(downhill))
        swell = _swell(rng, SLOPE_AMPLITUDE)
    terrain = Terrain(kind, gradient, swell, SWELL_SPACING, Rocks.none())
    if kind == "rocks":
        terrain = Terrain(kind, gradient, swell, SWELL_SPACING, _rocks(rng, terrain, bounds))
    return terrain


# --------------------------------------------------------------------------- terrain.npz


def terrain_npz_bytes(terrain: Terrain, bounds: tuple[float, float, float, float],
                      g_from_cam: list[np.ndarray]) -> bytes:
    """``terrain.npz``: the exact parameters (read back by :func:`load_terrain`); for tools
    without monovo, ``heights`` (rows y, columns x) sampled every HEIGHTS_SPACING m over
    ``bounds``, sample ``[j, i]`` at ``heights_origin + (i, j) * heights_spacing``; and
    ``g_from_cam`` (n, 4, 4), the camera poses in the terrain's frame G (camera 0's frame,
    the ground truth's world, is ``g_from_cam[0]``)."""
    x0, y0, x1, y1 = bounds
    xs = x0 + HEIGHTS_SPACING * np.arange(int(math.ceil((x1 - x0) / HEIGHTS_SPACING)) + 1)
    ys = y0 + HEIGHTS_SPACING * np.arange(int(math.ceil((y1 - y0) / HEIGHTS_SPACING)) + 1)
    heights = terrain.height(xs[None, :], ys[:, None]).astype(np.float32)
    buf = io.BytesIO()
    r = terrain.rocks
    np.savez_compressed(
        buf, kind=np.array(terrain.kind), gradient=np.array(terrain.gradient),
        swell=terrain.swell, swell_spacing=np.array(terrain.spacing),
        rock_centre=r.centre, rock_axes=r.axes, rock_angle=r.angle, rock_albedo=r.albedo,
        heights=heights, heights_origin=np.array([x0, y0]),
        heights_spacing=np.array(HEIGHTS_SPACING), g_from_cam=np.array(g_from_cam))
    return buf.getvalue()


def load_terrain(path) -> Terrain:
    """The terrain of a ``terrain.npz`` written by ``monovo synth --terrain``."""
    try:
        with np.load(path) as f:
            rocks = Rocks(f["rock_centre"], f["rock_axes"], f["rock_angle"], f["rock_albedo"])
            return Terrain(str(f["kind"]), tuple(float(v) for v in f["gradient"]),
                           f["swell"], float(f["swell_spacing"]), rocks)
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{path}: not a terrain.npz of monovo synth ({exc})") from None
