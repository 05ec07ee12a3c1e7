"""benchmarks.plane_drift's switch: the carrying Jacobian without the motion's share, and back."""

from __future__ import annotations

import numpy as np

import monovo_cli.core.plane.belief as belief
import monovo_cli.core.plane.tracker as tracker
from benchmarks.plane_drift import without_sensitivity


def test_without_sensitivity_drops_the_motions_share_and_restores_it():
    rng = np.random.default_rng(0)
    J, S = rng.normal(size=(3, 9)), rng.normal(size=(6, 3))
    with_share = belief.carrying_jacobian(J, S)
    assert not np.allclose(with_share, J[:, :3])
    with without_sensitivity():
        assert np.array_equal(belief.carrying_jacobian(J, S), J[:, :3])
        assert np.array_equal(tracker.carrying_jacobian(J, S), J[:, :3])
    assert np.array_equal(belief.carrying_jacobian(J, S), with_share)
    assert tracker.carrying_jacobian is belief.carrying_jacobian
