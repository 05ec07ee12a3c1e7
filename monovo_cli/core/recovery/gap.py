"""A run of lost frames closed by a frame whose pose was measured again (docs/algorithm.md
section 8, "Re-solving the gap").

Lost frames carry the prediction, and motion.csv streams them as they come. The frame that
ends the run is measured directly from before it: estimated against the keyframe that was
tracked before the loss, or, at a re-initialisation, re-solved from the last good frame.
Its pose then disagrees with the prediction that carried the lost frames. A
:class:`GapClosure` records what hindsight needs to share that disagreement out among their
predicted motions (:func:`monovo_cli.mapping.gaps.close_gaps`): the last good frame, the pose
the prediction gave the closing frame, and the variance of every predicted motion from the
last good frame to the closing one (the std their rows state).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class GapClosure:
    """How a frame closes the lost frames before it.

    ``last_good`` the index of the frame before them whose pose the tracker trusted;
    ``predicted`` (4, 4) the pose T_0_k the prediction gave the closing frame (its own pose,
    measured, is the frame's ``world_from_cam``); ``variances`` (n + 1, 6) of (tx, ty, tz,
    rx, ry, rz) (m^2, rad^2) of the n lost frames' predicted motions T_{k-1}_k and, last, of
    the closing frame's predicted one.
    """

    last_good: int
    predicted: np.ndarray
    variances: np.ndarray
