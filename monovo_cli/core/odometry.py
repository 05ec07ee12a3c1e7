"""The sequence loop: keyframes, pose chaining, re-anchoring, loss detection and recovery.

Owns the state; does no I/O and no printing. Frames come in one at a time and a
:class:`FrameResult` goes out for each, so memory does not grow with the sequence.

Each frame is estimated against the current keyframe (the paper's ground model, moved with
the accumulated motion), so drift grows per keyframe, not per frame. A new keyframe is
anchored on the current frame when too few of the keyframe's points stay in view or the
model covers too little of the image; its plane is then the MAP of the plane carried by the
motions, the normal measured from the two images and init.yaml's mounting prior
(:mod:`monovo_cli.core.plane.tracker`). A frame whose estimate fails the divergence checks
is marked ``lost``, carries the constant-velocity prediction (or the feature hypothesis'
pose where the two disagree), and the model is re-anchored on the next good frame
(:class:`OdometryState`). docs/algorithm.md section 4 gives the re-anchoring and loss rules,
section 8 the capture, bridging and re-initialisation.

The ground model itself is built by :mod:`monovo_cli.core.keyframe`; the settings are
:class:`~monovo_cli.core.options.TrackOptions`.

Long module: one state machine (prediction, capture, acceptance with the terrain grid and the
keyframe plane, re-anchoring, loss, re-initialisation) over one mutable state; its parts
already live in their own modules (recovery.bridge, plane.tracker, estimator.terrain_grid,
plane.motion_covariance), and splitting the loop itself would pass that state around.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from enum import Enum
from functools import partial

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, coarse_search, estimate_motion
from monovo_cli.core.estimator.robust import inlier_fraction
from monovo_cli.core.estimator.split import SPLIT_POINTS, SPLIT_POINTS_REANCHOR, split_half_fits
from monovo_cli.core.estimator.terrain_grid import (
    TerrainGrid,
    refine_pose_and_terrain_grid,
    transfer_terrain_grid,
)
from monovo_cli.core.keyframe import Keyframe, build_keyframe, footprint
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.core.plane.motion_covariance import MotionCovariance
from monovo_cli.core.plane.tracker import InitialTilt, Mounting, PlaneTracker
from monovo_cli.core.recovery.gap import GapClosure
from monovo_cli.core.recovery.lost_frames import LostFrameRecovery
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import orthonormalize, se3_exp, se3_inv, se3_log, skew, so3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import difference_sigma, estimate_noise_sigma
from monovo_cli.image.pyramid import build_pyramid, extend_pyramid


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


@dataclass(frozen=True)
class GoodFrame:
    """The last frame whose pose the tracker trusts (accepted, or a re-initialisation): its
    ``index``, ``image`` (H, W), ``world_from_cur`` T_0_k and ``cur_from_key`` (4x4, from the
    keyframe it was estimated against). A gap after it is re-solved from it."""

    index: int
    image: np.ndarray
    world_from_cur: np.ndarray
    cur_from_key: np.ndarray


PREDICTION_WINDOW = 30  # accepted frames whose motion changes measure the prediction's error
STANDING_SHARE = 0.2  # a lost frame with no motion seen yet: std of each translation, x distance
STANDING_DEG = 10.0  # ... and of each rotation, deg
CHANCE_SHARE = 0.5  # a fit leaving half the keyframe's intensity variance is no fit
REINIT_NOISE_SHARE = 0.3  # a fresh keyframe needs noise below this share of the contrast
COVER = 4.0  # a row's error is to stay within this many of its std
UNFORESEEN_COVER = 4.0  # a change from the prediction beyond this many std is not foreseen
REFUTED_MSD_RATIO = 2.0  # a fit from the prediction this much worse than the one kept refutes it


class OdometryState(Enum):
    """Where the tracker stands between frames: it decides the next frame's first guess."""

    STARTING = "starting"      # no frame estimated yet: standing still is the prediction, and
    #                            the rotation search gives the first guess
    TRACKING = "tracking"      # the last accepted frame's motion (constant velocity) is the guess
    RECOVERING = "recovering"  # a frame was lost: the rotation search gives the guess, and the
    #                            next accepted frame anchors a new keyframe


