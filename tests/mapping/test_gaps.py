"""Lost frames moved in hindsight by the frame that closed them (monovo_cli.mapping.gaps,
monovo_cli.core.recovery.gap)."""

import math

import numpy as np
import pytest

from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.geometry.lie import make_pose, se3_inv, so3_exp, so3_log
from monovo_cli.mapping.gaps import close_gaps, shared_out

UP = np.array([0.0, -1.0, 0.0])  # the camera's up (y down), the axis the rover turns about


def _chain(motions):
    out, T = [np.eye(4)], np.eye(4)
    for m in motions:
        T = T @ m
        out.append(T)
    return np.array(out)


def _step(metres, deg):
    return make_pose(so3_exp(UP * math.radians(deg)), np.array([0.0, 0.0, metres]))


def test_the_motions_least_sure_take_the_correction():
    """Two straight 0.5 m steps closed 0.3 m further on: the step of four times the variance
    takes four times the stretch, and together they meet the end."""
    steps = [_step(0.5, 0), _step(0.5, 0)]
    end = _step(1.3, 0)
    v = np.full((2, 6), 1e-4)
    v[1] *= 4.0
    out = shared_out(steps, end, v)
    np.testing.assert_allclose(out[0] @ out[1], end, atol=1e-9)
    assert out[0][2, 3] == pytest.approx(0.56, abs=1e-6)
    assert out[1][2, 3] == pytest.approx(0.74, abs=1e-6)


def test_the_closing_pose_is_met_and_the_correction_grows_along_the_gap():
    """Frames 0-2 good, 3-5 lost at a prediction that missed a 20 deg turn (4 x 5 deg), frame
    6 measured where the truth is: the lost frames move onto the truth's arc, within 2 mm
    where the prediction was up to 13 cm off, and the good ones not at all."""
    truth = _chain([_step(0.5, 0)] * 2 + [_step(0.5, 5)] * 4)
    predicted = _chain([_step(0.5, 0)] * 6)  # constant velocity through the gap
    W = truth.copy()
    W[3:6] = predicted[3:6]
    variances = np.tile([1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3], (4, 1))
    out = close_gaps(range(7), W, [(6, GapClosure(2, predicted[6], variances))])
    np.testing.assert_allclose(out[:3], W[:3], atol=1e-12)
    np.testing.assert_allclose(out[6], W[6], atol=1e-12)
    before = [np.linalg.norm(W[k][:3, 3] - truth[k][:3, 3]) for k in range(3, 6)]
    after = [np.linalg.norm(out[k][:3, 3] - truth[k][:3, 3]) for k in range(3, 6)]
    assert max(before) > 0.1 and max(after) < 0.002, (before, after)
    turned = [math.degrees(np.linalg.norm(so3_log((se3_inv(W[2]) @ out[k])[:3, :3])))
              for k in range(3, 7)]
    assert turned == sorted(turned) and turned[-1] == pytest.approx(20.0, abs=1e-6)
    for T in out:  # still rigid motions
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def test_a_closure_that_does_not_fit_the_frames_is_left_alone():
    W = _chain([_step(0.5, 0)] * 4)
    bad = [(4, GapClosure(0, W[4] @ _step(0.1, 3), np.ones((2, 6)))),  # 3 frames between
           (4, GapClosure(9, W[4] @ _step(0.1, 3), np.ones((4, 6))))]  # no frame 9
    np.testing.assert_array_equal(close_gaps(range(5), W, bad), W)
