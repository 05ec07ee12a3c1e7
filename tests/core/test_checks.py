"""The checks a fit must pass before the tracker accepts it (monovo_cli.core.checks)."""

from types import SimpleNamespace

import numpy as np
import pytest

from monovo_cli.core.checks import off_the_ground
from monovo_cli.core.frame_std import refuted
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import make_pose, so3_exp
from monovo_cli.geometry.plane import Plane, normal_from_pitch_roll, pitch_roll_deg

# 128 px at f = 100 px: the image spans 32.6 deg either side of the optical axis, so at a
# pitch of 45 deg its top row looks 12.4 deg below the horizon.
CAMERA = PinholeCamera(128, 128, 100.0, 100.0, 63.5, 63.5)
REGION = (0, 0, 128, 128)
KEY = SimpleNamespace(plane=Plane(normal_from_pitch_roll(45.0), 1.5))


def _pitched_up(deg: float) -> np.ndarray:
    """cur_from_key of the camera turned ``deg`` upwards about its x axis."""
    pose = make_pose(so3_exp(np.radians([-deg, 0.0, 0.0])), np.zeros(3))
    pitch, _ = pitch_roll_deg(KEY.plane.in_frame(pose).normal)
    assert pitch == pytest.approx(45.0 - deg)  # (the direction the test means)
    return pose


def test_poses_a_camera_that_sees_the_ground_can_take_pass():
    n = KEY.plane.normal
    along = np.cross(n, [1.0, 0.0, 0.0])  # a direction in the ground
    turn = make_pose(so3_exp(np.radians(30.0) * n), -1.0 * along)  # a yaw and a metre's step
    for pose in (np.eye(4), turn, _pitched_up(10.0), make_pose(np.eye(3), 1.2 * n)):
        assert off_the_ground(CAMERA, REGION, KEY, pose) == ""


def test_a_pose_that_looks_past_the_horizon_within_the_region_is_no_fit():
    assert "ground" in off_the_ground(CAMERA, REGION, KEY, _pitched_up(20.0))
    # the lower half of the image still sees the ground there: a region of it does not fail
    assert off_the_ground(CAMERA, (0, 64, 128, 128), KEY, _pitched_up(20.0)) == ""


def test_a_pose_below_the_ground_is_no_fit():
    n = KEY.plane.normal
    # the camera moved 1.6 m along the normal towards a ground 1.5 m away: 0.1 m below it
    below = make_pose(np.eye(3), -1.6 * n)
    assert KEY.plane.in_frame(below).distance == pytest.approx(-0.1)
    assert "ground" in off_the_ground(CAMERA, REGION, KEY, below)


def _fit(robust: float) -> SimpleNamespace:
    """A converged fit whose robust msd (squared MAD scale) is ``robust``."""
    return SimpleNamespace(msd=robust, scale=robust ** 0.5, converged=True)


def test_a_fit_that_left_the_prediction_refutes_it_only_where_the_prediction_fits_worse():
    # soak seed 42's scenario 149, frame 2: the fit went 0.6 m and 10 deg from a 3 cm step
    # prediction and leaves a robust msd of 58.5 where the prediction's own pose leaves 53.3
    est = _fit(58.5)
    asked = []

    def at(value):
        return lambda: asked.append(value) or value

    assert not refuted(est, est, False, at(53.3))
    assert refuted(est, est, False, at(2.5 * 58.5))  # a real change: the prediction misfits
    assert refuted(est, est, False, at(None))  # the fit stayed within the prediction's reach
    assert refuted(est, est, False)  # not asked
    assert not refuted(None, est, False, at(53.3))  # no fit from the prediction: nothing refuted
    assert asked == [53.3, 2.5 * 58.5, None]
    # a captured fit is judged by the fit from the prediction, as before; the start not asked
    assert refuted(_fit(3.0 * 58.5), est, True, at(1.0)) and not refuted(_fit(58.5), est, True, at(1.0))
    assert asked == [53.3, 2.5 * 58.5, None]
