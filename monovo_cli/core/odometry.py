"""The sequence loop: keyframes, pose chaining, re-anchoring, loss detection and recovery.

Owns the state; does no I/O and no printing; one :class:`FrameResult` out per frame in.
Each frame is estimated against the current keyframe (the paper's ground model, moved with
the accumulated motion); a new keyframe is anchored when too few of its points stay in view
or the model covers too little of the image, its plane the MAP of the carried plane, the
two images' normal and init.yaml's mounting (:mod:`monovo_cli.core.plane.tracker`). A
frame failing the divergence checks is ``lost`` at the constant-velocity prediction (or
the feature hypothesis' pose) and the next good frame re-anchors (:class:`OdometryState`).
docs/algorithm.md section 4 gives the rules, section 8 the capture and re-initialisation.

Long module: the coordinator, one state machine over one mutable state (the checkpoint
encodes its attributes as they are). The rules live beside it: the fit's checks and the
capture (:mod:`monovo_cli.core.checks`), the row's std (:mod:`monovo_cli.core.frame_std`),
the motions the images cannot tell apart (:mod:`monovo_cli.core.aliases`), the next
keyframe (:mod:`monovo_cli.core.plane.successor`, :mod:`monovo_cli.core.keyframe`), the
frame measured again after lost frames (:mod:`monovo_cli.core.recovery.reinit`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import replace
from functools import partial

import numpy as np

from monovo_cli.core.aliases import pose_doubt, rivals, unpinned, with_periods
from monovo_cli.core.checks import (
    FitChecks,
    OdometryState,
    constant_or_invalid,
    divergence,
    needs_reanchor,
    off_the_ground,
    step_too_large,
)
from monovo_cli.core.estimator.estimate import Estimate
from monovo_cli.core.estimator.split import SPLIT_POINTS, SPLIT_POINTS_REANCHOR
from monovo_cli.core.estimator.terrain_grid import TerrainGrid, transfer_terrain_grid
from monovo_cli.core.frame_std import (
    PREDICTION_WINDOW,
    FrameResult,
    accepted_covariance,
    lost_row,
    lost_std,
    motion_change,
    prediction_std,
    refuted,
    robust_msd,
    split_spread,
    unforeseen,
)
from monovo_cli.core.keyframe import Keyframe, build_keyframe
from monovo_cli.core.options import TrackOptions
from monovo_cli.core.plane.belief import PlaneLink
from monovo_cli.core.plane.motion_covariance import MotionCovariance
from monovo_cli.core.plane.successor import successor
from monovo_cli.core.plane.tracker import InitialTilt, Mounting, PlaneTracker
from monovo_cli.core.recovery.lost_frames import LostFrameRecovery
from monovo_cli.core.recovery.reinit import (
    GoodFrame,
    fresh_start,
    gap_closure,
    gap_reference,
    looks_usable,
    resolve_gap,
    resolved_row,
)
from monovo_cli.core.status import FrameStatus
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import orthonormalize, se3_exp, se3_inv, se3_log
from monovo_cli.geometry.plane import Plane
from monovo_cli.image.gradients import difference_sigma
from monovo_cli.image.pyramid import build_pyramid


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
        self._plane = PlaneTracker(plane, mounting, keep_initial_tilt=self.options.keep_initial_tilt)
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
        self._lost_run = self._unmeasured = 0  # lost in a row; since a motion was measured
        # the prediction's uncertainty (lost rows): the accepted motions' changes from one
        # frame to the next, (tx, ty, tz, rx, ry, rz) m and rad, and the last accepted motion
        self._motion_changes: deque[np.ndarray] = deque(maxlen=PREDICTION_WINDOW)
        self._last_motion: np.ndarray | None = None
        self._last_std, self._last_accepted = np.zeros(6), -2
        # the previous pose's variance beyond its noise (lost frames since; aliases, rivals)
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
        """The ground so far is a plane (PlaneTracker.ground_planar): hindsight may re-read."""
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
        self._key = with_periods(self._key, image, self.camera)  # (init's model has none)
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
        if constant_or_invalid(image):
            return self._lost(index, timestamp, "constant or invalid image")
        pyr = build_pyramid(image, len(key.levels))
        self._sigma = difference_sigma(key.noise_sigma, image)
        # what unrelated images would give (brightness fit free): the points' intensity variance
        self._chance_msd = key.levels[0].intensity_variance
        guess = self._cur_from_key_prev
        predicted = prior_motion is not None or self._state is OdometryState.TRACKING
        if predicted:
            motion = se3_inv(prior_motion) if prior_motion is not None else self._velocity
            guess = motion @ guess
        # a recovering tracker trusts no start but the capture's
        est, reason, captured, from_prediction = self._checks().fit(
            index, key, image, pyr, guess, predicted, self._state is OdometryState.STARTING,
            prediction=self._predicted, recovery=self._recovery, brightness=(self._gain, self._bias))
        if not reason:
            reason = step_too_large(self._world_from_prev, key, orthonormalize(est.cur_from_key),
                                    self.options)
        if reason:
            if self._lost_run >= self.options.reinit_after and looks_usable(image):
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
        # where no prediction picks the minimum: the others as good (an accepted fit's only)
        widen = self._checks().excess(est, key)  # above 1: beyond its level, and kept
        found = rivals(key, pyr, est, self.options.estimator) if widen > 1.0 \
            or unpinned(self._prior(index), key.plane.distance) else []
        start = partial(self._checks().start_msd, key, pyr, guess, est, self._prior(index))
        return self._accept(index, timestamp, image, pyr, est, captured=captured,
                            refuted=refuted(from_prediction, est, captured, start), rivals=found, widen=widen)

    def skip(self, index: int, timestamp: float) -> FrameResult:
        """Frame ``index`` has no usable image: record it as lost at the prediction."""
        return self._lost(index, timestamp, "unreadable frame")

    def _accept(self, index: int, timestamp: float, image: np.ndarray, pyr: list[np.ndarray],
                est: Estimate, *, captured: bool = False, refuted: bool = False,
                rivals: Sequence[np.ndarray] = (), widen: float = 1.0) -> FrameResult:
        """Record ``est`` (``captured``: it came from the capture's starts, not from the
        prediction; ``refuted``: the images refuted the prediction, :func:`frame_std.refuted`;
        ``rivals``: other minima as good, :func:`aliases.rivals`; ``widen``: :meth:`FitChecks.excess`).
        A captured frame's, and a re-anchoring frame's, split-half spread joins its covariance
        (:func:`frame_std.split_spread`); a motion the prediction did not foresee widens it
        (:meth:`_unforeseen`) unless the prediction was refuted."""
        gap = None  # the lost frames before this one: what the prediction would say here
        if self._lost_run and self._good is not None:
            gap = gap_closure(self._good, self._key, self._predicted, self._gap_steps,
                              self._prediction_std(np.zeros(6), self._unmeasured + 1))
        if self._plane.wants_test(self._key, index):
            est = self._settle_plane(index, pyr, est)
        key = self._key
        status = FrameStatus.OK
        recovering = self._state is OdometryState.RECOVERING
        reanchor = recovering or needs_reanchor(est, key, orthonormalize(est.cur_from_key), self.camera,
                                                self.options, self._key_msd)
        # a frame the prediction did not reach, or one far enough from the keyframe to anchor
        # the next: the change of view is largest there, and so is the plane model's error
        spread = split_spread(key, pyr, est, self.options.estimator,
                              SPLIT_POINTS if captured else SPLIT_POINTS_REANCHOR, self._motion_to) \
            if captured or reanchor else []
        nxt = successor(key, pyr, est, self._plane, self._motion_cov, self.options, recovering,
                        anchoring=reanchor and key.index != index)  # its plane in this camera
        tracked, est, terrain_grid = est, nxt.est, nxt.terrain_grid
        self.rebuilt_keyframes += [] if nxt.rebuilt is None else [nxt.rebuilt]
        cur_from_key = orthonormalize(est.cur_from_key)
        world_from_cur = orthonormalize(key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(self._world_from_prev) @ world_from_cur)
        # the model error: the correction the terrain grid made, the split halves' spread
        jumps = [] if terrain_grid is None else [(motion_change(
            prev_from_cur, self._motion_to(key, orthonormalize(tracked.cur_from_key))), 0.0)]
        cov, model = accepted_covariance(
            self._motion_cov.relative(est, key.levels[0], key.plane, self._plane.reported(key.plane),
                                      self._cur_from_key_prev, prev_from_cur, pyr[0]),
            jumps + [(half, noise) for half, noise, _ in spread], None if reanchor else self._handed_over,
            self._gap_variance, prev_from_cur)
        self._handed_over, self._gap_variance = None, np.zeros(6)
        motion = motion_change(prev_from_cur, np.eye(4))
        if not refuted:
            cov = cov + np.diag(self._unforeseen(motion, np.sqrt(np.clip(np.diag(cov), 0.0, None)), index))
        # the next motion against this keyframe inherits the doubt (a re-anchor's does not)
        doubt = pose_doubt(key, pyr, est, self._prior(index), partial(self._motion_to, key),
                           prev_from_cur, rivals, self.options.estimator)
        cov, self._gap_variance = cov + doubt, np.diag(doubt).copy()
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        if self._last_motion is not None and self._last_accepted == index - 1:
            self._motion_changes.append(np.abs(motion - self._last_motion))
        self._last_motion, self._last_std, self._last_accepted = motion, std, index
        self._velocity = se3_inv(prev_from_cur)
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        self._gain, self._bias = nxt.gain, nxt.bias
        self._recent_msd.append(robust_msd(est))
        self._lost_run, self._unmeasured, self._gap_steps = 0, 0, []
        self._good = GoodFrame(index, image, world_from_cur, cur_from_key)
        if self._key_msd is None:
            self._key_msd = robust_msd(est)
        if reanchor and self._reanchor(index, image, pyr, world_from_cur, nxt.plane, nxt.covariance,
                                       None if terrain_grid is None else (terrain_grid, cur_from_key),
                                       nxt.link):
            status, self._gap_variance = FrameStatus.REANCHORED, np.zeros(6)
            self._plane.anchored_captured(nxt.plane, [w for *_, w in spread])
            self._handed_over = model if model.any() else None
        elif not recovering:  # (a recovering tracker whose new keyframe failed stays so)
            self._state = OdometryState.TRACKING
        return FrameResult(index, timestamp, world_from_cur, prev_from_cur, est.msd, est.iterations,
                           est.points, status, std * np.sqrt(widen), cov * widen, self._key.index,
                           est.gain, est.bias, gap=gap)

    def _lost(self, index: int, timestamp: float, reason: str, est: Estimate | None = None) -> FrameResult:
        """The prediction, or the feature hypothesis where it contradicts it
        (:mod:`monovo_cli.core.recovery.lost_frames`)."""
        predicted = self._predicted
        cur_from_key = self._recovery.lost_pose(index, predicted)
        world_from_cur = orthonormalize(self._key.world_from_key @ se3_inv(cur_from_key))
        prev_from_cur = orthonormalize(se3_inv(self._world_from_prev) @ world_from_cur)
        self._world_from_prev = world_from_cur
        self._cur_from_key_prev = cur_from_key
        self._state = OdometryState.RECOVERING
        self._lost_run, self._unmeasured = self._lost_run + 1, self._unmeasured + 1
        predicted_std = self._prediction_std(motion_change(cur_from_key, predicted))
        std = lost_std(predicted_std, self._last_motion, self._key.plane.distance)
        self._gap_variance = self._gap_variance + std ** 2
        self._gap_steps.append(predicted_std ** 2)  # (where the change likely fell: shares)
        return lost_row(index, timestamp, world_from_cur, prev_from_cur, std, est, self._key.index,
                        (self._gain, self._bias), reason)

    def _prediction_std(self, bridged: np.ndarray, lost_run: int | None = None) -> np.ndarray:
        """(6,) m and rad: the std of a lost frame's motion (:func:`frame_std.prediction_std`);
        ``bridged`` (6,) how far the pose taken is from the prediction, ``lost_run`` the
        frames lost since a motion was measured, this one included (None: as counted)."""
        return prediction_std(self._motion_changes, self._last_motion, self._last_std,
                              self._key.plane.distance,
                              self._unmeasured if lost_run is None else lost_run, bridged)

    def _prior(self, index: int) -> np.ndarray:
        """(6,) the prediction's std at frame ``index``; after a loss a lost row's (a step)."""
        prior = self._prediction_std(np.zeros(6), self._unmeasured + 1)
        return prior if self._last_accepted == index - 1 else \
            lost_std(prior, self._last_motion, self._key.plane.distance)

    def _unforeseen(self, motion: np.ndarray, std: np.ndarray, index: int) -> np.ndarray:
        """(6,) the variance an accepted frame's motion ``motion`` (6,; its std ``std``) adds
        for a change the prediction did not foresee (:func:`frame_std.unforeseen`): none
        unless the previous frame was accepted too."""
        if self._last_motion is None or self._last_accepted != index - 1:
            return np.zeros(6)
        return unforeseen(motion - self._last_motion, std, self._prediction_std(np.zeros(6), 1))

    def _checks(self) -> FitChecks:
        """The current frame's search (:class:`~monovo_cli.core.checks.FitChecks`)."""
        return FitChecks(self.options, self.camera, self._sigma, self._failure, tuple(self._recent_msd))

    def _failure(self, est: Estimate, key: Keyframe) -> str:
        """Why ``est`` (against ``key``) cannot be trusted, or '' (:mod:`~monovo_cli.core.checks`'
        divergence and ground checks): every fit of the frame passes here."""
        return divergence(est, self.options, self._sigma, self._chance_msd, self._recent_msd) \
            or off_the_ground(self.camera, self.region, key, est.cur_from_key)

    def _settle_plane(self, index: int, pyr: list[np.ndarray], est: Estimate) -> Estimate:
        """PlaneTracker.test (with the keyframe gradients' noise factor); a corrected plane's
        keyframe is kept if its estimate passes, from the top level if level 2's fails (``est``,
        fitted over the old plane, can be far off)."""
        f = self._motion_cov.measure_noise(self._key.levels[0], self._key.plane, pyr[0], est, keep=False)
        found = self._plane.test(index, self._key, self._key_image, pyr, est, self.camera,
                                 self.region, self.options, self.mask, f)
        new = None if found is None else self._checks().refit(found[0], pyr, found[1], est)
        if new is None:
            return est
        self._key, self._plane.covariance = found[0], found[2]
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

    def _motion_to(self, key: Keyframe, cur_from_key: np.ndarray) -> np.ndarray:
        """The motion (4x4, T_{k-1}_k) from the previous pose to ``cur_from_key`` against ``key``."""
        return se3_inv(self._world_from_prev) @ key.world_from_key @ se3_inv(cur_from_key)

    def _resolve_gap(self, index: int, image: np.ndarray, pyr: list[np.ndarray]
                     ) -> tuple[Keyframe, Estimate] | None:
        """Frame ``index`` (``image``, ``pyr``) measured directly from the last good frame
        before the lost ones (:func:`~monovo_cli.core.recovery.reinit.resolve_gap`):
        ``(the keyframe, the estimate)`` if one passes the checks, else None. Called before
        the frame is recorded lost (the prediction is still the next)."""
        good = self._good
        chosen = None if good is None or not self.options.resolve_gaps else gap_reference(
            good, self._key, self._predicted, (self._gain, self._bias), lambda i, im, plane, w:
            build_keyframe(i, im, self.camera, plane, self.region, w, self.options, mask=self.mask))
        if chosen is None:
            return None
        ref, predicted, brightness = chosen
        chance, self._chance_msd = self._chance_msd, ref.levels[0].intensity_variance
        try:
            return resolve_gap(index, image, pyr, good, ref, predicted, brightness, self._checks(),
                               mask=self.mask, region=self.region)
        finally:
            self._chance_msd = chance

    def _reinit(self, index: int, timestamp: float, image: np.ndarray, pyr: list[np.ndarray],
                reason: str, resolved: tuple[Keyframe, Estimate] | None = None) -> FrameResult:
        """Frames stay lost: anchor a fresh keyframe on this one, at the predicted pose (the
        gap since the last good frame bridged by the prediction) or at the gap re-solved
        (:func:`~monovo_cli.core.recovery.reinit.fresh_start`); a frame that cannot carry a
        keyframe stays lost. ``resolved`` the gap already re-solved (:meth:`_resolve_gap`;
        None: try it here), ``reason`` why the frame was not tracked ("" for a frame that
        was, but is measured better from the last good frame). The recent frames' msd level
        stays: the scene and the camera are the same (:func:`checks.divergence`)."""
        lost_for, good = self._lost_run, self._good
        gap_before, world_from_prev = self._gap_variance.copy(), self._world_from_prev
        if resolved is None:
            resolved = self._resolve_gap(index, image, pyr)
        res = self._lost(index, timestamp, reason or "no keyframe could be anchored on it")
        variances = np.array(self._gap_steps)  # (this frame's predicted motion is the last)
        fresh = fresh_start(res, self._key, self._cur_from_key_prev, self._gap_variance, resolved,
                            good, self._motion_cov, self._plane)
        if not any(self._reanchor(index, image, pyr, fresh.world_from_cur, plane, plane_cov)
                   for plane, plane_cov in fresh.planes):
            return res
        self._lost_run, self._gap_steps = 0, []
        self._gap_variance = np.zeros(6)  # the next motions are from this keyframe
        self._handed_over = None  # (a re-initialised keyframe measured no model error)
        self._world_from_prev = fresh.world_from_cur
        self._good = GoodFrame(index, image, fresh.world_from_cur, np.eye(4))
        words = f"re-initialised after {lost_for} lost frames" + (f" ({reason})" if reason else "")
        if resolved is None:
            return replace(res, status=FrameStatus.REINIT, keyframe=self._key.index, reason=words)
        # the gap's mean motion per frame is the next prediction: a motion measured
        self._velocity, self._unmeasured = se3_exp(-se3_log(fresh.good_from_cur) / (index - good.index)), 0
        return resolved_row(res, words, self._key.index, resolved[1], good, world_from_prev,
                            fresh.world_from_cur, fresh.covariance, gap_before, variances)


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
