"""Planes for the keyframe-plane tests (test_plane_belief, test_motion_covariance)."""

from __future__ import annotations

import math

import numpy as np

from monovo_cli.geometry.lie import so3_exp
from monovo_cli.geometry.plane import Plane, tangent_basis

N0 = np.array([0.0, math.cos(math.radians(40)), math.sin(math.radians(40))])


def tilted(plane: Plane, t1: float, t2: float = 0.0, dd: float = 0.0) -> Plane:
    """``plane`` turned by angles t1, t2 (rad) along its tangent basis, distance + dd."""
    E = tangent_basis(plane.normal)
    axis = np.cross(plane.normal, E[:, 0]) * t1 + np.cross(plane.normal, E[:, 1]) * t2
    n = so3_exp(axis) @ plane.normal if np.any(axis) else plane.normal
    return Plane(n, plane.distance + dd)
