"""JPL's CAHV, CAHVOR and CAHVORE camera models, and their conversion to a pinhole camera.

MER, MSL and Mars 2020 ship camera models, not ``K`` + distortion. A model is a handful of
3-vectors in the *model's frame* (a rover or site frame, metres):

- ``C`` the camera centre (the entrance pupil at the optical axis for CAHVORE), m;
- ``A`` the unit pointing axis; ``H = fx * h + cx * A`` and ``V = fy * v + cy * A``, with
  ``h``, ``v`` unit vectors of the image's rows and columns (px);
- ``O`` the unit optical axis about which the radial distortion ``R = (r0, r1, r2)`` acts
  (CAHVOR, Gennery 2001);
- ``E = (e0, e1, e2)`` the entrance-pupil shift along ``O`` and the ``linearity`` L of the
  lens (CAHVORE, Gennery 2006): L = 1 perspective, L = 0 fish-eye (equidistant).

Projection of a point ``P`` (model frame). With ``p = P - C``, ``zeta = p . O`` and
``lam = p - zeta O`` (the part of ``p`` across ``O``):

- CAHVOR: ``tau = |lam|^2 / zeta^2``, ``mu = r0 + r1 tau + r2 tau^2``, ``p' = p + mu lam``;
- CAHVORE: the incoming ray makes the angle ``theta`` with ``O`` that solves
  ``tan theta = |lam| / (zeta - s(theta))``, ``s = (theta / sin theta - 1)(e0 + e1 theta^2 +
  e2 theta^4)`` (Newton); ``chi = tan(L theta) / L`` (L > 0), ``sin(L theta) / L`` (L < 0) or
  ``theta`` (L = 0); ``chi' = chi (1 + r0 + r1 chi^2 + r2 chi^4)``; ``p' = O + chi' lam/|lam|``;

then ``x = p' . H / p' . A`` and ``y = p' . V / p' . A`` (px). With ``L = 1`` and ``E = 0``
CAHVORE is CAHVOR; with ``R = 0`` CAHVOR is CAHV, a pinhole. Pixel coordinates are read as
monovo's (the centre of the top-left pixel is (0, 0)).

The camera frame monovo derives from a model (OpenCV axes): ``z = A``, ``x = h`` (``H``
without its component along ``A``, normalised) and ``y = z x x`` (which is ``v`` when ``h``
and ``v`` are orthogonal, as in a calibrated model). A point of the model's frame is, in
the camera frame, ``X_cam = R (X_model - C)`` with ``R`` the rows ``x, y, z``:
:attr:`CahvorModel.cam_from_model` is that 4x4 transform, so a plane known in the model's
frame is ``plane.in_frame(model.cam_from_model)`` in the camera's.

:func:`fit_pinhole` turns a model into a :class:`~monovo_cli.geometry.camera.PinholeCamera`
with OpenCV ``k1 k2 p1 p2 k3`` distortion, fitted by least squares so that the pinhole puts
the model's rays back on their pixels over a grid covering the image, and states the RMS
and largest reprojection error (px). A CAHVOR with ``O = A`` is exactly OpenCV's radial model
``k1 = r1``, ``k2 = r2`` (``r0`` only rescales the focal length); ``O != A`` is absorbed by the
tangential terms; CAHVORE's pupil shift is ignored (it moves rays by ~``e0`` metres, far
below a pixel at the ground's distance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from monovo_cli.geometry.camera import PinholeCamera

#: Grid of pixels (per side) over which :func:`fit_pinhole` compares the two models.
FIT_GRID = 41
_NEWTON_ITERATIONS = 100
_NEWTON_TOL = 1e-12
_SMALL = 1e-8  # tan of the angle below which a ray is on the optical axis


def _vec(name: str, value) -> np.ndarray:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return v


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


@dataclass(frozen=True, eq=False)
class CahvorModel:
    """A CAHV / CAHVOR / CAHVORE camera model (see the module docstring).

    Vectors are (3,) float64 in the model's frame; ``O`` and ``R`` default to ``A`` and zero
    (CAHV), ``E`` to zero and ``linearity`` to 1 (CAHVOR). ``kind`` says which model the
    numbers came from ("cahv", "cahvor" or "cahvore"). Raises ValueError for vectors that
    do not make a camera (zero ``A``, ``H`` parallel to ``A``, ...).
    """

    C: np.ndarray
    A: np.ndarray
    H: np.ndarray
    V: np.ndarray
    O: np.ndarray | None = None
    R: np.ndarray = field(default_factory=lambda: np.zeros(3))
    E: np.ndarray = field(default_factory=lambda: np.zeros(3))
    linearity: float = 1.0
    kind: str = "cahvor"

    def __post_init__(self) -> None:
        C, A, H, V = (_vec(n, getattr(self, n)) for n in "CAHV")
        O = A.copy() if self.O is None else _vec("O", self.O)
        R, E = _vec("R", self.R), _vec("E", self.E)
        if not math.isfinite(float(self.linearity)):
            raise ValueError(f"linearity must be finite, got {self.linearity!r}")
        for name, v in (("A", A), ("O", O)):
            n = float(np.linalg.norm(v))
            if n < 1e-9:
                raise ValueError(f"{name} must not be zero-length")
            if abs(n - 1.0) > 1e-3:
                raise ValueError(f"{name} must be a unit vector, got length {n:.6g}")
        A, O = _unit(A), _unit(O)
        if float(O @ A) <= 0.5:
            raise ValueError(f"O is {math.degrees(math.acos(max(-1.0, min(1.0, O @ A)))):.3g} deg "
                             "from A; the optical axis must lie near the pointing axis")
        hs = np.linalg.norm(np.cross(A, H))
        vs = np.linalg.norm(np.cross(A, V))
        if hs < 1e-9 or vs < 1e-9:
            raise ValueError("H and V must not be parallel to A")
        h, v = _unit(H - (H @ A) * A), _unit(V - (V @ A) * A)
        if float(np.linalg.norm(np.cross(h, v))) < 0.5:
            raise ValueError("H and V point almost the same way across A; not a camera")
        if float(np.cross(h, v) @ A) <= 0.0:
            raise ValueError("H, V and A are left-handed (image x right, y down needs "
                             "(H x V) . A > 0)")
        for name, value in (("C", C), ("A", A), ("H", H), ("V", V), ("O", O), ("R", R), ("E", E)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "linearity", float(self.linearity))

    # ------------------------------------------------------------------ intrinsics, frame

    @property
    def hc(self) -> float:
        """Image column of the pointing axis ``A`` (px)."""
        return float(self.H @ self.A)

    @property
    def vc(self) -> float:
        """Image row of the pointing axis ``A`` (px)."""
        return float(self.V @ self.A)

    @property
    def hs(self) -> float:
        """Horizontal focal length (px)."""
        return float(np.linalg.norm(np.cross(self.A, self.H)))

    @property
    def vs(self) -> float:
        """Vertical focal length (px)."""
        return float(np.linalg.norm(np.cross(self.A, self.V)))

    @property
    def cam_R_model(self) -> np.ndarray:
        """(3, 3) rotation from the model's frame to the camera frame (rows x, y, z)."""
        z = self.A
        x = _unit(self.H - (self.H @ z) * z)
        y = np.cross(z, x)
        return np.stack([x, y, z])

    @property
    def cam_from_model(self) -> np.ndarray:
        """(4, 4) ``X_cam = R (X_model - C)``: the camera frame monovo derives from the model."""
        T = np.eye(4)
        R = self.cam_R_model
        T[:3, :3] = R
        T[:3, 3] = -R @ self.C
        return T

    # ------------------------------------------------------------------ projection

    def project(self, P: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of model-frame points ``P`` (N, 3), m; NaN for points behind."""
        p = np.asarray(P, dtype=float).reshape(-1, 3) - self.C
        return self._project_directions(p)

    @property
    def _has_pupil_shift(self) -> bool:
        return bool(np.any(self.E != 0.0))

    def _perspective(self, p: np.ndarray) -> np.ndarray:
        """The distorted vectors ``p'`` (N, 3) that the CAHV part projects."""
        O, (r0, r1, r2) = self.O, self.R
        zeta = p @ O
        lam = p - zeta[:, None] * O
        if self.kind != "cahvore" and self.linearity == 1.0 and not self._has_pupil_shift:
            with np.errstate(divide="ignore", invalid="ignore"):
                tau = np.einsum("ij,ij->i", lam, lam) / (zeta * zeta)
            mu = r0 + tau * (r1 + tau * r2)
            return p + mu[:, None] * lam
        lam_n = np.linalg.norm(lam, axis=1)
        theta = self._incoming_angle(zeta, lam_n)
        L = self.linearity
        if L > 1e-15:
            chi = np.tan(L * theta) / L
        elif L < -1e-15:
            chi = np.sin(L * theta) / L
        else:
            chi = theta
        chi2 = chi * chi
        chip = chi * (1.0 + r0 + chi2 * (r1 + chi2 * r2))
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(lam_n[:, None] > 0, lam / lam_n[:, None], 0.0)
        out = O[None, :] + chip[:, None] * u
        # Behind the camera (theta >= 90 deg for a perspective lens): no image.
        bad = ~np.isfinite(chip) | (theta >= math.pi) | ((L > 0) & (L * theta >= math.pi / 2))
        out[bad] = np.nan
        return out

    def _incoming_angle(self, zeta: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """CAHVORE: angle (rad) of the incoming ray to O, with the entrance pupil shifted
        along O by s(theta); Newton from the unshifted angle."""
        theta = np.arctan2(lam, zeta)
        if not self._has_pupil_shift:
            return theta
        e0, e1, e2 = self.E
        for _ in range(_NEWTON_ITERATIONS):
            t2 = theta * theta
            sin_t, cos_t = np.sin(theta), np.cos(theta)
            small = np.abs(theta) < 1e-4
            with np.errstate(divide="ignore", invalid="ignore"):
                g = np.where(small, t2 / 6.0 + 7.0 * t2 * t2 / 360.0, theta / sin_t - 1.0)
                dg = np.where(small, theta / 3.0 + 7.0 * theta * t2 / 90.0,
                              (sin_t - theta * cos_t) / (sin_t * sin_t))
            ee = e0 + t2 * (e1 + t2 * e2)
            de = theta * (2.0 * e1 + 4.0 * e2 * t2)
            s = g * ee
            ds = dg * ee + g * de
            f = (zeta - s) * sin_t - lam * cos_t
            df = -ds * sin_t + (zeta - s) * cos_t + lam * sin_t
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(df != 0.0, f / df, 0.0)
            theta = theta - step
            if np.all(np.abs(step[np.isfinite(step)]) < _NEWTON_TOL):
                break
        return theta

    def _project_directions(self, p: np.ndarray) -> np.ndarray:
        pp = self._perspective(p)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = pp @ self.A
            out = np.stack([pp @ self.H / w, pp @ self.V / w], axis=1)
        out[~(w > 0)] = np.nan
        return out

    def rays(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixels ``uv`` (N, 2): their origins (N, 3) (``C``, or the shifted
        entrance pupil of a CAHVORE) and unit directions (N, 3), both in the model's frame."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        A, H, V, O, (r0, r1, r2) = self.A, self.H, self.V, self.O, self.R
        # The perspective ray: p . (H - x A) = 0 and p . (V - y A) = 0.
        a = V[None, :] - uv[:, 1:2] * A[None, :]
        b = H[None, :] - uv[:, 0:1] * A[None, :]
        rp = np.cross(a, b)
        rp *= np.sign(rp @ A)[:, None]
        rp /= np.linalg.norm(rp, axis=1, keepdims=True)
        zeta = rp @ O
        lam = rp - zeta[:, None] * O
        lam_n = np.linalg.norm(lam, axis=1)
        chip = lam_n / zeta
        # Undo the radial distortion: chi (1 + r0 + r1 chi^2 + r2 chi^4) = chi'.
        chi = chip / (1.0 + r0)
        for _ in range(_NEWTON_ITERATIONS):
            c2 = chi * chi
            f = chi * (1.0 + r0 + c2 * (r1 + c2 * r2)) - chip
            df = 1.0 + r0 + c2 * (3.0 * r1 + 5.0 * r2 * c2)
            step = f / df
            chi = chi - step
            if np.all(np.abs(step) < _NEWTON_TOL):
                break
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(lam_n[:, None] > _SMALL * np.abs(zeta[:, None]),
                         lam / lam_n[:, None], 0.0)
        L = self.linearity
        if self.kind != "cahvore" and L == 1.0 and not self._has_pupil_shift:
            d = O[None, :] + chi[:, None] * u
            return (np.broadcast_to(self.C, d.shape).copy(),
                    d / np.linalg.norm(d, axis=1, keepdims=True))
        if L > 1e-15:
            theta = np.arctan(L * chi) / L
        elif L < -1e-15:
            theta = np.arcsin(np.clip(L * chi, -1.0, 1.0)) / L
        else:
            theta = chi
        t2 = theta * theta
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.where(np.abs(theta) < 1e-4, t2 / 6.0, theta / np.sin(theta) - 1.0)
        e0, e1, e2 = self.E
        s = g * (e0 + t2 * (e1 + t2 * e2))
        origins = self.C[None, :] + s[:, None] * O[None, :]
        d = np.sin(theta)[:, None] * u + np.cos(theta)[:, None] * O[None, :]
        return origins, d


# ----------------------------------------------------------------------------- conversion


@dataclass(frozen=True)
class PinholeFit:
    """A pinhole camera fitted to a camera model, and how well it reproduces it.

    ``camera`` the pinhole with OpenCV ``k1 k2 p1 p2 k3``; ``cam_from_model`` (4, 4) the
    camera frame (module docstring); ``rms_px`` / ``max_px`` the RMS and largest distance
    (px) between a grid pixel and the pinhole's projection of the model's ray through it.
    """

    camera: PinholeCamera
    cam_from_model: np.ndarray
    rms_px: float
    max_px: float


def _pinhole_residuals(params: np.ndarray, xn: np.ndarray, yn: np.ndarray, uv: np.ndarray,
                       jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = params
    r2 = xn * xn + yn * yn
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xy = xn * yn
    xd = xn * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * xn * xn)
    yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xy
    res = np.concatenate([fx * xd + cx - uv[:, 0], fy * yd + cy - uv[:, 1]])
    if not jacobian:
        return res, None
    n = len(xn)
    J = np.zeros((2 * n, 9))
    r4 = r2 * r2
    J[:n, 0], J[:n, 2] = xd, 1.0
    J[n:, 1], J[n:, 3] = yd, 1.0
    J[:n, 4], J[:n, 5], J[:n, 8] = fx * xn * r2, fx * xn * r4, fx * xn * r4 * r2
    J[n:, 4], J[n:, 5], J[n:, 8] = fy * yn * r2, fy * yn * r4, fy * yn * r4 * r2
    J[:n, 6], J[:n, 7] = fx * 2.0 * xy, fx * (r2 + 2.0 * xn * xn)
    J[n:, 6], J[n:, 7] = fy * (r2 + 2.0 * yn * yn), fy * 2.0 * xy
    return res, J


def fit_pinhole(model: CahvorModel, width: int, height: int, *, grid: int = FIT_GRID) -> PinholeFit:
    """The pinhole camera (OpenCV ``k1 k2 p1 p2 k3``) closest to ``model`` over a
    ``width`` x ``height`` image, by Levenberg-Marquardt on the reprojection error.

    A ``grid`` x ``grid`` lattice of pixels spanning the image (pixel centres of the corners
    included) is cast through ``model`` into the camera frame (:attr:`CahvorModel.cam_R_model`);
    the pinhole's parameters minimise the squared distances between each pixel and its
    ray's projection. Raises ValueError if some grid pixel has no ray in front of the camera.
    """
    width, height = int(width), int(height)
    us = np.linspace(0.0, width - 1.0, grid)
    vs = np.linspace(0.0, height - 1.0, grid)
    uu, vv = np.meshgrid(us, vs)
    uv = np.stack([uu.ravel(), vv.ravel()], axis=1)
    _, d = model.rays(uv)
    d_cam = d @ model.cam_R_model.T
    if not np.all(np.isfinite(d_cam)) or np.any(d_cam[:, 2] <= 1e-6):
        raise ValueError("some pixels of the image see rays at or beyond 90 deg from the axis; "
                         "such a (fish-eye) model has no pinhole equivalent")
    xn, yn = d_cam[:, 0] / d_cam[:, 2], d_cam[:, 1] / d_cam[:, 2]
    # Start from CAHV's intrinsics (no distortion), in the camera frame's axes.
    params = np.array([model.hs, model.vs, model.hc, model.vc, 0.0, 0.0, 0.0, 0.0, 0.0])
    res, J = _pinhole_residuals(params, xn, yn, uv, True)
    cost = float(res @ res)
    damping = 1e-6
    for _ in range(100):
        JtJ = J.T @ J
        g = J.T @ res
        scale = np.sqrt(np.maximum(np.diag(JtJ), 1e-30))
        A = JtJ / np.outer(scale, scale) + damping * np.eye(9)
        step = -np.linalg.solve(A, g / scale) / scale
        trial = params + step
        r_t, _ = _pinhole_residuals(trial, xn, yn, uv, False)
        c_t = float(r_t @ r_t)
        if c_t <= cost:
            converged = cost - c_t <= 1e-15 * max(cost, 1e-30) or np.all(
                np.abs(step) <= 1e-13 * np.maximum(np.abs(params), 1.0))
            params, cost = trial, c_t
            res, J = _pinhole_residuals(params, xn, yn, uv, True)
            damping = max(damping / 10.0, 1e-12)
            if converged:
                break
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = (float(v) for v in params)
    camera = PinholeCamera(width, height, fx, fy, cx, cy, (k1, k2, p1, p2, k3))
    err = np.hypot(res[: len(xn)], res[len(xn):])
    return PinholeFit(camera=camera, cam_from_model=model.cam_from_model,
                      rms_px=float(np.sqrt(np.mean(err * err))), max_px=float(err.max()))


def cahvor_from_pinhole(camera: PinholeCamera, cam_from_model: np.ndarray | None = None, *,
                        O_tilt_deg: tuple[float, float] = (0.0, 0.0)) -> CahvorModel:
    """The CAHVOR model of ``camera`` placed by ``cam_from_model`` (4, 4; identity: the model's
    frame is the camera frame). Exact for a radial-only camera (``p1 = p2 = k3 = 0``):
    ``R = (0, k1, k2)``, ``O = A`` (raises ValueError otherwise). ``O_tilt_deg`` tilts ``O``
    away from ``A`` by (about x, about y) degrees -- no pinhole equivalent then; for tests."""
    k1, k2, p1, p2, k3 = (tuple(camera.distortion) + (0.0,) * 5)[:5]
    if p1 != 0.0 or p2 != 0.0 or k3 != 0.0:
        raise ValueError("only k1 and k2 have a CAHVOR equivalent (p1 = p2 = k3 = 0)")
    T = np.eye(4) if cam_from_model is None else np.asarray(cam_from_model, dtype=float)
    Rm = T[:3, :3]
    C = -Rm.T @ T[:3, 3]
    x, y, z = Rm  # camera axes in the model's frame
    A = z
    H = camera.fx * x + camera.cx * A
    V = camera.fy * y + camera.cy * A
    ax, ay = (math.radians(a) for a in O_tilt_deg)
    o_cam = np.array([math.sin(ay) * math.cos(ax), -math.sin(ax), math.cos(ay) * math.cos(ax)])
    O = Rm.T @ o_cam
    return CahvorModel(C=C, A=A, H=H, V=V, O=O, R=np.array([0.0, k1, k2]), kind="cahvor")
