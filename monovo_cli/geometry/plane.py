"""A plane ``{X : n . X = d}`` in a camera frame: the ground of the paper's model.

Ground from height and pitch
----------------------------
A camera ``height`` m above the ground, its optical axis pitched down from the horizontal by
``pitch_deg`` p (90 = looking straight down) and turned about its own optical axis by
``roll_deg`` r sees the plane ``distance = height`` and::

    normal = (sin r * cos p,  cos r * cos p,  sin p)

i.e. ``normal = Rz(r)^T (0, cos p, sin p)``: starting from the pitched camera (whose ground
normal is ``(0, cos p, sin p)``, docs/guide.md "init.yaml for a real camera"), the camera is
turned about its optical axis z by r with ``Rz`` the usual right-handed rotation. In the
image (x right, y down) a positive r turns the camera's x axis towards its y axis, i.e. the
camera turns *clockwise as seen from behind it*: its right side dips, so the scene appears
turned counter-clockwise and the horizon rises to the right (horizon slope dv/du = -tan r
for fx = fy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Plane:
    """The plane ``{X : normal . X = distance}`` in some camera frame.

    ``normal`` (3,) float64 is unit and points from the camera to the ground; ``distance`` > 0,
    m. Two planes are equal when their normals and distances are.
    """

    normal: np.ndarray
    distance: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "normal", np.asarray(self.normal, dtype=float))
        object.__setattr__(self, "distance", float(self.distance))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Plane):
            return NotImplemented
        return self.distance == other.distance and np.array_equal(self.normal, other.normal)

    __hash__ = None  # mutable array inside: not hashable

    @classmethod
    def from_height_pitch(cls, height: float, pitch_deg: float, roll_deg: float = 0.0) -> Plane:
        """The ground of a camera ``height`` m above it, pitched down by ``pitch_deg`` and rolled
        by ``roll_deg`` (degrees; convention in the module docstring)."""
        return cls(normal_from_pitch_roll(pitch_deg, roll_deg), float(height))

    def in_frame(self, b_from_a: np.ndarray) -> Plane:
        """The same plane expressed in frame b, given it in frame a and the 4x4 ``b_from_a``."""
        R, t = b_from_a[:3, :3], b_from_a[:3, 3]
        n = R @ self.normal
        return Plane(n, float(self.distance + n @ t))

    def intersect(self, rays: np.ndarray) -> np.ndarray:
        """Points (N, 3) where ``rays`` (N, 3) from the camera centre meet the plane.

        Rays that miss the plane (parallel or behind) give NaN rows.
        """
        denom = rays @ self.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(denom > 1e-9, self.distance / denom, np.nan)
        return rays * s[:, None]


def normal_from_pitch_roll(pitch_deg: float, roll_deg: float = 0.0) -> np.ndarray:
    """Unit ground normal (3,) of a camera pitched down by ``pitch_deg`` and rolled by
    ``roll_deg`` about its optical axis: ``(sin r cos p, cos r cos p, sin p)``."""
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    return np.array([math.sin(r) * math.cos(p), math.cos(r) * math.cos(p), math.sin(p)])


def pitch_roll_deg(normal: np.ndarray) -> tuple[float, float]:
    """The pitch and roll (degrees) of the camera that sees the ground of unit ``normal``
    (3,): the inverse of :func:`normal_from_pitch_roll`, ``p = asin(n_z)``,
    ``r = atan2(n_x, n_y)``."""
    n = np.asarray(normal, float)
    return (math.degrees(math.asin(max(-1.0, min(1.0, float(n[2]))))),
            math.degrees(math.atan2(float(n[0]), float(n[1]))))


def tangent_basis(n: np.ndarray) -> np.ndarray:
    """(3, 2): two orthonormal vectors orthogonal to the unit vector ``n`` (a fixed choice),
    ``e1 x e2 = n``."""
    a = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    e1 = _cross(n, a)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, _cross(n, e1)])


def _cross(a, b) -> np.ndarray:
    """``a x b`` of two 3-vectors (3,), the arithmetic of ``np.cross`` without its overhead,
    which shows at the few calls a frame this gets."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
