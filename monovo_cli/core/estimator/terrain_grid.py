"""Ground that is not a plane: a keyframe's terrain grid, estimated with the motion
(docs/algorithm.md section 9, "The terrain_grid").

The paper's "future work" made concrete: the keyframe's ground is its plane plus a **height
field on a grid of vertices** over the model rectangle (a mesh of quads, bilinear within
each), ``GRID_CELL`` m apart. An observation point keeps its keyframe pixel, so it moves
along its ray: on the plane ``n . X = d`` a point at height ``h`` above it (toward the
camera) is ``X = r (d - h) / (n . r)``, ``r = K^-1 (u, v, 1)``, exactly linear in ``h``,
and ``h`` is the bilinear blend of its cell's four vertex heights.

When a keyframe is left, :func:`refine_pose_and_terrain_grid` solves the two-view problem of the
keyframe and the frame that replaces it: the pose (with the affine brightness model) and
every vertex height, jointly, by Gauss-Newton on the intensity differences of a subsample of
the finest level's points (Huber weights, the scale from the median absolute deviation),
with the priors of :func:`_prior`: the heights stay near their own best-fit plane, whose
tilt is nearly free (it takes up the keyframe plane's tilt error) and which meets the ground
at the camera's foot, where the keyframe plane's distance is measured (the gauge of scale);
curvature is penalised, which also carries the heights into cells no point falls in. A
chi-square test (:attr:`TerrainGrid.significant`, run first on a quick, coarse solve) keeps the
plane where the images show no terrain_grid. Otherwise the pose comes from all the finest level's
points lifted onto the terrain grid (the estimator's warp of the points themselves), so the chain
of keyframes no longer inherits the plane's model error, and the terrain_grid's shape is carried
to the next keyframe (:func:`carried`), whose frames are tracked against it.

Derivatives (left perturbation ``T <- exp(delta^) T`` of ``cur_from_key``, ``Xc = T X``):
``dr/d delta`` is the observation row at ``Xc`` (:func:`~monovo_cli.core.estimator.jacobian.observation_rows`,
with the current image's gradient), ``dr/d h = (a . R r) * (-1 / (n . r))`` with ``a`` the
row's first three entries (d intensity / d Xc), ``dr/d gain = -I_key``, ``dr/d bias = -1``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import cv2
import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, KeyLevel, estimate_motion
from monovo_cli.core.estimator.jacobian import distortion_jacobian, observation_rows, project_in_front
from monovo_cli.core.estimator.robust import mad_scale, robust_weights
from monovo_cli.core.options import EstimatorOptions
from monovo_cli.geometry.lie import se3_exp
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import with_sobel_gradient
from monovo_cli.image.sampling import sample_bilinear

GRID_CELL = 0.4  # m between the grid's vertices on the ground
MAX_VERTICES_PER_SIDE = 32
HEIGHT_SIGMA = 0.05  # m: prior std of a vertex's height off the heights' best-fit plane
CURVATURE_SIGMA = 0.02  # m: prior std of a second difference of the heights
SAMPLE_POINTS = 20000  # points of the finest level used for the joint solution
QUICK_POINTS, QUICK_ITERATIONS, QUICK_CELL = 4000, 2, 0.8  # the test for a terrain grid at all
ITERATIONS = 4
HEIGHT_TOLERANCE = 5e-4  # m: the iterations stop when no height moves more (and the pose < 0.01 mm)
TILT_SIGMA_DEG = 2.0  # prior std of the heights' own tilt off the keyframe plane
FOOT_SIGMA = 0.001  # m: the heights' best-fit plane meets the camera's foot within this
SIGNIFICANCE = 3.0  # sigma of the chi-square over the heights (TerrainGrid.significant)
MIN_EXPLAINED = 0.3  # chi-square per point a terrain grid must reach (TerrainGrid.significant)


def plane_axes(plane: Plane) -> np.ndarray:
    """(2, 3): the plane's ``right`` and ``forward`` axes (keyframe camera): forward is the
    optical axis projected onto the plane, right = normal x forward."""
    n = plane.normal
    fwd = np.array([0.0, 0.0, 1.0]) - n[2] * n
    if np.linalg.norm(fwd) < 1e-9:  # looking straight down: image up
        fwd = np.array([0.0, -1.0, 0.0]) - n[1] * n
    fwd /= np.linalg.norm(fwd)
    return np.stack([np.cross(n, fwd), fwd])


@dataclass(frozen=True)
class TerrainGrid:
    """Heights ``h`` (ny, nx) m above ``plane`` (toward the camera; keyframe camera) at the
    vertices of a grid on it: vertex ``[j, i]`` at ``(x0 + i cell, y0 + j cell)`` along the
    plane's (right, forward) axes (:func:`plane_axes`), ``origin = (x0, y0)``."""

    plane: Plane
    origin: tuple[float, float]
    cell: float
    h: np.ndarray
    chi2: float = 0.0
    points: int = 0

    @property
    def significant(self) -> bool:
        """The images support the heights, and they matter: their chi-square (``chi2``, from
        the images alone, the pose free, in units of the residuals' variance) exceeds what
        noise gives over ``h.size`` heights by SIGNIFICANCE sigma, and it is at least
        MIN_EXPLAINED per point of the ``points`` it was measured on. On real images most
        of the residual is other model error (lens, lighting, objects off the ground): a
        terrain grid that explains little of it is significant but bends to that error
        (docs/algorithm.md section 9)."""
        dof = self.h.size
        return (self.chi2 > dof + SIGNIFICANCE * np.sqrt(2.0 * dof)
                and self.chi2 >= MIN_EXPLAINED * self.points)

    @classmethod
    def flat(cls, plane: Plane, X: np.ndarray, cell: float | None = None) -> TerrainGrid:
        """Zero heights on a grid of ``cell`` m covering points ``X`` (N, 3) on the plane
        (coarser where that would take more than MAX_VERTICES_PER_SIDE vertices)."""
        xy = X @ plane_axes(plane).T
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        cell = max(GRID_CELL if cell is None else cell,
                   float(np.max(hi - lo)) / (MAX_VERTICES_PER_SIDE - 1))
        nx, ny = (int(np.ceil((hi[k] - lo[k]) / cell - 1e-9)) + 1 for k in (0, 1))
        return cls(plane, (float(lo[0]), float(lo[1])), cell, np.zeros((max(ny, 2), max(nx, 2))))

    def vertices(self) -> np.ndarray:
        """(ny nx, 2): each vertex's position along the plane's (right, forward) axes, m,
        in the order of ``h.ravel()``."""
        ny, nx = self.h.shape
        j, i = np.mgrid[0:ny, 0:nx]
        return np.column_stack([self.origin[0] + self.cell * i.ravel(),
                                self.origin[1] + self.cell * j.ravel()])

    def weights(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bilinear blend at points ``X`` (N, 3) (their position along the plane): vertex
        indices (N, 4) into ``h.ravel()`` (the cell's corners, first row then second) and
        their weights (N, 4)."""
        first, fs, ft = self._cells(X)
        nx = self.h.shape[1]
        idx = np.stack([first, first + 1, first + nx, first + nx + 1], axis=1)
        w = np.stack([(1 - fs) * (1 - ft), fs * (1 - ft), (1 - fs) * ft, fs * ft], axis=1)
        return idx, w

    def _cells(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each point's cell (its first vertex's index) and position in it (N,), (N,), (N,)."""
        ny, nx = self.h.shape
        ax = plane_axes(self.plane)
        X = np.ascontiguousarray(X, dtype=np.float64)
        s = np.clip((X @ ax[0] - self.origin[0]) / self.cell, 0.0, nx - 1.0)
        t = np.clip((X @ ax[1] - self.origin[1]) / self.cell, 0.0, ny - 1.0)
        i0 = np.minimum(s.astype(np.int64), nx - 2)  # (s >= 0: truncation is the floor)
        j0 = np.minimum(t.astype(np.int64), ny - 2)
        return j0 * nx + i0, s - i0, t - j0

    def heights(self, X: np.ndarray) -> np.ndarray:
        """The terrain_grid's height (N,) m under points ``X`` (N, 3) on the plane."""
        first, fs, ft = self._cells(X)
        h = self.h.ravel()
        nx = self.h.shape[1]
        top = h[first] + fs * (h[first + 1] - h[first])
        bottom = h[first + nx] + fs * (h[first + nx + 1] - h[first + nx])
        return top + ft * (bottom - top)

    def lift(self, X: np.ndarray) -> np.ndarray:
        """Points ``X`` (N, 3) on the plane moved along their rays to the terrain_grid."""
        return X * ((self.plane.distance - self.heights(X)) / (X @ self.plane.normal))[:, None]


def transfer_terrain_grid(terrain_grid: TerrainGrid, cur_from_key: np.ndarray, plane: Plane,
                          X: np.ndarray) -> TerrainGrid:
    """``terrain_grid`` (of a keyframe) seen from a new keyframe at ``cur_from_key`` (4x4): a
    terrain grid on the new keyframe's ``plane`` (its camera) over its points ``X`` (N, 3, on that
    plane), each vertex at the height of the old terrain_grid's surface under it (the old grid's
    edge values beyond its extent)."""
    step = max(1, len(X) // 5000)
    new = TerrainGrid.flat(plane, X[::step])  # (points beyond a sample's extent: the edge heights)
    ny, nx = new.h.shape
    ax = plane_axes(plane)
    V = new.vertices()
    P = plane.distance * plane.normal + V @ ax  # the vertices, new camera
    R, t = cur_from_key[:3, :3], cur_from_key[:3, 3]
    n0, d0 = terrain_grid.plane.normal, terrain_grid.plane.distance
    Q = (P - t) @ R  # in the old keyframe's camera
    Q = Q + (d0 - Q @ n0)[:, None] * n0  # onto the old plane, along its normal
    S = (Q - terrain_grid.heights(Q)[:, None] * n0) @ R.T + t  # the old surface, new camera
    new = replace(new, h=(plane.distance - S @ plane.normal).reshape(ny, nx))
    # Its shape only: the plane through the heights under the new points is taken out (the
    # new keyframe's plane, the MAP of the plane beliefs, holds distance and tilt).
    xy = X[::step] @ ax.T
    A = np.column_stack([np.ones(len(xy)), xy])
    coef = np.linalg.lstsq(A, new.heights(X[::step]), rcond=None)[0]
    flat = coef[0] + V @ coef[1:]
    return replace(new, h=new.h - flat.reshape(ny, nx))


def lifted_levels(levels: tuple[KeyLevel, ...], terrain_grid: TerrainGrid) -> tuple[KeyLevel, ...]:
    """A keyframe's levels (points on ``terrain_grid.plane``) with every point lifted onto
    the terrain grid."""
    lift = terrain_grid.lift
    return tuple(KeyLevel.from_points(replace(kl.points, X=lift(terrain_grid.plane.intersect(kl.points.X))))
                 for kl in levels)


@lru_cache(maxsize=8)
def _curvature_normal(ny: int, nx: int) -> np.ndarray:
    """``D^T D`` (ny nx, ny nx) for the rows ``D`` of the grid's second differences along both
    sides (vertex ``[j, i]`` at ``j nx + i``); cached by shape, read-only."""
    def one_side(n: int) -> np.ndarray:
        D = np.zeros((max(n - 2, 0), n))
        for k in range(n - 2):
            D[k, k:k + 3] = (1.0, -2.0, 1.0)
        return D.T @ D
    out = np.kron(np.eye(ny), one_side(nx)) + np.kron(one_side(ny), np.eye(nx))
    out.flags.writeable = False
    return out


def _prior(terrain_grid: TerrainGrid, X: np.ndarray, idx: np.ndarray, bw: np.ndarray) -> np.ndarray:
    """The heights' prior information (V, V) (V = ``terrain_grid.h.size``), in m^-2, for the points
    ``X`` (N, 3, on the plane) with blend ``idx``, ``bw`` (:meth:`TerrainGrid.weights`):

    * each vertex's departure from the heights' best-fit plane (over the vertices), std
      HEIGHT_SIGMA; each second difference, std CURVATURE_SIGMA;
    * that plane's tilt, std TILT_SIGMA_DEG: free enough to take up the keyframe plane's
      own tilt error (a pitch error of 1 deg is 12 cm at the grid's far edge);
    * the gauge: the best-fit plane of the points' heights meets the ground at the camera's
      foot (where the keyframe plane's distance, the camera's height, is measured) within
      FOOT_SIGMA. Pinning the points' mean height instead would turn a pitch error of the
      keyframe plane into a scale error, the points lying metres ahead (docs/algorithm.md
      section 9, "the gauge of scale").
    """
    ny, nx = terrain_grid.h.shape
    V = ny * nx
    C = np.column_stack([np.ones(V), terrain_grid.vertices()])
    Cp = np.linalg.solve(C.T @ C, C.T)  # (3, V): coefficients of the heights' best-fit plane
    Q = np.eye(V) - C @ Cp  # the projector off the best-fit plane: Q^T Q = Q
    prior = Q / HEIGHT_SIGMA ** 2 + _curvature_normal(ny, nx) / CURVATURE_SIGMA ** 2
    prior += Cp[1:].T @ Cp[1:] / np.tan(np.radians(TILT_SIGMA_DEG)) ** 2
    xy = X @ plane_axes(terrain_grid.plane).T
    A = np.column_stack([np.ones(len(xy)), xy])
    q = np.linalg.solve(A.T @ A, A.T)[0]  # (N,): the intercept of a plane fit to the points
    foot = np.zeros(V)
    for k in range(4):
        foot += np.bincount(idx[:, k], weights=q * bw[:, k], minlength=V)
    return prior + np.outer(foot, foot) / FOOT_SIGMA ** 2


def height_rows(camera, Xc: np.ndarray, gx: np.ndarray, gy: np.ndarray,
                dXc_dh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The derivatives of the intensity at the projection of points ``Xc`` (N, 3, current
    camera; image gradients ``gx``, ``gy`` (N,) there, grey levels per px): the observation
    rows (6, N) of the twist of a left perturbation ``exp(delta^) Xc`` and ``dI/dh`` (N,),
    the derivative along ``dXc_dh`` (N, 3), each point's motion per metre of height. A
    camera with lens distortion gets its projection's Jacobian at the points."""
    D = distortion_jacobian(camera, Xc) if camera.has_distortion else None
    o = observation_rows(Xc, gx, gy, camera.fx, camera.fy, D)
    return o, np.einsum("kn,nk->n", o[:3], dXc_dh)


def _solve_spd(H: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """``H^-1 g`` for the joint normal matrix ``H`` (symmetric, positive definite with the
    heights' prior): OpenCV's Cholesky, serial and 2.5x faster than LAPACK's LU at the
    grid's ~600 unknowns; LU where Cholesky fails; None where both do."""
    ok, x = cv2.solve(H, g.reshape(-1, 1), flags=cv2.DECOMP_CHOLESKY)
    if ok and np.all(np.isfinite(x)):
        return x.ravel()
    try:
        return np.linalg.solve(H, g)
    except np.linalg.LinAlgError:
        return None


def solve_terrain_grid(level: KeyLevel, plane: Plane, image: np.ndarray,
                 cur_from_key: np.ndarray, *, start: TerrainGrid | None = None,
                 gain: float = 1.0, bias: float = 0.0,
                 options: EstimatorOptions | None = None, iterations: int | None = None,
                 sample_points: int | None = None, cell: float | None = None
                 ) -> tuple[TerrainGrid, np.ndarray, float, float]:
    """The joint Gauss-Newton of the module docstring on the finest ``level`` (points on
    ``plane``, or lifted onto the terrain grid ``start`` on it, whose heights the solution starts
    from) and the current frame's finest ``image`` from ``cur_from_key`` (4x4):
    ``(terrain grid, cur_from_key, gain, bias)``."""
    opts = options or EstimatorOptions()
    iterations = ITERATIONS if iterations is None else iterations
    pts = level.points
    step = max(1, len(pts) // (SAMPLE_POINTS if sample_points is None else sample_points))
    X0 = plane.intersect(pts.X[::step])  # (the points' rays onto the plane)
    I_key = pts.intensity[::step].astype(np.float64)
    terrain_grid = TerrainGrid.flat(plane, X0, cell) if start is None else start
    ny, nx = terrain_grid.h.shape
    V = ny * nx
    idx, bw = terrain_grid.weights(X0)
    # Points sorted by cell (named by its first vertex), so that per-cell sums are one
    # reduceat; a cell's sums go to its 4 vertices (offsets 0, 1, nx, nx + 1).
    order = np.argsort(idx[:, 0], kind="stable")
    X0, I_key, idx, bw = X0[order], I_key[order], idx[order], bw[order]
    cells, starts = np.unique(idx[:, 0], return_index=True)
    corner = cells[None, :] + np.array([0, 1, nx, nx + 1])[:, None]  # (4, cells)
    pairs = [(a, b) for a in range(4) for b in range(a, 4)]
    bwT = np.ascontiguousarray(bw.T, dtype=np.float32)
    rays = X0 / X0[:, 2:3]
    dz_dh = -rays / (rays @ plane.normal)[:, None]  # dX/dh (N, 3), keyframe camera
    prior = _prior(terrain_grid, X0, idx, bw)
    stack = with_sobel_gradient(image)  # sampled together: one remap
    cam = pts.camera
    T = np.array(cur_from_key, dtype=np.float64)
    h = terrain_grid.h.ravel().copy()
    Hhh = Hph = Hpp = None
    sigma2 = 1.0
    for _ in range(iterations):
        hb = h[idx] * bw  # (the four blends summed in order: np.sum's bits, a tenth its time)
        X = X0 + dz_dh * (hb[:, 0] + hb[:, 1] + hb[:, 2] + hb[:, 3])[:, None]
        Xc = X @ T[:3, :3].T + T[:3, 3]
        u, v, front = project_in_front(cam, Xc)
        samples, ok = sample_bilinear(stack, u, v)
        vals, gx, gy = samples.T
        ok &= front
        if np.count_nonzero(ok) < max(opts.min_valid_points, 50):
            break
        r = np.where(ok, vals - (gain * I_key + bias), 0.0)
        w = robust_weights(r.astype(np.float32), opts.robust, huber_k=opts.huber_k,
                           tukey_c=opts.tukey_c, scale=mad_scale(r.astype(np.float32), ok))[0]
        w = np.where(ok, w, 0.0).astype(np.float64)
        sigma2 = max(float(np.sum(w * r * r) / max(np.sum(w), 1.0)), 1e-6)
        o, jh = height_rows(cam, np.where(ok[:, None], Xc, 1.0), np.where(ok, gx, 0.0),
                            np.where(ok, gy, 0.0), dz_dh @ T[:3, :3].T)
        Jp = np.vstack([o, -I_key[None, :], -np.ones((1, len(r)))])  # (8, N)
        # Normal equations over (pose 8, heights V); a point's height column is jh blended
        # over its cell's vertices by bw.
        wr, wj = w * r, w * jh
        Hpp = (Jp * w) @ Jp.T
        gp = Jp @ wr
        # (float32: sums of ~100 terms per cell, for normal equations of a Gauss-Newton step)
        F = np.empty((46, len(r)), np.float32)
        np.multiply(Jp.astype(np.float32)[:, None, :], (wj * bw.T).astype(np.float32)[None],
                    out=F[:32].reshape(8, 4, -1))  # rows p * 4 + k
        wjj = (wj * jh).astype(np.float32)
        for m, (a, b) in enumerate(pairs):
            np.multiply(wjj, bwT[a] * bwT[b], out=F[32 + m])
        np.multiply((wr * jh).astype(np.float32), bwT, out=F[42:46])
        per_cell = np.add.reduceat(F, starts, axis=1).astype(np.float64)
        Hph = np.zeros((8, V))
        Hhh = np.zeros((V, V))
        gh = np.zeros(V)
        for k in range(4):
            Hph[:, corner[k]] += per_cell[k:32:4]
            gh[corner[k]] += per_cell[42 + k]
        for m, (a, b) in enumerate(pairs):
            Hhh[corner[a], corner[b]] += per_cell[32 + m]
            if a != b:
                Hhh[corner[b], corner[a]] += per_cell[32 + m]
        H = np.block([[Hpp, Hph], [Hph.T, Hhh + sigma2 * prior]])
        g = np.concatenate([gp, gh + sigma2 * prior @ h])
        dx = _solve_spd(H, g)
        if dx is None:
            break
        dx = -dx
        T = se3_exp(dx[:6]) @ T
        gain, bias, h = gain + dx[6], bias + dx[7], h + dx[8:]
        if np.max(np.abs(dx[8:])) < HEIGHT_TOLERANCE and np.linalg.norm(dx[:3]) < 1e-5:
            break
    chi2 = 0.0
    if Hhh is not None:  # what the images alone say of the heights, the pose set free
        try:
            M = Hhh - Hph.T @ np.linalg.solve(Hpp, Hph)
            chi2 = float(h @ M @ h) / sigma2
        except np.linalg.LinAlgError:
            chi2 = 0.0
    return (replace(terrain_grid, h=h.reshape(ny, nx), chi2=chi2, points=len(X0)), T, float(gain),
            float(bias))


def refine_pose_and_terrain_grid(level: KeyLevel, plane: Plane, image: np.ndarray,
                           est: Estimate, options: EstimatorOptions, *,
                           start: TerrainGrid | None = None
                           ) -> tuple[Estimate, TerrainGrid, KeyLevel | None]:
    """:func:`solve_terrain_grid` from the estimate ``est`` over the plane (or over ``start``, the
    terrain grid the level's points were lifted onto), then the pose from all the level's points
    lifted onto the terrain grid found: ``(estimate, terrain grid, the lifted level)``. ``est`` comes back
    (with the terrain grid found, and no level) where the images do not support the terrain grid
    (:attr:`TerrainGrid.significant`: ground that is a plane, where the heights would only add
    their noise) or the pose does not converge."""
    try:
        if start is None:  # first a quick look: is there a terrain grid at all? (most ground: no)
            quick = solve_terrain_grid(level, plane, image, est.cur_from_key, gain=est.gain,
                                 bias=est.bias, options=options, iterations=QUICK_ITERATIONS,
                                 sample_points=QUICK_POINTS, cell=QUICK_CELL)[0]
            if not quick.significant:
                return est, quick, None
        terrain_grid, T, gain, bias = solve_terrain_grid(level, plane, image, est.cur_from_key, start=start,
                                             gain=est.gain, bias=est.bias, options=options)
    except (ValueError, np.linalg.LinAlgError):  # degenerate points (e.g. all on one line)
        return est, TerrainGrid.flat(plane, plane.intersect(level.points.X)), None
    if not terrain_grid.significant:
        return est, terrain_grid, None
    lifted, = lifted_levels((level,), terrain_grid)
    new = estimate_motion((lifted,), (image,), T, options=options, gain=gain, bias=bias)
    if not new.converged or not np.all(np.isfinite(new.cur_from_key)):
        return est, terrain_grid, None
    return new, terrain_grid, lifted
