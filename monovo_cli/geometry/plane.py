"""A plane ``{X : n . X = d}`` in a camera frame: the ground of the paper's model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plane:
    """The plane ``{X : normal . X = distance}`` in some camera frame.

    ``normal`` (3,) is unit and points from the camera to the ground; ``distance`` > 0, m.
    """

    normal: np.ndarray
    distance: float

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
