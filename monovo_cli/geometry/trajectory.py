"""Measures of a camera path given as ``world_from_cam`` poses (N, 4, 4)."""

from __future__ import annotations

import numpy as np


def path_length(world_from_cam: np.ndarray) -> float:
    """The length (m) of the camera path through poses (N, 4, 4): the sum of the steps."""
    return float(np.linalg.norm(np.diff(world_from_cam[:, :3, 3], axis=0), axis=1).sum())
