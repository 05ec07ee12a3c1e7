"""Split-half fits: how far a frame's estimate moves when only half of its points speak.

The estimate's covariance ``sigma^2 (O^T W O)^-1`` counts the image noise only. Where the
plane model's own error dominates (a frame captured across a wide change of view: a turn in
place, two steps at once; less, the frame that anchors the next keyframe), the differences
are correlated over the image and that covariance is far too small (a 30 deg MER turn:
0.04 deg off at 43 of its std). The fit on
the points left of the median column against the fit on those right of it, and the same for
the rows above and below, disagree by about what the model error moves the whole fit
(docs/algorithm.md section 8, "The capture's own error").
"""

from __future__ import annotations

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, KeyLevel, estimate_motion
from monovo_cli.core.options import EstimatorOptions

#: Points in view a split thins to, about: every floor(n / this)-th of the n in view (all n
#: below twice this; never twice this many or more): on a captured frame, and
#: on one that only anchors the next keyframe (a tracked drive's, where the time counts).
#: Chosen on the 1024² MER turn (10 000 and 20 000 left one of its 37 rows beyond 4 std,
#: 40 000 none) and the 512² speed drive (40 000 on its re-anchoring frames: 5.0 -> 4.5x ECC).
SPLIT_POINTS = 40_000
SPLIT_POINTS_REANCHOR = 10_000


def split_half_fits(level: KeyLevel, image: np.ndarray, est: Estimate,
                    options: EstimatorOptions, max_points: int = SPLIT_POINTS
                    ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(cur_from_key of one half, of the other)`` (4x4 each) for the split at the median
    column and at the median row of ``level``'s points in view under ``est`` (the finest
    level's, whose image is ``image``; every ``floor(n / max_points)``-th of the n in view,
    fewer than twice ``max_points``), each fitted at that
    level from ``est``'s pose and brightness; a split either of whose halves does not
    converge is left out."""
    if est.valid is None:
        return []
    inview = np.flatnonzero(est.valid)
    inview = inview[::max(1, len(inview) // max_points)]
    pts = level.points
    out = []
    for axis in (0, 1):
        coord = pts.uv[inview, axis]
        median = np.median(coord)
        pair = []
        for half in (inview[coord < median], inview[coord >= median]):
            if len(half) < max(options.min_valid_points, 8):
                break
            fit = estimate_motion((level.subset(half),), (image,), est.cur_from_key, options=options,
                                  gain=est.gain, bias=est.bias)
            if not fit.converged or fit.finest_iterations >= options.max_iterations:
                break
            pair.append(fit)
        if len(pair) == 2:
            out.append((pair[0], pair[1]))
    return out
