"""A frame's row (:class:`FrameResult`) and the std it states: the rules that turn the
tracker's history into uncertainty.

A lost frame's row holds the prediction, its std the prediction's error
(:func:`prediction_std`); an accepted frame's covariance widens for a change of motion the
prediction did not foresee (:func:`unforeseen`, unless the images refuted the prediction,
:func:`refuted`), for a previous pose known only to the prediction (:func:`from_predicted`)
and for the model error its split halves show (:func:`split_spread`). Plain functions of
what :class:`~monovo_cli.core.odometry.Odometry` keeps; docs/algorithm.md section 8 gives
the rules.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate
from monovo_cli.core.estimator.split import split_half_fits
from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.options import EstimatorOptions
from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.core.status import FrameStatus
from monovo_cli.geometry.lie import (
    motion_change,
    motion_covariance_of_key_twist,
    orthonormalize,
    skew,
    so3_log,
)

PREDICTION_WINDOW = 30  # accepted frames whose motion changes measure the prediction's error
STANDING_SHARE = 0.5  # a lost frame's least std of each translation, x distance
STANDING_DEG = 10.0  # ... and of each rotation, deg
COVER = 4.0  # a row's error is to stay within this many of its std
UNFORESEEN_COVER = 4.0  # a change from the prediction beyond this many std is not foreseen
REFUTED_MSD_RATIO = 2.0  # a fit from the prediction this much worse than the one kept refutes it



@dataclass(frozen=True)
class FrameResult:
    """One frame's output.

    Poses are 4x4: ``world_from_cam`` is T_0_k, ``prev_from_cur`` T_{k-1}_k. ``covariance``
    (6, 6) and ``std`` (6,) are of (tx, ty, tz, rx, ry, rz) of ``prev_from_cur`` (m, rad;
    NaN for lost frames). ``gain``/``bias``: brightness relative to the keyframe.
    """

    index: int
    timestamp: float
    world_from_cam: np.ndarray
    prev_from_cur: np.ndarray
    msd: float
    iterations: int
    points: int
    status: FrameStatus
    std: np.ndarray
    covariance: np.ndarray
    keyframe: int = 0
    gain: float = 1.0
    bias: float = 0.0
    reason: str = ""
    gap: GapClosure | None = None  # the lost frames before this one, measured directly

def prediction_std(changes: Sequence[np.ndarray], last_motion: np.ndarray | None,
                   last_std: np.ndarray, distance: float, lost_run: int,
                   bridged: np.ndarray) -> np.ndarray:
    """(6,) m and rad: the std of a lost frame's motion, the prediction's uncertainty.

    The prediction repeats the last accepted motion (``last_motion`` (6,), None: none yet),
    so its error is the change of the motion since: per axis the larger of the RMS and the
    largest of the recent accepted frames' ``changes`` (PREDICTION_WINDOW of them, each (6,)),
    grown as a random walk with the frames lost since a motion was last measured
    (``lost_run``, this one included; a re-initialisation that re-solved no gap measured
    none, and the rows after it are as far from knowing the motion as before it), added to
    the last accepted motion's own std ``last_std`` (6,). Without such a history (the first
    frames) the motion itself, or at a standing start a fraction of the ground's
    ``distance`` (m) and STANDING_DEG, stands for it. ``bridged`` (6,): how far the pose
    taken (the feature hypothesis') is from the prediction, added as a further error.
    """
    if len(changes) >= 3:
        changes = np.array(changes)
        step = np.maximum(np.sqrt(np.mean(changes ** 2, axis=0)), changes.max(axis=0))
    elif last_motion is not None:
        step = np.abs(last_motion)
    else:
        step = np.r_[np.full(3, STANDING_SHARE * distance), np.full(3, np.radians(STANDING_DEG))]
    spread = step * np.sqrt(lost_run)
    return np.sqrt(spread ** 2 + last_std ** 2 + bridged ** 2)


def lost_std(predicted_std: np.ndarray, last_motion: np.ndarray | None,
             distance: float) -> np.ndarray:
    """(6,) m and rad: a lost row's std, the prediction's ``predicted_std`` (6,) but never
    below what a frame the images said nothing of may hold: STANDING_SHARE of the ground's
    ``distance`` (m) on each translation axis and STANDING_DEG on each rotation axis, or the
    last accepted motion's size (``last_motion`` (6,): its translation's norm on each
    translation axis, its rotation angle on each rotation axis) where that is larger.

    A frame is lost where the images contradict the prediction or say nothing (blank,
    corrupt). Either way the motion may have changed by more than it did in the recent
    history: the rover stopped, began a turn in place, or stepped past the capture range.
    The prediction is then off by up to a whole step, which the recent changes do not
    measure. The next accepted row inherits this variance (its motion starts at the
    prediction).
    """
    floor = np.r_[np.full(3, STANDING_SHARE * distance), np.full(3, np.radians(STANDING_DEG))]
    if last_motion is not None:
        floor = np.maximum(floor, np.r_[np.full(3, np.linalg.norm(last_motion[:3])),
                                        np.full(3, np.linalg.norm(last_motion[3:]))])
    return np.maximum(predicted_std, floor)


def unforeseen(change: np.ndarray, std: np.ndarray, predicted_std: np.ndarray) -> np.ndarray:
    """(6,) the variance (m^2, rad^2) an accepted frame's motion must add for a change the
    prediction did not foresee: zeros unless its motion differs from the previous frame's
    by ``change`` (6,: t m, rotation vector rad) more than UNFORESEEN_COVER times the two
    uncertainties, its own ``std`` (6,) and the prediction's ``predicted_std`` (6,: what a
    lost row would have stated here), on some axis; then ``(change / COVER)^2`` on every axis.

    The fit passed every check, so either the motion changed (a rover stopping to turn,
    a hand-held jerk: the estimate is right) or the fit found a wrong minimum that
    explains the images as well (the prediction was right). The images cannot tell the
    two apart, and a row marked lost would hold the prediction, wrong in the first case;
    so the estimate is kept and its std made to cover the prediction within COVER std.
    """
    expected = np.sqrt(std ** 2 + predicted_std ** 2)
    if np.all(np.abs(change) <= UNFORESEEN_COVER * expected):
        return np.zeros(6)
    return (change / COVER) ** 2


def refuted(from_prediction: Estimate | None, est: Estimate, captured: bool,
            at_start: Callable[[], float | None] | None = None) -> bool:
    """Whether the images refute the constant-velocity prediction as the frame's motion, so a
    change from it needs no wider std: the estimator started at the prediction
    (``from_prediction``, None: it did not) and either converged to ``est`` itself (not
    ``captured``: the prediction is not a minimum of the fit, or it would have stayed there),
    or its fit is worse than the captured ``est``'s by more than REFUTED_MSD_RATIO (robust
    msd: a turn in place predicted as a step fits near chance).

    A fit from the prediction that went far from it (``at_start``: the robust msd at the
    prediction's own pose, None where the fit stayed within the prediction's reach) refutes
    it only where that pose fits worse by more than REFUTED_MSD_RATIO too. On low texture
    under heavy noise the fit can wander into a wrong minimum no better than the pose it
    left: soak seed 42's scenario 149, frame 2 (a 3 cm zigzag step fitted 0.6 m and 10 deg
    away, 1.2x the noise level) was written at 0.05 deg, 207 std."""
    if from_prediction is None:
        return False
    if not captured:
        start = None if at_start is None else at_start()
        return start is None or start > REFUTED_MSD_RATIO * robust_msd(est)
    if not from_prediction.converged or not np.isfinite(from_prediction.msd):
        return True
    return robust_msd(from_prediction) > REFUTED_MSD_RATIO * robust_msd(est)


def from_predicted(variance: np.ndarray, prev_from_cur: np.ndarray) -> np.ndarray:
    """(6, 6) what a previous pose known only to ``variance`` (6,: m^2, rad^2, in its own
    frame; the lost frames' predictions, an accepted fit's aliases) adds to the covariance
    of the motion ``prev_from_cur`` (4x4) measured from it: with that pose off by ``(v, w)``,
    the motion is off by ``(-v + t x w, -w)``, so its rotation's doubt reaches the
    translation by the lever ``t`` (after a turn predicted where the rover drove, a 0.7 m
    step is 0.2 m off sideways)."""
    t = prev_from_cur[:3, 3]
    J = np.zeros((6, 6))
    J[:3, :3] = -np.eye(3)
    J[:3, 3:] = skew(t)
    J[3:, 3:] = -np.eye(3)
    return (J * variance) @ J.T


def lost_row(index: int, timestamp: float, world_from_cur: np.ndarray, prev_from_cur: np.ndarray,
             std: np.ndarray, est: Estimate | None, keyframe: int, brightness: tuple[float, float],
             reason: str) -> FrameResult:
    """The row of a lost frame ``index``: its pose (4x4 ``world_from_cur``, ``prev_from_cur``)
    the prediction's or the feature hypothesis', its covariance the diagonal of ``std`` (6,:
    :func:`prediction_std`), the failed fit ``est``'s numbers (None: none was made; a NaN msd
    as 0), ``keyframe`` the current keyframe, ``brightness`` the last gain and bias."""
    msd = est.msd if est is not None and np.isfinite(est.msd) else 0.0
    its = est.iterations if est is not None else 0
    pts = est.points if est is not None else 0
    return FrameResult(index, timestamp, world_from_cur, prev_from_cur, msd, its, pts,
                       FrameStatus.LOST, std, np.diag(std ** 2), keyframe, *brightness, reason)


def accepted_covariance(cov: np.ndarray, differences: Sequence[tuple[np.ndarray, np.ndarray]],
                        handed_over: np.ndarray | None, gap_variance: np.ndarray,
                        prev_from_cur: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(covariance, model error)`` (6, 6) of an accepted frame's motion ``prev_from_cur``
    (4x4) before the unforeseen change: the noise's ``cov``, the model error its row measured
    (``differences``, pairs of a difference (6,) and the variance (6,) its own noise gives it:
    the correction its terrain grid made, its split halves' spreads), the model error
    ``handed_over`` by the re-anchor before it (None: none; a row that re-anchors in turn
    states its own) and what the previous pose's doubt beyond its noise leaves
    (``gap_variance`` (6,), :func:`from_predicted`; zeros: none): a pose known only to the
    prediction, or one whose fit had aliases or rivals (which minimum it is: on a
    checkerboard a row one period off, the next row measured against the same keyframe
    comes back by a period that its own noise-only std called 0.005 m, 41 std).

    The row counts, on each axis, what a difference's square holds beyond its noise's
    variance: the halves of a thinned split measure a rotation no better than their noise
    on a drive that re-anchors on every frame, and counting that noise made its rotations'
    std 2-2.5x too large (``benchmarks.honesty``, MER drives).

    The first motion against a keyframe: its points sit on the plane (or the grid) the
    re-anchor fitted, with that fit's model error, and over one frame's baseline the robust
    weights do not yet set the unmodelled relief apart (on rocks: 2.5-2.8 mdeg off on 5 cm,
    6-8.5 std, where the rows after it are within 2). It carries the error its re-anchor
    measured on its own row, the whole differences (the returned model error; with only their
    part beyond the noise, a rock drive's frame 54 is 5.0 std off; counting both made a MER
    drive's std, which re-anchors on nearly every frame, 1.4-1.9x wider still)."""
    own, model = np.zeros((6, 6)), np.zeros((6, 6))
    for d, variance in differences:
        model += np.outer(d, d)
        beyond = np.sign(d) * np.sqrt(np.clip(d ** 2 - variance, 0.0, None))
        own += np.outer(beyond, beyond)
    if handed_over is not None:
        cov = cov + handed_over
    cov = cov + own
    if gap_variance.any():  # the previous pose's doubt: its error is ours
        cov = cov + from_predicted(gap_variance, prev_from_cur)
    return cov, model


