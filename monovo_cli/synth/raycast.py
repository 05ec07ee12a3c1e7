"""Rendering a terrain (:mod:`monovo_cli.synth.terrain`) by casting a ray per supersample.

Image formation, independent of the estimator's planar model:

* a pinhole camera without distortion; every image is rendered at ``supersample`` times its
  resolution (supersample ``(i, j)`` at original pixel ``((i + 0.5)/s - 0.5, (j + 0.5)/s -
  0.5)``, as in :mod:`~monovo_cli.synth.render`) and area-averaged down;
* each ray's first hit with the height field: the base ground (plane + swell) by marching
  with steps that cannot jump over the swell (the step is the height above the swell's
  top over the fastest the ray can approach it, at least ``MIN_STEP_XY`` of ground), then
  bisection to ``TOLERANCE_XY`` and one secant step; rocks (ellipsoids) in closed form; the
  nearest hit wins, so rocks occlude whatever lies behind them;
* the texture is draped on the surface (texture coordinates = the hit point's ground x, y),
  sampled trilinearly from its mip-map with the level of the supersample's footprint (the
  Jacobian of pixel to ground x, y on the local tangent plane);
* Lambertian shading by a distant sun (no cast shadows), scaled so that level ground keeps
  the texture's grey values; rays that miss the ground see a plain sky.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.synth.render import SKY_VALUE
from monovo_cli.synth.terrain import Terrain
from monovo_cli.synth.texture import GroundTexture

TERRAIN_SUPERSAMPLE = 2
MIN_STEP_XY = 0.03  # m of ground per marching step, at least
TOLERANCE_XY = 0.01  # m of ground: bisection stops here, a secant step finishes
SUN_ELEVATION_DEG = 45.0
AMBIENT = 0.35  # share of the light that does not depend on the surface's orientation
_REMAP_WIDTH = 2048  # points are sampled as rows of this many (cv2.remap wants < 32767)
_PAIR_CHUNK = 1 << 21  # (ray, rock) pairs tested at a time


@dataclass(frozen=True)
class Hits:
    """First hits of N rays: ``t`` (N,) depth along the camera's optical axis, m (``inf``:
    no hit, sky); ``point`` (N, 3) in G, m; ``rock`` (N,) int, index of the rock hit or -1
    for the base ground; ``normal`` (N, 3) unit surface normals in G."""

    t: np.ndarray
    point: np.ndarray
    rock: np.ndarray
    normal: np.ndarray


def _sample(img: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear, periodic samples of ``img`` at texel coordinates ``(u, v)`` (N,) -> (N,) float32.

    Coordinates may lie outside the image (BORDER_WRAP); keep them within a few thousand
    texels of it, where float32 still resolves 1/1000 texel."""
    n = len(u)
    if n == 0:
        return np.zeros(0, np.float32)
    rows = -(-n // _REMAP_WIDTH)
    mu = np.zeros(rows * _REMAP_WIDTH, np.float32)
    mv = np.zeros(rows * _REMAP_WIDTH, np.float32)
    mu[:n] = u
    mv[:n] = v
    out = cv2.remap(img, mu.reshape(rows, -1), mv.reshape(rows, -1), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_WRAP)
    return out.ravel()[:n]


class TerrainRenderer:
    """Renders views of one textured terrain with one camera (module docstring).

    ``sun_azimuth`` (rad, from G's x axis) and ``SUN_ELEVATION_DEG`` place the sun;
    ``shading=False`` shows the bare texture (albedo) everywhere.
    """

    def __init__(self, cam: PinholeCamera, texture: GroundTexture, terrain: Terrain, *,
                 supersample: int = TERRAIN_SUPERSAMPLE, sky: float = SKY_VALUE,
                 sun_azimuth: float = 0.0, shading: bool = True) -> None:
        self.cam, self.texture, self.terrain = cam, texture, terrain
        self.s = int(supersample)
        self.sky = float(sky)
        s = self.s
        xs = (np.arange(cam.width * s) + 0.5) / s - 0.5
        ys = (np.arange(cam.height * s) + 0.5) / s - 0.5
        self._rx = ((xs - cam.cx) / cam.fx).astype(np.float32)
        self._ry = ((ys - cam.cy) / cam.fy).astype(np.float32)
        self._swell = np.ascontiguousarray(terrain.swell, dtype=np.float32)
        self._lo, self._hi = terrain.swell_range()
        self._lipschitz = terrain.swell_slope()
        h = terrain.spacing
        z = self._swell
        self._dzdx = ((np.roll(z, -1, axis=1) - np.roll(z, 1, axis=1)) / (2 * h)).astype(np.float32)
        self._dzdy = ((np.roll(z, -1, axis=0) - np.roll(z, 1, axis=0)) / (2 * h)).astype(np.float32)
        el = math.radians(SUN_ELEVATION_DEG)
        self._sun = np.array([math.cos(el) * math.cos(sun_azimuth),
                              math.cos(el) * math.sin(sun_azimuth), math.sin(el)], np.float32)
        self._shading = bool(shading)
        r = terrain.rocks
        self._rock_reach = r.axes.max(axis=1) if len(r) else np.zeros(0)

    # ----------------------------------------------------------------- the base ground

    def _swell_origin(self, o: np.ndarray) -> tuple[float, float]:
        """Swell grid coordinates of the camera, reduced by whole periods (float32 precision)."""
        h, period = self.terrain.spacing, self.terrain.period
        return float(np.mod(o[0], period) / h), float(np.mod(o[1], period) / h)

    def _base(self, o: np.ndarray, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray) -> np.ndarray:
        """Depth ``t`` (N,) float32 of the first hit of rays ``o + t d`` with the base ground
        (``inf``: none)."""
        gx, gy = self.terrain.gradient
        g0 = float(o[2] - gx * o[0] - gy * o[1])  # camera height over the plane
        g1 = dz - np.float32(gx) * dx - np.float32(gy) * dy
        t = np.full(len(dx), np.inf, np.float32)
        idx = np.flatnonzero(g1 < 0)
        a = -g1[idx]
        lo, hi = self._lo, self._hi
        if hi == lo:  # a plane
            t[idx] = (g0 - lo) / a
            return t
        if g0 <= hi:
            raise ValueError("camera must be above the terrain's highest swell")
        dxi, dyi = dx[idx], dy[idx]
        dxy = np.hypot(dxi, dyi)
        inv_h = np.float32(1.0 / self.terrain.spacing)
        ux, uy = dxi * inv_h, dyi * inv_h
        ox, oy = self._swell_origin(o)

        def f(tk, a_, ux_, uy_):  # the ray's height over the surface
            return (g0 - a_ * tk) - _sample(self._swell, ox + tk * ux_, oy + tk * uy_)

        t0, t1 = (g0 - hi) / a, (g0 - lo) / a  # the ray is in the swell's slab in between
        # March: steps the surface cannot rise into (the height over the swell's top over
        # the fastest the ray can approach the surface), at least MIN_STEP_XY of ground.
        rate = np.float32(self._lipschitz) * dxy + a
        min_step = np.float32(MIN_STEP_XY) / np.maximum(dxy, np.float32(1e-9))
        lo_t, hi_t = t0.copy(), t1.copy()
        f_lo, f_hi = np.zeros_like(t0), np.zeros_like(t0)
        k = np.arange(len(idx))
        state = [t0, a, ux, uy, rate, min_step, t1]
        f_cur = f(t0, a, ux, uy)
        while len(k):
            cur, a_, ux_, uy_, rate_, step_, t1_ = state
            nxt = np.minimum(cur + np.maximum(f_cur / rate_, step_), t1_)
            f_nxt = f(nxt, a_, ux_, uy_)
            hit = (f_nxt <= 0) | (nxt >= t1_)
            kh = k[hit]
            lo_t[kh], hi_t[kh], f_lo[kh], f_hi[kh] = cur[hit], nxt[hit], f_cur[hit], f_nxt[hit]
            go = ~hit
            k, f_cur = k[go], f_nxt[go]
            state = [nxt[go]] + [v[go] for v in state[1:]]
        # Bisection of every bracket to TOLERANCE_XY of ground, then one secant step.
        widest = float(((hi_t - lo_t) * dxy).max(initial=0.0))
        for _ in range(min(int(np.ceil(np.log2(max(widest / TOLERANCE_XY, 1.0)))), 40)):
            mid = 0.5 * (lo_t + hi_t)
            f_mid = f(mid, a, ux, uy)
            below = f_mid <= 0
            hi_t = np.where(below, mid, hi_t)
            f_hi = np.where(below, f_mid, f_hi)
            lo_t = np.where(below, lo_t, mid)
            f_lo = np.where(below, f_lo, f_mid)
        den = f_lo - f_hi
        frac = np.where(den > 0, f_lo / np.where(den > 0, den, 1.0), 1.0)
        t[idx] = lo_t + np.clip(frac, 0.0, 1.0) * (hi_t - lo_t)
        return t

    def _base_normal(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        """Unit normals (three (N,) float32 arrays) of the base at swell grid coordinates."""
        gx, gy = self.terrain.gradient
        if self._hi == self._lo:
            nx = np.full(len(u), -gx, np.float32)
            ny = np.full(len(u), -gy, np.float32)
        else:
            nx = -np.float32(gx) - _sample(self._dzdx, u, v)
            ny = -np.float32(gy) - _sample(self._dzdy, u, v)
        norm = np.sqrt(nx * nx + ny * ny + 1.0)
        return nx / norm, ny / norm, 1.0 / norm

    # ----------------------------------------------------------------- rocks

    def _visible_rocks(self, g_from_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rocks whose bounding sphere meets the view frustum, and their conservative pixel
        boxes ``(k, 4)`` = x0, y0, x1, y1 (original pixels, inclusive, inside the image)."""
        rocks, cam = self.terrain.rocks, self.cam
        if len(rocks) == 0:
            return np.zeros(0, np.int64), np.zeros((0, 4))
        R, o = g_from_cam[:3, :3], g_from_cam[:3, 3]
        C = (rocks.centre - o) @ R  # camera frame
        rho = self._rock_reach
        xl, xr = (-0.5 - cam.cx) / cam.fx, (cam.width - 0.5 - cam.cx) / cam.fx
        yt, yb = (-0.5 - cam.cy) / cam.fy, (cam.height - 0.5 - cam.cy) / cam.fy
        X, Y, Z = C[:, 0], C[:, 1], C[:, 2]
        ok = ((Z > -rho) & ((X - xl * Z) >= -rho * math.hypot(1, xl))
              & ((xr * Z - X) >= -rho * math.hypot(1, xr))
              & ((Y - yt * Z) >= -rho * math.hypot(1, yt))
              & ((yb * Z - Y) >= -rho * math.hypot(1, yb)))
        k = np.flatnonzero(ok)
        X, Y, Z, rho = X[k], Y[k], Z[k], rho[k]
        near, far = Z - rho, Z + rho
        straddles = near <= 1e-3
        near = np.maximum(near, 1e-3)
        with np.errstate(divide="ignore", invalid="ignore"):
            x0 = np.minimum((X - rho) / near, (X - rho) / far)
            x1 = np.maximum((X + rho) / near, (X + rho) / far)
            y0 = np.minimum((Y - rho) / near, (Y - rho) / far)
            y1 = np.maximum((Y + rho) / near, (Y + rho) / far)
        box = np.column_stack([cam.fx * x0 + cam.cx, cam.fy * y0 + cam.cy,
                               cam.fx * x1 + cam.cx, cam.fy * y1 + cam.cy])
        box[straddles] = [-1.0, -1.0, cam.width, cam.height]
        lim = np.array([cam.width - 0.5, cam.height - 0.5] * 2)
        box = np.clip(box, -0.5, lim)
        return k, box

    def _rock_hits(self, o: np.ndarray, d: np.ndarray, rock: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Entry depth of rays ``o + t d`` (M, 3) into rocks ``rock`` (M,) (``inf``: miss), and
        the entry points in the rocks' unit-sphere coordinates (M, 3)."""
        r = self.terrain.rocks
        ax = r.axes[rock]
        c, s = np.cos(r.angle[rock]), np.sin(r.angle[rock])
        p = o[None, :] - r.centre[rock]
        d = d.astype(np.float64)
        pu = np.column_stack([(c * p[:, 0] + s * p[:, 1]), (-s * p[:, 0] + c * p[:, 1]), p[:, 2]]) / ax
        du = np.column_stack([(c * d[:, 0] + s * d[:, 1]), (-s * d[:, 0] + c * d[:, 1]), d[:, 2]]) / ax
        A = np.einsum("ij,ij->i", du, du)
        tc = -np.einsum("ij,ij->i", pu, du) / A
        closest = pu + tc[:, None] * du
        q = 1.0 - np.einsum("ij,ij->i", closest, closest)
        t = tc - np.sqrt(np.maximum(q, 0.0) / A)
        t = np.where((q >= 0) & (t > 0), t, np.inf)
        return t, pu + np.where(np.isfinite(t), t, 0.0)[:, None] * du

    def _rock_normal(self, rock: np.ndarray, unit: np.ndarray) -> np.ndarray:
        r = self.terrain.rocks
        m = unit / r.axes[rock]  # gradient of |p / axes|^2 in the rock's frame
        c, s = np.cos(r.angle[rock]), np.sin(r.angle[rock])
        n = np.column_stack([c * m[:, 0] - s * m[:, 1], s * m[:, 0] + c * m[:, 1], m[:, 2]])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def _nearest_rocks(self, o: np.ndarray, d: np.ndarray, pairs) -> tuple[np.ndarray, np.ndarray]:
        """Per ray, the nearest rock entry depth and rock index (-1: none), given an iterable
        of candidate ``(ray, rock)`` index arrays."""
        t_best = np.full(len(d), np.inf)
        best = np.full(len(d), -1, np.int64)
        for ray, rock in pairs:
            t, _ = self._rock_hits(o, d[ray], rock)
            hit = np.isfinite(t)
            ray, rock, t = ray[hit], rock[hit], t[hit]
            np.minimum.at(t_best, ray, t)
            win = t <= t_best[ray]
            best[ray[win]] = rock[win]
        return t_best, best

    def _grid_pairs(self, g_from_cam: np.ndarray):
        """Candidate ``(supersample index, rock)`` pairs of the full image, in chunks."""
        k, box = self._visible_rocks(g_from_cam)
        s, sw = self.s, self.cam.width * self.s
        # Supersamples whose centre lies in the box: i with (i + 0.5)/s - 0.5 in [x0, x1].
        i0 = np.ceil((box[:, 0] + 0.5) * s - 0.5).astype(np.int64)
        i1 = np.floor((box[:, 2] + 0.5) * s - 0.5).astype(np.int64)
        j0 = np.ceil((box[:, 1] + 0.5) * s - 0.5).astype(np.int64)
        j1 = np.floor((box[:, 3] + 0.5) * s - 0.5).astype(np.int64)
        nx, ny = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
        count = nx * ny
        start = 0
        while start < len(k):
            stop = start + max(1, int(np.searchsorted(np.cumsum(count[start:]), _PAIR_CHUNK)))
            sel = np.arange(start, min(stop, len(k)))
            start = sel[-1] + 1
            n = count[sel]
            if n.sum() == 0:
                continue
            which = np.repeat(sel, n)
            local = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
            px = i0[which] + local % nx[which]
            py = j0[which] + local // nx[which]
            yield py * sw + px, k[which]

    # ----------------------------------------------------------------- casting

    def _hit(self, g_from_cam: np.ndarray, d: tuple[np.ndarray, np.ndarray, np.ndarray], pairs):
        """The rays that hit: their indices, depth ``t`` (float32), rock (-1: base), offset
        ``t d`` from the camera (three float32 arrays) and unit normal (three arrays)."""
        o = g_from_cam[:3, 3].astype(np.float64)
        dx, dy, dz = d
        t = self._base(o, dx, dy, dz)
        rock = np.full(len(dx), -1, np.int64)
        if len(self.terrain.rocks):
            t_rock, best = self._nearest_rocks(o, np.column_stack(d), pairs)
            t_rock = t_rock.astype(np.float32)
            closer = t_rock < t
            t = np.where(closer, t_rock, t)
            rock = np.where(closer, best, -1)
        idx = np.flatnonzero(np.isfinite(t))
        t, rock = t[idx], rock[idx]
        rel = (t * dx[idx], t * dy[idx], t * dz[idx])
        ox, oy = self._swell_origin(o)
        inv_h = np.float32(1.0 / self.terrain.spacing)
        nx, ny, nz = self._base_normal(ox + rel[0] * inv_h, oy + rel[1] * inv_h)
        on_rock = np.flatnonzero(rock >= 0)
        if len(on_rock):
            ray = idx[on_rock]
            _, unit = self._rock_hits(o, np.column_stack([dx[ray], dy[ray], dz[ray]]), rock[on_rock])
            n = self._rock_normal(rock[on_rock], unit).astype(np.float32)
            nx[on_rock], ny[on_rock], nz[on_rock] = n[:, 0], n[:, 1], n[:, 2]
        return idx, t, rock, rel, (nx, ny, nz)

    def cast(self, g_from_cam: np.ndarray, x: np.ndarray, y: np.ndarray) -> Hits:
        """First hits of the rays through pixels ``(x, y)`` (N,) of the camera at ``g_from_cam``."""
        cam = self.cam
        x = np.asarray(x, dtype=float).ravel()
        y = np.asarray(y, dtype=float).ravel()
        r = np.column_stack([(x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, np.ones_like(x)])
        d = (r @ g_from_cam[:3, :3].T).astype(np.float32)
        k, box = self._visible_rocks(g_from_cam)
        inside = ((x[:, None] >= box[None, :, 0] - 1) & (x[:, None] <= box[None, :, 2] + 1)
                  & (y[:, None] >= box[None, :, 1] - 1) & (y[:, None] <= box[None, :, 3] + 1))
        ray, j = np.nonzero(inside)
        idx, t, rock, _, normal = self._hit(g_from_cam, (d[:, 0], d[:, 1], d[:, 2]), [(ray, k[j])])
        n = len(x)
        out_t = np.full(n, np.inf)
        out_t[idx] = t
        point = np.full((n, 3), np.nan)
        point[idx] = g_from_cam[:3, 3] + t[:, None].astype(np.float64) * d[idx].astype(np.float64)
        out_rock = np.full(n, -1, np.int64)
        out_rock[idx] = rock
        out_normal = np.full((n, 3), np.nan)
        out_normal[idx] = np.column_stack(normal)
        return Hits(out_t, point, out_rock, out_normal)

    def render(self, g_from_cam: np.ndarray) -> np.ndarray:
        """Noise-free float32 image (height x width) of the terrain seen from ``g_from_cam``."""
        out = self.render_fine(g_from_cam)
        if self.s > 1:
            return cv2.resize(out, (self.cam.width, self.cam.height), interpolation=cv2.INTER_AREA)
        return out

    def render_fine(self, g_from_cam: np.ndarray) -> np.ndarray:
        """The supersampled image (height * s x width * s, float32) that :meth:`render`
        area-averages."""
        cam, s = self.cam, self.s
        R = g_from_cam[:3, :3].astype(np.float32)
        rx, ry = self._rx[None, :], self._ry[:, None]
        d = tuple((R[i, 0] * rx + R[i, 1] * ry + R[i, 2]).ravel() for i in range(3))
        idx, t, rock, rel, n = self._hit(g_from_cam, d, self._grid_pairs(g_from_cam))
        out = np.full(len(d[0]), self.sky, np.float32)
        if len(idx):
            out[idx] = self._shade(g_from_cam, [c[idx] for c in d], t, rock, rel, n)
        return out.reshape(cam.height * s, cam.width * s)

    def _shade(self, g_from_cam, d, t, rock, rel, n) -> np.ndarray:
        """Grey values of the hits: the draped texture (trilinear mip-map), rock albedo, sun."""
        cam, tex, s = self.cam, self.texture, self.s
        # Pixel size on the ground (x, y): d X / d px = t/f (v - d (n.v)/(n.d)) on the
        # tangent plane, v the camera axis in G; the larger of the two pixel axes.
        nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2]
        size = np.zeros(len(t), np.float32)
        for axis, f in ((0, cam.fx), (1, cam.fy)):
            v = [np.float32(c) for c in g_from_cam[:3, axis]]
            ratio = (n[0] * v[0] + n[1] * v[1] + n[2] * v[2]) / nd
            size = np.maximum(size, np.hypot(v[0] - d[0] * ratio, v[1] - d[1] * ratio)
                              * (t * np.float32(1.0 / f)))
        top = len(tex.levels) - 1
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.log2(size * np.float32(1.0 / tex.metres_per_texel)) - np.float32(math.log2(s))
        lam = np.clip(np.nan_to_num(lam, nan=top, posinf=top), 0.0, top)

        o = g_from_cam[:3, 3]
        k0 = np.float32(1.0 / tex.metres_per_texel)
        h, w = tex.shape
        u0 = float(np.mod(o[0] / tex.metres_per_texel, w))
        v0 = float(np.mod(o[1] / tex.metres_per_texel, h))
        value = np.zeros(len(t), np.float32)
        for level in range(int(lam.min()), min(int(np.ceil(lam.max())), top) + 1):
            sel = np.flatnonzero(np.abs(lam - level) < 1.0)
            if len(sel):
                weight = 1.0 - np.abs(lam[sel] - level)
                k = np.float32(0.5 ** level)
                value[sel] += weight * _sample(tex.levels[level], (u0 + rel[0][sel] * k0) * k,
                                               (v0 + rel[1][sel] * k0) * k)
        if len(self.terrain.rocks):
            on = rock >= 0
            value[on] *= self.terrain.rocks.albedo[rock[on]].astype(np.float32)
        if self._shading:
            sun = self._sun
            lit = np.float32(AMBIENT) + np.float32(1.0 - AMBIENT) * np.maximum(
                n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2], np.float32(0.0))
            value *= lit * np.float32(1.0 / (AMBIENT + (1.0 - AMBIENT) * sun[2]))
        return value