class Odometry:
    """Tracks a sequence frame by frame against keyframes (the paper's moved ground model).

    ``camera`` the frames' camera; ``plane`` the ground in camera 0 (init.yaml's, normal from
    the camera to the ground, distance m); ``region`` ``(x0, y0, x1, y1)`` px, the image part
    the ground model covers; ``mask`` (H, W), non-zero where pixels are usable;
    ``first_keyframe`` a ground model built earlier (``monovo init``), else built from frame
    0; ``mounting`` what init.yaml says of the ground besides frame 0's plane
    (:class:`~monovo_cli.core.plane.tracker.Mounting`; None: frame 0's plane exact, the mean
    mount latent, the prior's width the defaults).
    Call :meth:`start` with frame 0, then :meth:`step` (or :meth:`skip`) per frame, or
    :meth:`advance` with every frame.
    """

    def __init__(self, camera: PinholeCamera, plane: Plane, region: tuple[int, int, int, int],
                 options: TrackOptions | None = None, *, mask: np.ndarray | None = None,
                 first_keyframe: Keyframe | None = None,
                 mounting: Mounting | None = None) -> None:
        self.camera = camera
        self.region = region
        self.options = options or TrackOptions()
        self.mask = mask
        self._plane0 = plane
        self._plane = PlaneTracker(plane, mounting,
                                   keep_initial_tilt=self.options.keep_initial_tilt)
        self._key: Keyframe | None = first_keyframe
        self._world_from_prev = np.eye(4)
        self._cur_from_key_prev = np.eye(4)
        self._motion_cov = MotionCovariance()  # the reported covariance's previous frame
        self._velocity = np.eye(4)  # cur_from_prev of the last accepted frame (none: standing)
        self._state = OdometryState.STARTING
        self._gain, self._bias = 1.0, 0.0
        self._recent_msd: deque[float] = deque(maxlen=15)  # accepted frames' robust msd
        self._sigma = 1.0  # noise sigma of the current frame's differences (difference_sigma)
        self._chance_msd = np.inf  # msd of unrelated images (see step)
        self._prev_image: np.ndarray | None = None
        self._key_image: np.ndarray | None = None  # the keyframe's image (plane test)
        # the keyframe the last step left, with the terrain grid it measured (terrain products)
        self.rebuilt_keyframes: list[Keyframe] = []
        self._recovery = LostFrameRecovery(camera, options=self.options.features, mask=mask,
                                  region=region)  # the feature hypothesis
        self._key_msd: float | None = None  # msd of the first frame fitted to the keyframe
        self._lost_run = 0  # frames lost in a row
        # the prediction's uncertainty (lost rows): the accepted motions' changes from one
        # frame to the next, (tx, ty, tz, rx, ry, rz) m and rad, and the last accepted motion
        self._motion_changes: deque[np.ndarray] = deque(maxlen=PREDICTION_WINDOW)
        self._last_motion: np.ndarray | None = None
        self._last_std, self._last_accepted = np.zeros(6), -2
        # the variance the lost frames since the last accepted one left in the previous pose
        self._gap_variance = np.zeros(6)
        self._gap_steps: list[np.ndarray] = []  # their predicted motions' variances (6,)
        #: (6, 6) the model error the last re-anchor measured on its own row (its terrain
        #: grid's correction, its split halves' spread), for the first motion against the
        #: keyframe it anchored (None: nothing handed over)
        self._handed_over: np.ndarray | None = None
        self._good: GoodFrame | None = None
        self._started = False
        self._announced: Keyframe | None = None  # the keyframe :meth:`advance` last reported

    @property
    def keyframe(self) -> Keyframe | None:
        """The current keyframe (None before :meth:`start`)."""
        return self._key

    @property
    def _predicted(self) -> np.ndarray:
        """The constant velocity's ``cur_from_key`` (4x4) for the frame after the last one
        recorded (accepted or lost)."""
        return orthonormalize(self._velocity @ self._cur_from_key_prev)

    @property
    def initial_tilt(self) -> InitialTilt | None:
        """The images' verdict on init.yaml's tilt, once measured on the first frames."""
        return self._plane.initial_tilt

    @property
    def ground_planar(self) -> bool:
        """The ground seen so far is a plane (:attr:`PlaneTracker.ground_planar`): hindsight
        may re-read motions against the tilts it solves."""
        return self._plane.ground_planar

    @property
    def state(self) -> OdometryState:
        """Where the tracker stands between frames (:class:`OdometryState`)."""
        return self._state

    def start(self, index: int, timestamp: float, image: np.ndarray) -> FrameResult:
        """Frame 0: the identity pose; builds the first ground model unless one was given."""
        if self._key is None:
            self._key = build_keyframe(index, image, self.camera, self._plane0, self.region,
                                       np.eye(4), self.options, mask=self.mask)
        self._prev_image = self._key_image = image
        self._recovery.anchored(image)
        self._good = GoodFrame(index, image, np.eye(4), se3_inv(self._key.world_from_key))
        n = len(self._key.levels[0].points)
        return FrameResult(index, timestamp, np.eye(4), np.eye(4), 0.0, 0, n, FrameStatus.OK,
                           np.zeros(6), np.zeros((6, 6)), keyframe=self._key.index)

    def advance(self, index: int, timestamp: float, image: np.ndarray | None,
                prior_motion: np.ndarray | None = None) -> tuple[FrameResult, list[Keyframe]]:
        """The next frame of the sequence: :meth:`start` for the first, :meth:`skip` when
        ``image`` is None, else :meth:`step` (with ``prior_motion``). Returns its result and
        the keyframes it anchored or rebuilt in place, the rebuilt ones first.

        The whole state lives in this object, so a copy of it taken between two frames
        (the checkpoint's, :mod:`monovo_cli.io.checkpoint`) continues the sequence exactly as
        this one would.
        """
        if not self._started:
            res = self.start(index, timestamp, image)
            self._started = True
        elif image is None:
            res = self.skip(index, timestamp)
        else:
            res = self.step(index, timestamp, image, prior_motion)
        keys = list(self.rebuilt_keyframes)  # (rebuilt in place: the points at their terrain grid)
        if self._key is not self._announced:
            keys.append(self._key)
            self._announced = self._key
        return res, keys

    # -- one frame --------------------------------------------------------------------
    def step(self, index: int, timestamp: float, image: np.ndarray,
             prior_motion: np.ndarray | None = None) -> FrameResult:
        """Estimate frame ``index`` (``image`` (H, W) float32 grey levels, ``timestamp`` s):
        its :class:`FrameResult`, status OK, REANCHORED, REINIT or LOST (with the reason).

        ``prior_motion`` (4x4, T_{k-1}_k, e.g. from wheel odometry) replaces the constant
        velocity as the initial guess.
        """
        key = self._key
        assert key is not None, "call start() first"
        self.rebuilt_keyframes.clear()
        if self._prev_image is not None and image.shape == self._prev_image.shape and \
                np.array_equal(image, self._prev_image):
            return self._lost(index, timestamp, "duplicate of the previous frame")
        self._prev_image = image
        if _constant_or_invalid(image):
            return self._lost(index, timestamp, "constant or invalid image")
        pyr = build_pyramid(image, len(key.levels))
        self._sigma = difference_sigma(key.noise_sigma, image)
        # what unrelated images would give (the brightness fit free): the keyframe points'
        # intensity variance
        self._chance_msd = key.levels[0].intensity_variance
        est, reason = None, ""
        guess = self._cur_from_key_prev
        predicted = prior_motion is not None or self._state is OdometryState.TRACKING
        if predicted:
            motion = se3_inv(prior_motion) if prior_motion is not None else self._velocity
            guess = motion @ guess
        # A prediction starts the estimator at pyramid level predicted_top_level; a standing
        # start tries "no motion yet" from the top (the capture search, 0.1 s, runs only if
        # that fails the checks); a recovering tracker trusts no start but the capture's.
        if predicted or self._state is OdometryState.STARTING:
            est = estimate_motion(key.levels, pyr, guess, options=self.options.estimator,
                                  gain=self._gain, bias=self._bias,
                                  first_level=self.options.predicted_top_level if predicted else None)
            reason = self._failure(est, key)
        captured = est is None or bool(reason)
        from_prediction = est if predicted else None  # (its fit, failing or not)
        if captured:
            est, reason = self._capture(index, key, image, pyr, guess, est, reason)
        if not reason:
            reason = self._step_too_large(orthonormalize(est.cur_from_key))
        if reason:
            if self._lost_run >= self.options.reinit_after and self._looks_usable(image):
                return self._reinit(index, timestamp, image, pyr, reason)
            return self._lost(index, timestamp, reason, est)
        if self._lost_run and self._good is not None and self._good.index != key.index:
            # the first frame after lost frames, captured against the keyframe: measured from
            # the last good frame instead where that sees it on more than twice the points
            # (the keyframe's view can be a turn and two steps away, its fit on the little
            # left in view biased by the change of view)
            closer = self._resolve_gap(index, image, pyr)
            if closer is not None and closer[1].points > 2 * est.points:
                return self._reinit(index, timestamp, image, pyr, "", resolved=closer)
        return self._accept(index, timestamp, image, pyr, est, captured=captured,
                            refuted=_refuted(from_prediction, est, captured))

    def _capture(self, index: int, key: Keyframe, image: np.ndarray, pyr: list[np.ndarray],
                 guess: np.ndarray, est: Estimate | None, reason: str, *,
                 predicted: np.ndarray | None = None,
                 recovery: LostFrameRecovery | None = None,
                 brightness: tuple[float, float] | None = None) -> tuple[Estimate, str]:
        """The capture range beyond the prediction: the rotation search around ``guess`` and
        the feature hypothesis each start the estimator from the top level, and while no
        estimate passes the checks, the finer feature hypothesis
        (``TrackOptions.fine_features``), then the same matched in the reference's view
        warped by the prediction (:mod:`monovo_cli.core.recovery.predicted_view`), then the
        finer one's settings at full resolution (frames larger than its level); the
        estimate that passes the checks with the most inliers is kept (``est``, failing
        with ``reason``, competes too).

        ``predicted`` the predicted ``cur_from_key`` (None: the constant velocity's),
        ``recovery`` whose reference the features are matched against (None: the tracker's),
        ``brightness`` the starting gain and bias (None: the last accepted frame's)."""
        gain, bias = (self._gain, self._bias) if brightness is None else brightness
        recovery = recovery or self._recovery
        if predicted is None:
            predicted = self._predicted
        starts = [lambda: self._search(key, pyr, guess, gain, bias)]
        if self.options.feature_hypothesis:
            starts += [partial(recovery.hypothesis, index, image, key.plane)]
            fine = self.options.fine_features
            if fine is not None:  # only while nothing before passed
                starts += [partial(recovery.hypothesis, index, image, key.plane, options=fine),
                           partial(recovery.hypothesis, index, image, key.plane, options=fine,
                                   predicted=predicted)]
                full = replace(fine, level=0)  # last, frames larger than fine's: full resolution
                if full.level_for(self.camera) != fine.level_for(self.camera):
                    starts += [partial(recovery.hypothesis, index, image, key.plane, options=full)]
        for i, start in enumerate(starts):
            if i >= 2 and not reason:
                break
            begin = start()
            if begin is None:
                continue
            cand = estimate_motion(key.levels, pyr, begin, options=self.options.estimator,
                                   gain=gain, bias=bias)
            why = self._failure(cand, key)
            if est is None or (not why, self._score(cand)) > (not reason, self._score(est)):
                est, reason = cand, why
        return est, reason

    def skip(self, index: int, timestamp: float) -> FrameResult:
        """Frame ``index`` has no usable image: record it as lost at the prediction."""
        return self._lost(index, timestamp, "unreadable frame")

    # -- outcomes ---------------------------------------------------------------------
    def _accept(self, index: int, timestamp: float, image: np.ndarray, pyr: list[np.ndarray],
                est: Estimate, *, captured: bool = False, refuted: bool = False) -> FrameResult:
        """Record ``est`` (``captured``: it came from the capture's starts, not from the
        prediction; ``refuted``: the images refuted the prediction, :func:`_refuted`). A
        captured frame's, and a re-anchoring frame's, split-half spread joins its covariance
        (``_split_spread``); a motion the prediction did not foresee widens it
        (:meth:`_unforeseen`) unless the prediction was refuted."""
        closing = None  # the lost frames before this one: what the prediction would say here
        if self._lost_run and self._good is not None:
            predicted = self._predicted
            last = self._prediction_std(np.zeros(6), self._lost_run + 1)
            closing = (orthonormalize(self._key.world_from_key @ se3_inv(predicted)),
                       np.array(self._gap_steps + [last ** 2]))
        if self._plane.wants_test(self._key, index):
            est = self._settle_plane(index, pyr, est)
        key = self._key
        status = FrameStatus.OK
        recovering = self._state is OdometryState.RECOVERING
        reanchor = recovering or self._needs_reanchor(est, key, orthonormalize(est.cur_from_key))
        # a frame the prediction did not reach, or one far enough from the keyframe to anchor
        # the next: the change of view is largest there, and so is the plane model's error
        spread = self._split_spread(key, pyr, est, SPLIT_POINTS if captured else SPLIT_POINTS_REANCHOR) \
            if captured or reanchor else []
        terrain_grid, tracked = None, est
        if reanchor and key.index != index and self.options.terrain_grid:
            est, terrain_grid, lifted = refine_pose_and_terrain_grid(key.levels[0], key.plane, pyr[0], est,
                                                         self.options.estimator, start=key.terrain_grid)
            if lifted is None:
                terrain_grid = None
            else:  # the keyframe's finest points at the heights found
                self.rebuilt_keyframes.append(replace(key, levels=(lifted,) + key.levels[1:],
                                                      terrain_grid=terrain_grid))
        cur_from_key = orthonormalize(est.cur_from_key)
        gain, bias = est.gain, est.bias
        plane_cur, plane_cov, link = key.plane.in_frame(cur_from_key), None, None
        if reanchor and key.index != index:
            # The next keyframe's plane (in this camera); the pose keeps the fixed-plane
            # estimate, whose error is smaller (the free normal adds variance to the joint
            # solution's motion).
            plane_cur, plane_cov, gain, bias, link = self._plane.successor(
                key, pyr[0], est, cur_from_key, gain, bias, self.options.estimator,
                self._motion_cov.sensitivity(est, key.levels[0], key.plane))
            if recovering and plane_cov is not None:
                plane_cov = self._plane.loosened(plane_cov)
        world_from_cur = orthonormalize(key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(self._world_from_prev) @ world_from_cur)
        cov = self._motion_cov.relative(est, key.levels[0], key.plane,
                                        self._plane.reported_covariance,
                                        self._cur_from_key_prev, prev_from_cur)
        model = np.zeros((6, 6))
        if terrain_grid is not None:  # the correction the terrain grid made is this motion's model error
            jump = _motion_change(prev_from_cur, self._motion_to(key, orthonormalize(tracked.cur_from_key)))
            model += np.outer(jump, jump)
        for half, _ in spread:  # a captured frame's model error, as its halves disagree
            model += np.outer(half, half)
        if self._handed_over is not None and not reanchor:
            # The first motion against a keyframe: its points sit on the plane (or the grid)
            # the re-anchor fitted, with that fit's model error, and over one frame's
            # baseline the robust weights do not yet set the unmodelled relief apart (on
            # rocks: 2.5-2.8 mdeg off on 5 cm, 6-8.5 std, where the rows after it are within
            # 2). It carries the error its re-anchor measured on its own row. A row that
            # re-anchors in turn states its own (counting both made a MER drive's std, which
            # re-anchors on nearly every frame, 1.4-1.9x wider still).
            cov = cov + self._handed_over
        self._handed_over = None
        cov = cov + model
        if self._gap_variance.any():  # the previous pose was only predicted: its error is ours
            cov = cov + _from_predicted(self._gap_variance, prev_from_cur)
            self._gap_variance = np.zeros(6)
        motion = _motion_change(prev_from_cur, np.eye(4))
        if not refuted:
            cov = cov + np.diag(self._unforeseen(motion, np.sqrt(np.clip(np.diag(cov), 0.0, None)),
                                                 index))
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        if self._last_motion is not None and self._last_accepted == index - 1:
            self._motion_changes.append(np.abs(motion - self._last_motion))
        self._last_motion, self._last_std, self._last_accepted = motion, std, index
        self._velocity = se3_inv(prev_from_cur)
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        self._gain, self._bias = gain, bias
        self._recent_msd.append(_robust_msd(est))
        self._lost_run, self._gap_steps = 0, []
        gap = None if closing is None else GapClosure(self._good.index, *closing)
        self._good = GoodFrame(index, image, world_from_cur, cur_from_key)
        if self._key_msd is None:
            self._key_msd = _robust_msd(est)
        if reanchor and self._reanchor(index, image, pyr, world_from_cur, plane_cur, plane_cov,
                                       None if terrain_grid is None else (terrain_grid, cur_from_key), link):
            status = FrameStatus.REANCHORED
            self._plane.anchored_captured(plane_cur, [w for _, w in spread])
            self._handed_over = model if model.any() else None
        elif not recovering:  # (a recovering tracker whose new keyframe failed stays so)
            self._state = OdometryState.TRACKING
        return FrameResult(index, timestamp, world_from_cur, prev_from_cur, est.msd,
                           est.iterations, est.points, status, std, cov, self._key.index,
                           est.gain, est.bias, gap=gap)

    def _lost(self, index: int, timestamp: float, reason: str,
              est: Estimate | None = None) -> FrameResult:
        """The prediction, or the feature hypothesis where it contradicts it
        (:mod:`monovo_cli.core.recovery.lost_frames`)."""
        predicted = self._predicted
        cur_from_key = self._recovery.lost_pose(index, predicted)
        world_from_cur = orthonormalize(self._key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(self._world_from_prev) @ world_from_cur)
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        self._state = OdometryState.RECOVERING
        self._lost_run += 1
        std = self._prediction_std(_motion_change(cur_from_key, predicted))
        self._gap_variance = self._gap_variance + std ** 2
        self._gap_steps.append(std ** 2)
        msd = est.msd if est is not None and np.isfinite(est.msd) else 0.0
        its = est.iterations if est is not None else 0
        pts = est.points if est is not None else 0
        return FrameResult(index, timestamp, world_from_cur, prev_from_cur, msd, its, pts,
                           FrameStatus.LOST, std, np.diag(std ** 2), self._key.index,
                           self._gain, self._bias, reason)

    def _prediction_std(self, bridged: np.ndarray, lost_run: int | None = None) -> np.ndarray:
        """(6,) m and rad: the std of a lost frame's motion, the prediction's uncertainty.

        The prediction repeats the last accepted motion, so its error is the change of the
        motion since: per axis the larger of the RMS and the largest of the recent accepted
        frames' changes (PREDICTION_WINDOW of them), grown as a random walk with the frames
        lost in a row, added to the last accepted motion's own std. Without such a history
        (the first frames) the motion itself, or at a standing start a fraction of the
        ground's distance and STANDING_DEG, stands for it. ``bridged`` (6,): how far the pose
        taken (the feature hypothesis') is from the prediction, added as a further error;
        ``lost_run`` the frames lost in a row, this one included (None: as counted).
        """
        if len(self._motion_changes) >= 3:
            changes = np.array(self._motion_changes)
            step = np.maximum(np.sqrt(np.mean(changes ** 2, axis=0)), changes.max(axis=0))
        elif self._last_motion is not None:
            step = np.abs(self._last_motion)
        else:
            d = self._key.plane.distance
            step = np.r_[np.full(3, STANDING_SHARE * d), np.full(3, np.radians(STANDING_DEG))]
        spread = step * np.sqrt(self._lost_run if lost_run is None else lost_run)
        return np.sqrt(spread ** 2 + self._last_std ** 2 + bridged ** 2)

    def _unforeseen(self, motion: np.ndarray, std: np.ndarray, index: int) -> np.ndarray:
        """(6,) the variance (m^2, rad^2) an accepted frame's motion must add for a change the
        prediction did not foresee: zeros unless its motion ``motion`` (6,: t m, rotation
        vector rad) differs from the previous frame's by more than UNFORESEEN_COVER times
        the two uncertainties, its own ``std`` (6,) and the prediction's (what a lost row
        would have stated here), on some axis; then ``(change / COVER)^2`` on every axis.

        The fit passed every check, so either the motion changed (a rover stopping to turn,
        a hand-held jerk: the estimate is right) or the fit found a wrong minimum that
        explains the images as well (the prediction was right). The images cannot tell the
        two apart, and a row marked lost would hold the prediction, wrong in the first case;
        so the estimate is kept and its std made to cover the prediction within COVER std.
        """
        if self._last_motion is None or self._last_accepted != index - 1:
            return np.zeros(6)
        change = motion - self._last_motion
        expected = np.sqrt(std ** 2 + self._prediction_std(np.zeros(6), 1) ** 2)
        if np.all(np.abs(change) <= UNFORESEEN_COVER * expected):
            return np.zeros(6)
        return (change / COVER) ** 2

    # -- checks -----------------------------------------------------------------------
    def _search(self, key: Keyframe, pyr: list[np.ndarray], guess: np.ndarray,
                gain: float, bias: float) -> np.ndarray:
        top = len(key.levels) - 1  # (a pyramid built for another keyframe may differ in length)
        return coarse_search(key.levels[top], extend_pyramid(pyr, top + 1)[top], guess,
                             options=self.options.estimator,
                             noise_sigma=self._sigma, gain=gain, bias=bias)

    def _score(self, est: Estimate) -> float:
        """Share of the in-view points that agree with the estimate within the noise."""
        if est.residuals is None:
            return 0.0
        return inlier_fraction(est.residuals, est.valid, self._sigma) / max(est.valid_fraction, 1e-9)

    def _failure(self, est: Estimate, key: Keyframe) -> str:
        """Why ``est`` cannot be trusted, or '' (the divergence checks)."""
        if not est.converged or not np.all(np.isfinite(est.cur_from_key)):
            return "too few observation points in view"
        if not np.all(np.isfinite(est.covariance)) or est.condition > self.options.max_condition:
            return "ill-conditioned normal equations"
        if self._score(est) < self.options.min_inliers:
            return "intensity differences do not fit the motion"
        if est.msd > CHANCE_SHARE * self._chance_msd:
            return "intensity differences no better than chance"
        # The fit of the bulk of the points (the robust msd: a region the robust weights reject,
        # a reflection, a hand, does not count) against the recent good frames' (but at least
        # the two images' noise): far above both, it does not hold. Before there are any the
        # check does not apply: on real images the plane model's own error (lens, parallax,
        # lighting) can exceed the noise many times over from frame 1 on.
        if self._recent_msd:
            noise = 2.0 * self._sigma ** 2
            baseline = max(float(np.median(self._recent_msd)), noise, 1.0)
            if _robust_msd(est) > self.options.msd_factor * baseline:
                return "robust mean squared difference rose sharply"
        if est.finest_iterations >= self.options.estimator.max_iterations:
            return "no convergence within the iteration cap"
        return ""

    def _step_too_large(self, cur_from_key: np.ndarray) -> str:
        o = self.options
        if o.max_step_m is None and o.max_step_deg is None:
            return ""
        world_from_cur = self._key.world_from_key @ se3_inv(cur_from_key)
        step = se3_inv(self._world_from_prev) @ world_from_cur
        if o.max_step_m is not None and np.linalg.norm(step[:3, 3]) > o.max_step_m:
            return f"step beyond the maximum step {o.max_step_m} m"
        if o.max_step_deg is not None and \
                np.degrees(np.linalg.norm(so3_log(step[:3, :3]))) > o.max_step_deg:
            return f"step beyond the maximum step {o.max_step_deg} deg"
        return ""

    def _needs_reanchor(self, est: Estimate, key: Keyframe, cur_from_key: np.ndarray) -> bool:
        """Points leaving the view, the model leaving the image, or the fit degrading."""
        corners_cur = key.corners @ cur_from_key[:3, :3].T + cur_from_key[:3, 3]
        degraded = self._key_msd is not None and \
            _robust_msd(est) > self.options.reanchor_msd_ratio * max(self._key_msd, 1.0)
        return (degraded or est.valid_fraction < self.options.reanchor_fraction
                or footprint(self.camera, corners_cur) < self.options.min_footprint)

    def _settle_plane(self, index: int, pyr: list[np.ndarray], est: Estimate) -> Estimate:
        """PlaneTracker.test; a corrected plane's keyframe is kept if its estimate passes, from
        the top level if level 2's fails (``est``, fitted over the old plane, can be far off)."""
        found = self._plane.test(index, self._key, self._key_image, pyr, est, self.camera,
                                 self.region, self.options, self.mask)
        if found is None:
            return est
        key, new, cov = found
        if self._failure(new, key):
            new = estimate_motion(key.levels, pyr, est.cur_from_key, options=self.options.estimator,
                                  gain=est.gain, bias=est.bias)
            if self._failure(new, key):
                return est
        self._key, self._plane.covariance = key, cov
        return new

    def _reanchor(self, index: int, image: np.ndarray, pyr: list[np.ndarray],
                  world_from_cur: np.ndarray, plane: Plane, cov: np.ndarray | None = None,
                  terrain_grid: tuple[TerrainGrid, np.ndarray] | None = None,
                  link: PlaneLink | None = None) -> bool:
        """Anchor a new ground model on this frame (``plane`` in its camera, ``cov`` its
        covariance, None: the prior's; ``terrain_grid``: the old keyframe's terrain grid and this frame's
        pose from it, carried onto the new points; ``link``: the plane's link to the old
        keyframe's, for smoothing); False if the frame cannot carry one."""
        surface = None if terrain_grid is None else partial(transfer_terrain_grid, *terrain_grid, plane)
        try:
            key = build_keyframe(index, image, self.camera, plane, self.region,
                                 world_from_cur, self.options, mask=self.mask, pyramid=pyr,
                                 surface=surface)
        except TrackingError:
            return False
        self._key = replace(key, link=link)
        self._plane.anchored(cov)
        self._cur_from_key_prev = np.eye(4)
        self._motion_cov.anchored()
        self._gain, self._bias = 1.0, 0.0
        self._state = OdometryState.TRACKING
        self._key_image, self._key_msd = image, None
        self._recovery.anchored(image)
        return True

    def _split_spread(self, key: Keyframe, pyr: list[np.ndarray], est: Estimate,
                      max_points: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per split of ``est``'s points whose halves both converged
        (:func:`~monovo_cli.core.estimator.split.split_half_fits`), the difference between
        the halves' motions (6,) (m, rad; as motion.csv's) and between their rotations in
        the current camera (3,) (rad): the model error of a frame captured across a wide
        change of view, which the noise-only covariance does not count. The whole
        difference, not half of it: that error is shared by the halves, not averaged away."""
        out = []
        for a, b in split_half_fits(key.levels[0], pyr[0], est, self.options.estimator, max_points):
            a, b = orthonormalize(a), orthonormalize(b)
            out.append((_motion_change(self._motion_to(key, a), self._motion_to(key, b)),
                        so3_log(a[:3, :3] @ b[:3, :3].T)))
        return out

    def _motion_to(self, key: Keyframe, cur_from_key: np.ndarray) -> np.ndarray:
        """The motion (4x4, T_{k-1}_k) from the previous pose to the pose ``cur_from_key``
        (4x4, orthonormal) against ``key``: an alternative fit's, beside the frame's own."""
        return se3_inv(self._world_from_prev) @ key.world_from_key @ se3_inv(cur_from_key)

    def _carried_plane(self, key: Keyframe, cur_from_key: np.ndarray,
                       twist: np.ndarray | None = None, sensitivity: np.ndarray | None = None
                       ) -> tuple[Plane, np.ndarray | None]:
        """The ground of a fresh keyframe at ``cur_from_key`` (4x4, from ``key``) and its chart
        covariance: the MAP of ``key``'s plane carried there and the mounting prior.
        ``twist`` (6, 6) the covariance of the pose (None: a predicted one, the variance the
        lost frames' predictions left, ``_gap_variance``, taken on every axis), ``sensitivity``
        that of a pose estimated against ``key``'s plane (``carrying_jacobian``). After a few
        lost frames the prediction's tilt is worth less than the mounting's, and a fresh
        keyframe on a plane tilted by the prediction's error fits nothing. The carried plane
        alone (covariance None) where they cannot be fused."""
        if twist is None:
            gap = self._gap_variance
            twist = np.diag(np.r_[np.full(3, gap[:3].max()), np.full(3, gap[3:].max())])
        return self._plane.carried(key.plane, cur_from_key, twist, sensitivity)

    def _resolve_gap(self, index: int, image: np.ndarray, pyr: list[np.ndarray]
                     ) -> tuple[Keyframe, Estimate] | None:
        """Frame ``index`` (``image``, ``pyr``) measured directly from the last good frame
        before the lost ones: against the keyframe if that frame is the keyframe, else
        against a keyframe built on it (closer than the old one), starting from the
        prediction, then with the capture's starts, its features matched against the last
        good frame's image. ``(the keyframe, the estimate)`` if one passes the checks, else
        None. Called before the frame is recorded lost (the prediction is still the next)."""
        good, key = self._good, self._key
        if good is None or not self.options.resolve_gaps:
            return None
        predicted = self._predicted
        ref, gain, bias = key, self._gain, self._bias
        if good.index != key.index:
            try:
                ref = build_keyframe(good.index, good.image, self.camera,
                                     key.plane.in_frame(good.cur_from_key), self.region,
                                     good.world_from_cur, self.options, mask=self.mask)
            except TrackingError:
                return None
            predicted = orthonormalize(predicted @ se3_inv(good.cur_from_key))
            gain, bias = 1.0, 0.0
        recovery = LostFrameRecovery(self.camera, options=self.options.features, mask=self.mask,
                                     region=self.region)
        recovery.anchored(good.image)
        chance, self._chance_msd = self._chance_msd, ref.levels[0].intensity_variance
        try:
            est = estimate_motion(ref.levels, pyr, predicted, options=self.options.estimator,
                                  gain=gain, bias=bias)
            reason = self._failure(est, ref)
            if reason:
                est, reason = self._capture(index, ref, image, pyr, predicted, est, reason,
                                            predicted=predicted, recovery=recovery,
                                            brightness=(gain, bias))
        finally:
            self._chance_msd = chance
        return None if reason else (ref, est)

    @staticmethod
    def _looks_usable(image: np.ndarray) -> bool:
        """Whether a frame may carry a fresh keyframe: its noise well below its contrast (a
        frame of pure noise, or a blank one, may not)."""
        contrast = float(image.std())
        return contrast > 1e-3 and estimate_noise_sigma(image) < REINIT_NOISE_SHARE * contrast

    def _reinit(self, index: int, timestamp: float, image: np.ndarray, pyr: list[np.ndarray],
                reason: str, resolved: tuple[Keyframe, Estimate] | None = None) -> FrameResult:
        """Frames stay lost: anchor a fresh keyframe on this one at the predicted pose.

        The plane is the current keyframe's carried to the prediction fused with the mounting
        prior (:meth:`_carried_plane`), or the mount's plane (relative to the camera) when
        that one does not meet the region's rays in front of the camera; the gap since the
        last good frame is bridged by the prediction. A frame that cannot carry a keyframe
        stays lost. ``resolved`` the gap already re-solved (:meth:`_resolve_gap`; None: try
        it here), ``reason`` why the frame was not tracked ("" for a frame that was, but
        is measured better from the last good frame)."""
        lost_for, good = self._lost_run, self._good
        gap_before, world_from_prev = self._gap_variance.copy(), self._world_from_prev
        if resolved is None:
            resolved = self._resolve_gap(index, image, pyr)
        res = self._lost(index, timestamp, reason or "no keyframe could be anchored on it")
        variances = np.array(self._gap_steps)  # (this frame's predicted motion is the last)
        world_from_cur, planes = res.world_from_cam, [self._carried_plane(self._key,
                                                                          self._cur_from_key_prev)]
        if resolved is not None:
            ref, est = resolved
            cur_from_ref = orthonormalize(est.cur_from_key)
            world_from_cur = orthonormalize(ref.world_from_key @ se3_inv(cur_from_ref))
            motion_cov = self._motion_cov if ref is self._key else MotionCovariance()
            planes = [self._carried_plane(ref, cur_from_ref, est.covariance,
                                          motion_cov.sensitivity(est, ref.levels[0], ref.plane))]
            # the motion from the last good frame and its covariance, before the keyframe
            # changes (the motion covariance's previous frame is the last good one)
            good_from_cur = orthonormalize(se3_inv(good.world_from_cur) @ world_from_cur)
            cov = motion_cov.relative(est, ref.levels[0], ref.plane,
                                      self._plane.reported_covariance,
                                      good.cur_from_key if ref is self._key else np.eye(4),
                                      good_from_cur)
        for plane, plane_cov in planes + [(self._plane.mount_plane, None)]:
            if plane_cov is not None:  # a frame after lost frames: its tilt is measured again
                plane_cov = self._plane.loosened(plane_cov)
            if self._reanchor(index, image, pyr, world_from_cur, plane, plane_cov):
                self._lost_run, self._gap_steps = 0, []
                self._gap_variance = np.zeros(6)  # the next motions are from this keyframe
                self._handed_over = None  # (a re-initialised keyframe measured no model error)
                self._recent_msd.clear()  # a fresh start: no msd history yet
                self._world_from_prev = world_from_cur
                self._good = GoodFrame(index, image, world_from_cur, np.eye(4))
                words = f"re-initialised after {lost_for} lost frames" + (f" ({reason})" if reason else "")
                if resolved is None:
                    return replace(res, status=FrameStatus.REINIT, keyframe=self._key.index,
                                   reason=words)
                # the row: from the last lost frame's predicted pose to the re-solved one, its
                # covariance the re-solved motion's plus what the lost frames left
                cov = cov + _from_predicted(
                    gap_before, orthonormalize(se3_inv(world_from_prev) @ world_from_cur))
                # the gap's mean motion per frame is the next prediction
                self._velocity = se3_exp(-se3_log(good_from_cur) / (index - good.index))
                return replace(
                    res, status=FrameStatus.REINIT, keyframe=self._key.index,
                    world_from_cam=world_from_cur,
                    prev_from_cur=orthonormalize(se3_inv(world_from_prev) @ world_from_cur),
                    msd=est.msd, iterations=est.iterations, points=est.points,
                    std=np.sqrt(np.clip(np.diag(cov), 0.0, None)), covariance=cov,
                    gain=est.gain, bias=est.bias,
                    reason=f"{words}; the gap re-solved from frame {good.index}",
                    gap=GapClosure(good.index, res.world_from_cam, variances))
        return res


def _refuted(from_prediction: Estimate | None, est: Estimate, captured: bool) -> bool:
    """Whether the images refute the constant-velocity prediction as the frame's motion, so a
    change from it needs no wider std: the estimator started at the prediction
    (``from_prediction``, None: it did not) and either converged to ``est`` itself (not
    ``captured``: the prediction is not a minimum of the fit, or it would have stayed there),
    or its fit is worse than the captured ``est``'s by more than REFUTED_MSD_RATIO (robust
    msd: a turn in place predicted as a step fits near chance)."""
    if from_prediction is None:
        return False
    if not captured:
        return True
    if not from_prediction.converged or not np.isfinite(from_prediction.msd):
        return True
    return _robust_msd(from_prediction) > REFUTED_MSD_RATIO * _robust_msd(est)


def _from_predicted(variance: np.ndarray, prev_from_cur: np.ndarray) -> np.ndarray:
    """(6, 6) what a previous pose known only to ``variance`` (6,: m^2, rad^2, in its own
    frame; the lost frames' predictions) adds to the covariance of the motion ``prev_from_cur``
    (4x4) measured from it: with that pose off by ``(v, w)``, the motion is off by
    ``(-v + t x w, -w)``, so its rotation's doubt reaches the translation by the lever ``t``
    (after a turn predicted where the rover drove, a 0.7 m step is 0.2 m off sideways)."""
    t = prev_from_cur[:3, 3]
    J = np.zeros((6, 6))
    J[:3, :3] = -np.eye(3)
    J[:3, 3:] = skew(t)
    J[3:, 3:] = -np.eye(3)
    return (J * variance) @ J.T


def _motion_change(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(6,) (m, rad): motion ``a`` (4x4) less motion ``b`` in (tx, ty, tz, rx, ry, rz), the
    rotation as the rotation vector of ``a_R b_R^T``."""
    return np.concatenate([a[:3, 3] - b[:3, 3], so3_log(a[:3, :3] @ b[:3, :3].T)])


def _constant_or_invalid(image: np.ndarray) -> bool:
    """``image`` holds a NaN or an infinity, or its std is below 1e-3 grey levels. Its extremes
    say so in one pass (NaN and infinities show in them); the std, a fifth as fast, is taken
    only where they allow it to be that small (a std is at least the range / sqrt(2 N))."""
    lo, hi = float(image.min()), float(image.max())
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return True
    return hi - lo < 1e-3 * np.sqrt(2.0 * image.size) and float(image.std()) < 1e-3


def estimate_frames(frames: Iterable[tuple[int, float, np.ndarray | None]], camera: PinholeCamera,
                    plane: Plane, region: tuple[int, int, int, int],
                    options: TrackOptions | None = None, *, mask: np.ndarray | None = None,
                    first_keyframe: Keyframe | None = None,
                    priors: Mapping[int, np.ndarray] | None = None,
                    mounting: Mounting | None = None,
                    on_keyframe: Callable[[Keyframe], None] | None = None) -> Iterator[FrameResult]:
    """Yield a :class:`FrameResult` per ``(index, timestamp, image)``, frame 0 first: the
    sequence through :meth:`Odometry.advance`.

    ``image`` (H, W) float32, or None for a frame that could not be read (recorded lost at
    the prediction); frame 0 must have one (it carries the ground model unless
    ``first_keyframe`` is given). ``priors`` maps a frame index to its prior motion
    T_{k-1}_k (4x4); ``mounting`` what init.yaml says of the ground (:class:`Odometry`);
    ``on_keyframe(keyframe)`` is called for every keyframe anchored (or rebuilt in place).
    """
    odo = Odometry(camera, plane, region, options, mask=mask, first_keyframe=first_keyframe,
                   mounting=mounting)
    for index, ts, image in frames:
        res, keys = odo.advance(index, ts, image, (priors or {}).get(index))
        if on_keyframe is not None:
            for key in keys:
                on_keyframe(key)
        yield res


def _robust_msd(est: Estimate) -> float:
    """The squared robust scale (MAD) of the frame's final differences (``Estimate.scale``):
    the msd of the bulk of the points, which a region the robust weights reject (a shadow, an
    object) leaves alone; the msd where the estimate has no scale."""
    return est.msd if est.scale is None else est.scale ** 2