def split_spread(key: Keyframe, pyr: list[np.ndarray], est: Estimate, options: EstimatorOptions,
                 max_points: int, motion_to: Callable[[Keyframe, np.ndarray], np.ndarray]
                 ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per split of ``est``'s points whose halves both converged
    (:func:`~monovo_cli.core.estimator.split.split_half_fits`), the difference between
    the halves' motions (6,) (m, rad; as motion.csv's, ``motion_to(key, cur_from_key)`` the
    motion to a pose against ``key``), the variance (6,) the two halves' noise gives it, and
    the difference between their rotations in the current camera (3,) (rad): the model
    error of a frame captured across a wide change of view, which the noise-only covariance
    does not count (:func:`accepted_covariance`). The whole difference, not half of it: that
    error is shared by the halves, not averaged away."""
    out = []
    prev_from_key = motion_to(key, np.eye(4))
    for fa, fb in split_half_fits(key.levels[0], pyr[0], est, options, max_points):
        a, b = orthonormalize(fa.cur_from_key), orthonormalize(fb.cur_from_key)
        noise = motion_covariance_of_key_twist(fa.covariance + fb.covariance, prev_from_key,
                                               motion_to(key, a))
        out.append((motion_change(motion_to(key, a), motion_to(key, b)), np.diag(noise),
                    so3_log(a[:3, :3] @ b[:3, :3].T)))
    return out


def robust_msd(est: Estimate) -> float:
    """The squared robust scale (MAD) of the frame's final differences (``Estimate.scale``):
    the msd of the bulk of the points, which a region the robust weights reject (a shadow, an
    object) leaves alone; the msd where the estimate has no scale."""
    return est.msd if est.scale is None else est.scale ** 2
