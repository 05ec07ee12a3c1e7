"""After frames are lost: the frame measured again from the last good one, and the fresh
keyframe a re-initialisation anchors.

:func:`resolve_gap` measures a frame directly from the last frame the tracker trusted
(:class:`GoodFrame`) before a run of lost ones (against :func:`gap_reference`),
:func:`resolved_pose` turns that fit into the frame's pose, the plane a fresh keyframe on it
starts from and its motion from the good frame; :func:`fresh_start` gives where a fresh
keyframe is anchored, with or without the re-solved gap, :func:`resolved_row` the row of a
frame re-initialised on the re-solved gap, and :func:`looks_usable` says whether a frame
may carry a fresh keyframe at all.
:class:`~monovo_cli.core.odometry.Odometry` decides when (docs/algorithm.md section 8).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from monovo_cli.core.checks import FitChecks, step_too_large
from monovo_cli.core.estimator.estimate import Estimate, estimate_motion
from monovo_cli.core.frame_std import FrameResult, from_predicted
from monovo_cli.core.keyframe import Keyframe
from monovo_cli.core.plane.motion_covariance import MotionCovariance
from monovo_cli.core.plane.tracker import PlaneTracker
from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.core.recovery.lost_frames import LostFrameRecovery
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.lie import orthonormalize, se3_inv
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import estimate_noise_sigma

REINIT_NOISE_SHARE = 0.3  # a fresh keyframe needs noise below this share of the contrast


@dataclass(frozen=True)
class GoodFrame:
    """The last frame whose pose the tracker trusts (accepted, or a re-initialisation): its
    ``index``, ``image`` (H, W), ``world_from_cur`` T_0_k and ``cur_from_key`` (4x4, from the
    keyframe it was estimated against). A gap after it is re-solved from it."""

    index: int
    image: np.ndarray
    world_from_cur: np.ndarray
    cur_from_key: np.ndarray


def looks_usable(image: np.ndarray) -> bool:
    """Whether a frame may carry a fresh keyframe: its noise well below its contrast (a
    frame of pure noise, or a blank one, may not)."""
    contrast = float(image.std())
    return contrast > 1e-3 and estimate_noise_sigma(image) < REINIT_NOISE_SHARE * contrast


def gap_reference(good: GoodFrame, key: Keyframe, predicted: np.ndarray,
                  brightness: tuple[float, float],
                  build: Callable[[int, np.ndarray, Plane, np.ndarray], Keyframe]
                  ) -> tuple[Keyframe, np.ndarray, tuple[float, float]] | None:
    """What a frame after lost ones is measured against from ``good``, the last good frame
    before them: ``key`` (the current keyframe) if that frame is the keyframe, else a
    keyframe built on it (``build(index, image, plane, world_from_key)``; closer than the
    old one). ``(the keyframe, the predicted cur_from_key against it, the starting gain and
    bias)`` from ``predicted`` (against ``key``) and ``brightness``; None where no keyframe
    can be built on the good frame."""
    if good.index == key.index:
        return key, predicted, brightness
    try:
        ref = build(good.index, good.image, key.plane.in_frame(good.cur_from_key),
                    good.world_from_cur)
    except TrackingError:
        return None
    return ref, orthonormalize(predicted @ se3_inv(good.cur_from_key)), (1.0, 0.0)


def resolve_gap(index: int, image: np.ndarray, pyr: list[np.ndarray], good: GoodFrame,
                ref: Keyframe, predicted: np.ndarray, brightness: tuple[float, float],
                checks: FitChecks, *, mask: np.ndarray | None, region: tuple[int, int, int, int]
                ) -> tuple[Keyframe, Estimate] | None:
    """Frame ``index`` (``image``, ``pyr``) measured directly against ``ref``, the keyframe
    on or at ``good`` (:func:`gap_reference`), starting from ``predicted`` (its
    ``cur_from_key`` against ``ref``, with ``brightness`` the gain and bias), then with the
    capture's starts (``checks``), its features matched against the good frame's image
    (``mask``, ``region`` the feature hypothesis'). ``(ref, the estimate)`` if one passes the
    checks, the step from the good frame among them (the one-frame bound once per frame of
    the gap: a fit across a gap, on little or repetitive texture, can land 100-135 deg
    turned), else None."""
    options = checks.options
    recovery = LostFrameRecovery(checks.camera, options=options.features, mask=mask, region=region)
    recovery.anchored(good.image)
    est = estimate_motion(ref.levels, pyr, predicted, options=options.estimator,
                          gain=brightness[0], bias=brightness[1])
    reason = checks.failure(est, ref)
    if reason:
        est, reason = checks.capture(index, ref, image, pyr, predicted, est, reason,
                                     predicted=predicted, recovery=recovery, brightness=brightness)
    if not reason:
        reason = step_too_large(good.world_from_cur, ref, orthonormalize(est.cur_from_key), options,
                                frames=index - good.index)
    return None if reason else (ref, est)


def resolved_pose(ref: Keyframe, est: Estimate, key: Keyframe, good: GoodFrame,
                  motion_cov: MotionCovariance, plane: PlaneTracker
                  ) -> tuple[np.ndarray, tuple[Plane, np.ndarray | None], np.ndarray, np.ndarray]:
    """A frame re-solved against ``ref`` (``est``, :func:`resolve_gap`; ``key`` the current
    keyframe, ``motion_cov`` its motion covariance, ``plane`` the tracker's plane side):
    its ``world_from_cur`` (4x4), the plane a fresh keyframe on it starts from (``key``'s
    carried there, with its chart covariance: :meth:`PlaneTracker.carried`), and the motion
    from ``good`` (4x4 ``good_from_cur``) with its covariance (6, 6), taken before the
    keyframe changes (the motion covariance's previous frame is the good one)."""
    cur_from_ref = orthonormalize(est.cur_from_key)
    world_from_cur = orthonormalize(ref.world_from_key @ se3_inv(cur_from_ref))
    motion_cov = motion_cov if ref is key else MotionCovariance()
    carried = plane.carried(ref.plane, cur_from_ref, est.covariance,
                            motion_cov.sensitivity(est, ref.levels[0], ref.plane))
    good_from_cur = orthonormalize(se3_inv(good.world_from_cur) @ world_from_cur)
    cov = motion_cov.relative(est, ref.levels[0], ref.plane, plane.reported(ref.plane),
                              good.cur_from_key if ref is key else np.eye(4), good_from_cur)
    return world_from_cur, carried, good_from_cur, cov


@dataclass(frozen=True)
class FreshStart:
    """Where a re-initialisation anchors a fresh keyframe: ``world_from_cur`` (4x4) the frame's
    pose, ``planes`` the planes to try in turn (in its camera, with their chart covariances,
    None: the prior's); for a re-solved gap ``good_from_cur`` (4x4) the motion from the last
    good frame and ``covariance`` (6, 6) its covariance (None: the gap bridged by the
    prediction)."""

    world_from_cur: np.ndarray
    planes: list[tuple[Plane, np.ndarray | None]]
    good_from_cur: np.ndarray | None = None
    covariance: np.ndarray | None = None


def fresh_start(lost: FrameResult, key: Keyframe, cur_from_key: np.ndarray,
                gap_variance: np.ndarray, resolved: tuple[Keyframe, Estimate] | None,
                good: GoodFrame, motion_cov: MotionCovariance, plane: PlaneTracker) -> FreshStart:
    """Where frame ``lost`` (recorded lost at ``cur_from_key`` against ``key``, the lost
    frames' predictions leaving ``gap_variance`` (6,)) is re-initialised: at the predicted
    pose on ``key``'s plane carried there fused with the mounting prior (the prediction's
    twist covariance :func:`predicted_twist`: after a few lost frames its tilt is worth less
    than the mounting's, and a fresh keyframe on a plane tilted by the prediction's error
    fits nothing), or at the pose ``resolved`` from ``good`` (:func:`resolved_pose`); the
    mount's plane (relative to the camera) last, where that one does not meet the region's
    rays in front of the camera. A covariance is loosened: the frame after lost ones
    measures its tilt again (:meth:`PlaneTracker.loosened`)."""
    if resolved is None:
        fresh = FreshStart(lost.world_from_cam, [plane.carried(
            key.plane, cur_from_key, predicted_twist(gap_variance), None)])
    else:
        world_from_cur, carried, good_from_cur, cov = resolved_pose(*resolved, key, good,
                                                                    motion_cov, plane)
        fresh = FreshStart(world_from_cur, [carried], good_from_cur, cov)
    planes = [(p, None if c is None else plane.loosened(c))
              for p, c in fresh.planes + [(plane.mount_plane, None)]]
    return replace(fresh, planes=planes)


def gap_closure(good: GoodFrame, key: Keyframe, predicted: np.ndarray, gap_steps: list[np.ndarray],
                last_std: np.ndarray) -> GapClosure:
    """What the lost frames since ``good`` leave for hindsight when the frame after them is
    accepted: the pose the prediction would give it (``predicted``, ``cur_from_key`` against
    ``key``) and the lost frames' predicted motions' variances (``gap_steps``, each (6,)),
    the accepted frame's own (``last_std`` (6,), what a lost row would have stated) last."""
    return GapClosure(good.index, orthonormalize(key.world_from_key @ se3_inv(predicted)),
                      np.array(gap_steps + [last_std ** 2]))


def predicted_twist(gap_variance: np.ndarray) -> np.ndarray:
    """(6, 6) the covariance of a predicted pose after lost frames: the variance their
    predictions left (``gap_variance`` (6,)), its largest translation's and rotation's taken
    on every axis of each."""
    return np.diag(np.r_[np.full(3, gap_variance[:3].max()), np.full(3, gap_variance[3:].max())])


def resolved_row(lost: FrameResult, words: str, keyframe: int, est: Estimate, good: GoodFrame,
                 world_from_prev: np.ndarray, world_from_cur: np.ndarray, cov: np.ndarray,
                 gap_before: np.ndarray, variances: np.ndarray) -> FrameResult:
    """The row of a frame re-initialised on its re-solved pose ``world_from_cur`` (``est``
    against the keyframe :func:`resolve_gap` returned, ``cov`` its motion's covariance from
    ``good``, :func:`resolved_pose`), the frame first recorded ``lost``: from the last lost
    frame's predicted pose ``world_from_prev`` to the re-solved one, its covariance the
    re-solved motion's plus what the lost frames left (``gap_before`` (6,)); ``keyframe``
    the fresh keyframe's index, ``words`` why, ``variances`` the lost frames' predicted
    motions' variances (n, 6) for the gap's closure."""
    prev_from_cur = orthonormalize(se3_inv(world_from_prev) @ world_from_cur)
    cov = cov + from_predicted(gap_before, prev_from_cur)
    return replace(
        lost, status=FrameStatus.REINIT, keyframe=keyframe, world_from_cam=world_from_cur,
        prev_from_cur=prev_from_cur, msd=est.msd, iterations=est.iterations, points=est.points,
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)), covariance=cov, gain=est.gain,
        bias=est.bias, reason=f"{words}; the gap re-solved from frame {good.index}",
        gap=GapClosure(good.index, lost.world_from_cam, variances))
