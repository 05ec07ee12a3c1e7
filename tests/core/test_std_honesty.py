"""The reported std is honest on both sides: std(error / std) per axis within 0.5-2 (issue
40), so a std twice too large fails as surely as one twice too small.

Every std multiplied by 2.5 puts each axis below 0.5 on these drives, every std multiplied
by 0.4 puts each above 2 (checked when the test was written: the bounds hold on the measured
0.57-1.05)."""

import numpy as np
import pytest

from benchmarks.common import motion_errors
from monovo_cli import iter_track
from monovo_cli.io.formats import read_motion_csv

HONEST = (0.5, 2.0)


def _z(seq) -> np.ndarray:
    """(rows, 6) error / reported std of the ``ok`` and ``reanchored`` rows of ``seq``."""
    res = list(iter_track(seq))[1:]
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    z = []
    for r, g in zip(res, gt):
        if r.status.value in ("ok", "reanchored"):
            e = motion_errors(r.prev_from_cur, g)
            e[3:] = np.radians(e[3:])
            z.append(e / r.std)
    return np.array(z)


@pytest.mark.parametrize("seed", [7, 8])
def test_the_std_of_a_planar_drive_is_neither_too_large_nor_too_small(synth_drive, seed):
    """A 60-frame 256² drive on the plane: std(error / std) 0.57-1.05 on every axis (seeds 7
    and 8, measured). Before issue 40's fixes ty and tz were 0.37-0.60: the carried distance's
    process noise, a weight of the MAP, was reported as its error."""
    seq = synth_drive(preset="drive", frames=60, size=(256, 256), seed=seed, noise_var=10.0)
    z = _z(seq)
    assert len(z) == 59
    honesty = np.std(z, axis=0)
    assert np.all((HONEST[0] <= honesty) & (honesty <= HONEST[1])), honesty
    assert np.all(np.abs(z) < 5.0)


def test_the_std_of_a_drive_that_re_anchors_on_every_frame_is_not_too_large(synth_drive):
    """MER spacing (0.6-0.75 m steps, turns in place, 256², 40 frames, seed 4): nearly every
    row re-anchors, so its std counts its split halves' spread. std(error / std) 0.65-0.99 on
    every axis (measured). Counting the halves' own noise in that spread (the thinned halves
    measure rotation no better than it) made the rotations' std too large: rx and ry 0.47."""
    seq = synth_drive(preset="mer", frames=40, size=(256, 256), seed=4, noise_var=10.0)
    z = _z(seq)
    assert len(z) == 39
    honesty = np.std(z, axis=0)
    assert np.all((HONEST[0] <= honesty) & (honesty <= HONEST[1])), honesty
    assert np.all(np.abs(z) < 5.0)


#: per axis (tx ty tz m, rx ry rz deg): 1.5 times the largest RMS error of the two drives
#: below, measured (7.5e-5, 5.8e-5, 4.8e-5 m; 1.40e-3, 1.86e-3, 1.29e-3 deg): a 2x loss of
#: accuracy fails, the run-to-run spread of an RMS over 59 rows (about 10 %) does not
RMS_BOUND = np.array([1.1e-4, 8.6e-5, 7.2e-5, 2.1e-3, 2.8e-3, 1.9e-3])


@pytest.mark.parametrize("seed", [7, 8])
def test_the_accuracy_on_a_planar_drive_is_that_measured(synth_drive, seed):
    """The same drives' RMS error of the motions per axis within 1.5 times what was measured
    (tests that allowed 30 std let a 2x loss of accuracy pass; issue 40)."""
    seq = synth_drive(preset="drive", frames=60, size=(256, 256), seed=seed, noise_var=10.0)
    res = list(iter_track(seq))[1:]
    _, gt, _ = read_motion_csv(seq / "groundtruth_motion.csv")
    errors = np.array([motion_errors(r.prev_from_cur, g) for r, g in zip(res, gt)])
    rms = np.sqrt(np.mean(errors ** 2, axis=0))
    assert np.all(rms <= RMS_BOUND), rms / RMS_BOUND
