"""init.yaml read as written: frame 0's ground (the default) or a declared nominal mount.

The drives bob on their suspension (+-2 cm, +-2 deg) with frame 0 at a crest, so frame 0's
ground and the nominal mount differ by the crest: each reading must be unbiased on data
written its way, and reading one file the other way must show.
"""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from monovo_cli import track_frames
from monovo_cli.core.plane.belief import DISTANCE_CHANGE_PLANAR, PlaneBelief
from monovo_cli.core.plane.motion_covariance import TILT_MODEL_ERROR_DEG
from monovo_cli.core.plane.tracker import InitialTilt, PlaneTracker
from monovo_cli.geometry.plane import Plane
from monovo_cli.geometry.trajectory import path_length
from monovo_cli.io.config import load_init
from monovo_cli.io.formats import read_tum


def final_pct(seq, init=None, **kw) -> float:
    run = track_frames(seq / "frames", init if init is not None else seq / "init.yaml", **kw)
    _, gt = read_tum(seq / "groundtruth.tum")
    end = np.linalg.inv(gt[0]) @ gt[-1]
    return 100.0 * float(np.linalg.norm(run.trajectory[-1][:3, 3] - end[:3, 3])) / path_length(gt)


@pytest.fixture(scope="module")
def drives(synth_drive, tmp_path_factory):
    """The drive written each way. ``init_pose`` changes init.yaml alone (the frames and the
    ground truth are the same bytes), and the nominal mount's init.yaml does not depend on
    the drive's length: the nominal drive is the frame-0 one with the init.yaml of its
    2-frame start (byte for byte the 60-frame one's), rendered once instead of twice."""
    kw = dict(preset="drive", terrain="flat", size=(256, 256), seed=12, noise_var=10.0)
    frame0 = synth_drive(frames=60, init_pose="frame0", **kw)
    nominal = tmp_path_factory.mktemp("nominal") / "seq"
    shutil.copytree(frame0, nominal)
    start = synth_drive(frames=2, init_pose="nominal", **kw)
    for k in (0, 1):  # (what the sharing rests on: the frames are the same)
        name = f"frames/frame_{k:06d}.png"
        assert (start / name).read_bytes() == (frame0 / name).read_bytes(), name
    shutil.copyfile(start / "init.yaml", nominal / "init.yaml")
    return {"frame0": frame0, "nominal": nominal}


def test_both_conventions_are_unbiased_and_reading_either_as_the_other_is_not(drives):
    """Final error, % of the path (measured, 60 frames of 256², frame 0 at a crest of the
    bobbing 0.5 % off the mean distance): frame 0's ground 0.007 %, the nominal mount 0.14 %
    (60 frames' bobbing does not average to the nominal mount); the nominal mount read as
    frame 0's ground 0.76 %; frame 0's ground read as the nominal mount 0.46 %: its bob is
    then taken for the mean (0.007 % before 41e0f8d, when images that confirmed a nominal
    mount's tilt made its distance exact too, the next test's case)."""
    as_frame0 = final_pct(drives["frame0"])
    as_nominal = final_pct(drives["nominal"])
    assert as_frame0 < 0.05 and as_nominal < 0.3
    cfg = load_init(drives["frame0"] / "init.yaml")
    misread = final_pct(drives["frame0"], dataclasses.replace(cfg, nominal=True))
    cfg = load_init(drives["nominal"] / "init.yaml")
    misread_other = final_pct(drives["nominal"], dataclasses.replace(cfg, nominal=False))
    assert misread > 2 * as_frame0 and misread_other > 2 * as_nominal


def test_a_nominal_mount_whose_tilt_the_images_confirm_keeps_its_distance_loose(synth_drive):
    """Issue 24's case: frame 0 1.3 cm above the mean height, its pitch and roll at their
    means, init.yaml the nominal mount declared. The images confirm the tilt; the distance
    they cannot test stays known to the prior's width, and hindsight sets the scale from the
    declared mount: 0.17 % of the path (measured; 0.10 and 0.01 % on seeds 21 and 3). When a
    confirmed tilt made the distance exact too, frame 0's 0.87 % stayed in the scale: 0.83 %
    on each of the three seeds."""
    seq = synth_drive(preset="drive", terrain="flat", frames=60, size=(256, 256), seed=12,
                      noise_var=10.0, init_pose="nominal", crest=0.013)
    assert final_pct(seq) < 0.3


def test_a_tilt_the_images_stop_confirming_carries_the_model_error():
    """Frame 0's exact tilt agreed with frame 1 (chi-square 2): the ground seen is the plane
    under the wheels, and the carried distance gets the planar process noise. When a later
    frame's images no longer confirm it (chi-square 6, above the 90 % point), every tilt
    carries the model error in the report; the distance keeps the planar noise (on a plane
    one test in ten does that by chance)."""
    tracker = PlaneTracker(Plane(np.array([0.0, 0.8, 0.6]), 1.5))
    tracker.initial_tilt = InitialTilt((0.1, -0.1), (0.1, 0.1), 2.0, 1, False)
    assert tracker.distance_change == DISTANCE_CHANGE_PLANAR
    before = tracker.reported_covariance
    tracker._unconfirmed(4, 6.0)  # what PlaneTracker.test does on frame 4's images
    assert tracker.distance_change == DISTANCE_CHANGE_PLANAR
    added = np.diag(tracker.reported_covariance - before)[1:]
    np.testing.assert_allclose(added, np.radians(TILT_MODEL_ERROR_DEG) ** 2)


@pytest.mark.parametrize("keep", [False, True])
def test_a_corrected_tilt_leaves_the_disagreement_once_a_re_anchor_measures_the_ground(keep):
    """Frame 0's exact tilt contradicted by 1.6 and 0.4 deg (what PlaneTracker.test records):
    until a re-anchor has measured how far the ground seen departs from the carried plane,
    every tilt carries the disagreement (one of the two is that far off). Corrected on the
    images, the tilt tracked is the ground seen's from then on, and the departure the
    re-anchors measure is its error: the disagreement leaves the report (kept at init.yaml's
    with ``keep_initial_tilt``, it stays). Counting it for the whole drive made a rolling
    drive's std 2.4-3.6x too large on every axis (benchmarks.honesty, rolling-512: std of
    error / std 0.28-0.42; 0.36-0.86 without it)."""
    plane = Plane(np.array([0.0, 0.8, 0.6]), 1.5)
    tracker = PlaneTracker(plane, keep_initial_tilt=keep)
    disputed = np.radians([1.6, 0.4]) ** 2
    tracker._disputed_tilt = np.diag(disputed)
    before = np.diag(tracker.reported_covariance)[1:]
    assert np.all(before >= disputed)
    belief = PlaneBelief.from_covariance(plane, np.diag([1e-4, 1e-6, 1e-6]))
    tracker.consistency.reanchored(belief, belief, belief, 0.0, measured=belief)
    assert tracker.consistency.departure_measured
    after = np.diag(tracker.reported_covariance)[1:]
    if keep:
        assert np.all(after >= disputed)
    else:
        assert np.all(after < 0.1 * disputed), np.degrees(np.sqrt(after))
