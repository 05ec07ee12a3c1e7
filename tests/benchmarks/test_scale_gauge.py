"""benchmarks.scale_gauge: the scale error of tying the ground seen to init.yaml's plane."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.scale_gauge import gauge_errors, visible_heights

MONOVO = "best-fit plane of all the visible ground (monovo)"


def test_a_plane_offset_at_the_foot_is_the_scale_error_of_every_plane_rule():
    """Heights that are a plane 6 mm above init.yaml's at the camera's foot, tilted: each
    best-fit-plane rule finds the 6 mm (0.4 % of a 1.5 m distance), the mean height does not."""
    x, y = np.meshgrid(np.linspace(-3.0, 3.0, 40), np.linspace(0.5, 6.0, 40))
    xy = np.column_stack([x.ravel(), y.ravel()])
    h = 0.006 + 0.01 * xy[:, 0] - 0.02 * xy[:, 1]
    errors = gauge_errors(xy, h, 1.5)
    for rule, e in errors.items():
        if rule.startswith("best-fit"):
            assert e == pytest.approx(0.4, abs=1e-9), rule
    assert abs(errors["mean height of the visible ground (no tilt)"] - 0.4) > 1.0


def test_flat_ground_leaves_no_gauge_error(synth_drive):
    """On flat ground the wheels' plane is the ground seen: the ray-cast heights above
    init.yaml's plane vanish and so does every rule's error."""
    seq = synth_drive(preset="drive", terrain="flat", frames=2, size=(128, 128), seed=2,
                      noise_var=0.0)
    xy, h, d = visible_heights(seq)
    assert len(h) > 500 and d == pytest.approx(1.5, abs=0.05)
    assert np.max(np.abs(h)) < 1e-6
    assert abs(gauge_errors(xy, h, d)[MONOVO]) < 1e-4
