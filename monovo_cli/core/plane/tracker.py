"""The keyframe plane along a drive: its covariance, its test on the first frames, and the
plane of every new keyframe (the tracker's side of :mod:`monovo_cli.core.plane.belief`).

Long module: the plane's belief, its tests against the images and what the report adds to
it are one state, read and changed together by every frame.

What init.yaml says of the ground is a :class:`Mounting`. By default its plane is frame 0's
ground, exact (the paper's known initial pose; the drive's scale comes from it), and the
mounting prior is centred on a *latent mean mount*: the rover's long-run distance and tilt
over the ground, unknown, with a prior centred on frame 0's plane of the bobbing's width
(``sigma_distance``, ``sigma_deg``). Frame 0 is one sample of the ground around that mean, so
the forward pass centres every keyframe's prior on frame 0's plane with the mean's
uncertainty and the bobbing's (twice the bobbing's variance), and the smoother
(:mod:`monovo_cli.mapping.smoothing`) solves the mean's distance over the whole drive, so that
the trajectory written does not keep frame 0's own bob. (The forward pass does not re-estimate
the mean from the keyframes' planes: those are samples of one carried chain, not independent
ones, and counting them as independent made the mean follow the chain's drift.) A declared
nominal mount (``ground.nominal: true``, or a ``mount:`` block) centres the prior on that
mount instead; with ``ground.nominal: true`` frame 0's plane is the nominal one, known only
to the prior's width.

A keyframe plane known only loosely (tilt std above PLANE_SETTLED_DEG: a nominal frame 0, a
stated uncertainty, a keyframe anchored after lost frames, :meth:`PlaneTracker.loosened`) is
tested on every frame by :meth:`PlaneTracker.test`: images that contradict it correct it,
images that measure frame 0's precisely correct it (its distance keeps its uncertainty: the
images cannot measure it) and make a later keyframe's as sure as they are. The
contradiction of a tilt given as exact stays in the reported covariance, and on ground
frame 0's images confirm the carried distance keeps frame 0's
(:attr:`PlaneTracker.distance_change`). Frame 0's tilt is
measured from the first frames whatever its uncertainty (:attr:`PlaneTracker.initial_tilt`):
a contradiction is reported (logged, kept in run.yaml) and corrects the tilt, a tilt given as
exact then counting with the prior's width; the distance is kept, and with
``keep_initial_tilt`` so is the tilt. A tilt given as exact that the images agreed with is
asked again on frames 2, 4, 8, ... until the first re-anchor: from the first whose images do
not confirm it, every tilt carries the plane model's error in the report, and where they
contradict it the carried distance gets the terrain's process noise. At a
re-anchor, :meth:`PlaneTracker.successor` gives
the new keyframe's plane: the MAP of the plane carried by the motion, the normal measured
from the two images and the mounting prior. docs/algorithm.md section 4 gives the reasons and
thresholds.
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, estimate_motion
from monovo_cli.core.keyframe import Keyframe, build_keyframe
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.core.plane.belief import (
    CONFIRMED_DEG,
    CONSISTENT_CHI2,
    DISTANCE_CHANGE,
    DISTANCE_CHANGE_PLANAR,
    PLANE_SETTLED_DEG,
    TILT_CHANGE_DEG,
    UNCONFIRMED_CHI2,
    PlaneBelief,
    PlaneLink,
    carried_map,
    carrying_jacobian,
    default_sigmas,
    exact_covariance,
    fuse,
    keyframe_plane,
    measured_tilt,
    measured_tilt_std_deg,
    mounting_prior,
    process_noise,
    propagated_plane,
    propagation_jacobian,
    tilt_chi2,
    tilt_std_deg,
    to_chart,
    transported,
    widened,
    with_mount_departure,
)
from monovo_cli.core.plane.fit import refine_plane_and_motion
from monovo_cli.core.plane.motion_covariance import TILT_MODEL_ERROR_DEG, PlaneCovarianceCalibration
from monovo_cli.core.plane.mounting import InitialTilt, Mounting
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import orthonormalize, skew
from monovo_cli.geometry.plane import Plane, tangent_basis

log = logging.getLogger(__name__)

TILT_CHECK_FRAMES = 10  # frames of keyframe 0 on which init.yaml's tilt is measured at most


class PlaneTracker:
    """What the tracker believes about its keyframe's plane.

    ``plane`` init.yaml's (frame 0's ground, or the nominal mount), ``mounting`` what else
    it says (:class:`Mounting`; None: the defaults); ``keep_initial_tilt`` keeps frame 0's
    tilt whatever the images say. ``covariance`` (3, 3): of the current keyframe plane's
    distance and tilts, in its chart; ``consistency`` calibrates it for the reported motion
    covariance (:attr:`reported_covariance`); ``initial_tilt`` the images' verdict on frame
    0's tilt once measured (:class:`InitialTilt`).
    """

    def __init__(self, plane: Plane, mounting: Mounting | None = None, *,
                 keep_initial_tilt: bool = False) -> None:
        m = mounting or Mounting()
        self.sigmas = default_sigmas(plane, m.sigma_distance, m.sigma_deg)
        self.latent_mount = m.mount is None
        self._reference = plane if m.mount is None else m.mount  # the smoother's distance reference
        prior = mounting_prior(self._reference, *self.sigmas)
        #: the mounting prior on a keyframe's ground: the declared mount with the bobbing's
        #: width, or frame 0's plane with the latent mean's uncertainty and the bobbing's
        self.mounting = prior if not self.latent_mount else PlaneBelief(plane, 0.5 * prior.information)
        if m.initial_std is None:
            self.covariance = exact_covariance(plane)
        else:
            s_d, s_deg = m.initial_std
            self.covariance = np.diag([s_d ** 2] + [math.radians(s_deg) ** 2] * 2)
        self.keep_initial_tilt = keep_initial_tilt
        self.initial_tilt: InitialTilt | None = None
        self._tilt_checks = 0
        self._model_variance = 0.0  # (m^2) the ground seen departs from a plane given as exact
        #: (2, 2) rad^2: the images contradicted frame 0's tilt given as exact by this much
        #: (squared, per angle); one of the two is that far off (reported while the tilt is
        #: kept, or corrected until a re-anchor measures the ground seen)
        self._disputed_tilt: np.ndarray | None = None
        #: (2, 2) rad^2: the images did not confirm frame 0's tilt given as exact on some
        #: frame before the first re-anchor (chi-square from UNCONFIRMED_CHI2 up, below
        #: CONSISTENT_CHI2 where it is the verdict): the ground seen is not that plane, and
        #: every keyframe's tilt, carried from it, keeps the plane model's error, for the
        #: whole drive
        self._unconfirmed_tilt: np.ndarray | None = None
        #: ... and asked again, they contradicted it (chi-square from CONSISTENT_CHI2): the
        #: carried distance gets the terrain's process noise (:attr:`distance_change`)
        self._contradicted_later = False
        #: (2, 2) rad^2: this keyframe was anchored on a captured frame whose split-half
        #: fits disagreed on its rotation this much (:meth:`anchored_captured`)
        self._spread_tilt: np.ndarray | None = None
        self.consistency = PlaneCovarianceCalibration()
        #: the keyframe distance for reporting where it differs from the filter's
        #: (:meth:`_reported_distance_variance`): (its variance (m^2), the share of the prior's
        #: offset its error holds, the variance of the rest of it (m^2)); and the next
        #: keyframe's, worked out by :meth:`successor` for :meth:`anchored` (None: the filter's)
        self._report_distance: tuple[float, float, float] | None = None
        self._next_report_distance: tuple[float, float, float] | None = None
        #: (keyframe plane, mounting prior, the prior's tilt in its chart): :meth:`reported`'s
        self._mount_tilt: tuple[Plane, PlaneBelief, tuple[np.ndarray, np.ndarray] | None] | None = None

    @property
    def ground_planar(self) -> bool:
        """The ground seen so far is a plane, as the re-anchors measured it
        (:attr:`PlaneCovarianceCalibration.ground_planar`)."""
        return self.consistency.ground_planar

    @property
    def reported_covariance(self) -> np.ndarray:
        """(3, 3) :attr:`covariance` as the re-anchors so far say it is (for reporting only);
        where the images contradicted a plane given as exact, the ground they see departs
        from it by up to the bobbing's width in distance too, and every tilt from then on is
        uncertain by the contradiction itself: the images and init.yaml disagreed by that
        much, one of them is that far off, and the tool cannot tell which (with
        ``keep_initial_tilt`` for the whole drive; a tilt corrected on the images until the
        re-anchors measure how far the ground seen departs from it)."""
        cov = self.covariance
        if self._report_distance is not None and cov[0, 0] > 0:  # (its correlations kept)
            r = math.sqrt(self._report_distance[0] / cov[0, 0])
            cov = np.array(cov, dtype=float)
            cov[0, :] *= r
            cov[:, 0] *= r
        P = self.consistency.reported(cov)
        # (the tilt frame 0's images did not confirm is the ground seen departing from the
        # plane: once the re-anchors measure that departure, it is theirs, not counted twice)
        measured = self.consistency.departure_measured
        unconfirmed = None if measured else self._unconfirmed_tilt
        # (a contradicted tilt the images corrected: so too, where the tilt is tracked on the
        # images' ground, not kept at init.yaml's)
        disputed = None if measured and not self.keep_initial_tilt else self._disputed_tilt
        extras = [e for e in (disputed, unconfirmed, self._spread_tilt)
                  if e is not None]
        if self._model_variance or extras:
            P = P.copy()
            P[0, 0] += self._model_variance
            for extra in extras:
                P[1:, 1:] += extra
        return P

    def reported(self, plane: Plane) -> np.ndarray:
        """(3, 3) :attr:`reported_covariance` of the keyframe ``plane`` (in its camera), with
        its departure from the mounting prior where the two cannot both hold
        (:func:`~monovo_cli.core.plane.belief.with_mount_departure`)."""
        cached = self._mount_tilt
        if cached is None or cached[0] is not plane or cached[1] is not self.mounting:
            cached = self._mount_tilt = plane, self.mounting, measured_tilt(self.mounting, plane)
        return with_mount_departure(self.reported_covariance, cached[2])

    @property
    def distance_change(self) -> float:
        """The carried distance's process noise per keyframe, a share of the distance:
        DISTANCE_CHANGE_PLANAR once the images of frame 0 confirmed init.yaml's tilt (the
        ground seen is the plane under the wheels, and the distance changes only as the
        motion carries it), DISTANCE_CHANGE until then or where they contradicted it, on
        the first frames or asked again before the first re-anchor (terrain, a road seen at
        grazing angles: the ground seen can change unseen between keyframes). Chosen by
        ``benchmarks.held_out``."""
        agreed = self.initial_tilt is not None and not self.initial_tilt.contradicts \
            and not self._contradicted_later
        return DISTANCE_CHANGE_PLANAR if agreed else DISTANCE_CHANGE

    @property
    def mounting_tilt_covariance(self) -> np.ndarray:
        """(2, 2) the bobbing's covariance of the tilts (rad^2)."""
        return np.eye(2) * math.radians(self.sigmas[1]) ** 2

    @property
    def mount_plane(self) -> Plane:
        """The plane the ground keeps around the rover as now believed (the declared mount,
        or the mean mount's estimate), in any camera frame."""
        return self.mounting.plane

    @property
    def unsettled(self) -> bool:
        """The keyframe's tilt is known only loosely: :meth:`test` it on each frame."""
        return tilt_std_deg(self.covariance) > PLANE_SETTLED_DEG

    def wants_test(self, key: Keyframe, index: int) -> bool:
        """Whether :meth:`test` should run on frame ``index``: the keyframe's tilt is unsettled,
        or frame 0's tilt is still to be measured."""
        if key.index == index:
            return False
        first = key.index == 0 and self.initial_tilt is None and self._tilt_checks < TILT_CHECK_FRAMES
        watch = self._watching(key) and index & (index - 1) == 0  # frames 2, 4, 8, ...
        return first or watch or (self.unsettled and not (key.index == 0 and self.keep_initial_tilt))

    def _watching(self, key: Keyframe) -> bool:
        """Frame 0's tilt, given as exact, agreed with the first frames' images, and until
        the first re-anchor the images are asked again whether they still confirm it, each
        time across twice the baseline (:meth:`wants_test`)."""
        return (key.index == 0 and self.initial_tilt is not None and not self.initial_tilt.contradicts
                and not self._contradicted_later and not self.unsettled)

    def anchored(self, covariance: np.ndarray | None = None) -> None:
        """A new keyframe was anchored with a plane of ``covariance`` (None: the prior's)."""
        self._model_variance = 0.0
        self._spread_tilt = None
        self.covariance = self.mounting.covariance if covariance is None else covariance
        self._report_distance = self._next_report_distance if covariance is not None else None
        self._next_report_distance = None

    def anchored_captured(self, plane: Plane, rotations: list[np.ndarray]) -> None:
        """The keyframe just anchored (``plane`` in its camera) stands on a captured frame
        whose split-half fits disagreed by ``rotations`` (each (3,) rad, in that camera):
        its tilt is that uncertain too, for reporting (the plane carried from a rotation
        that far off is tilted by it, and the next rows measured against it inherit that;
        docs/algorithm.md section 8). The next keyframe's anchoring clears it."""
        if not rotations:
            return
        n = plane.normal
        J = -tangent_basis(n).T @ skew(n)  # d tilt / d rotation of the camera
        self._spread_tilt = sum(J @ np.outer(w, w) @ J.T for w in rotations)

    def test(self, index: int, key: Keyframe, key_image: np.ndarray, pyramid: list[np.ndarray],
             est: Estimate, camera: PinholeCamera, region: tuple[int, int, int, int],
             options: TrackOptions, mask: np.ndarray | None = None, noise_factor: float = 1.0
             ) -> tuple[Keyframe, Estimate, np.ndarray] | None:
        """Test the keyframe's tilt on the current frame ``index`` (``pyramid``, estimate
        ``est``); on keyframe 0's first frames, record the verdict on init.yaml's tilt.

        If the normal of the joint refinement contradicts it (chi-square above
        CONSISTENT_CHI2), the two are fused and ``(keyframe rebuilt on the result from
        key_image at the same pose, the frame re-estimated against it, the fused covariance)``
        comes back for the caller to check and adopt; the plane keeps its distance and that
        distance's uncertainty. So too for frame 0's plane known only loosely (a nominal
        mount, a stated std) when the images measure its tilt to within CONFIRMED_DEG,
        whatever the chi-square: the tilt given is the mount's mean, or a guess, and frame
        0's own bobs. A later keyframe's unsettled plane the images confirm takes the
        measurement's tilt covariance (:attr:`covariance` shrinks). None unless the plane
        was corrected; never for frame 0's with ``keep_initial_tilt``. The normal's std is
        ``noise_factor`` times the fit's (the keyframe gradients' noise, as in the rows' std)."""
        fit = refine_plane_and_motion(key.levels[0].points, pyramid[0], est.cur_from_key,
                                      key.plane, gain=est.gain, bias=est.bias,
                                      options=options.estimator, iterations=4)
        if fit.measured is None:
            return None
        fit = replace(fit, measured=widened(fit.measured, noise_factor))
        chi2 = tilt_chi2(fit.measured, key.plane)
        if self._watching(key):  # the tilt is kept whatever they say
            if chi2 >= UNCONFIRMED_CHI2:
                self._unconfirmed(index, chi2, fit.measured, key.plane)
            self._contradicted_later = chi2 >= CONSISTENT_CHI2
            if self._contradicted_later:
                log.info("frame %d's images contradict init.yaml's ground tilt (chi-square "
                         "%.1f): the distance carried from keyframe to keyframe is treated as "
                         "on terrain from here; the tilt is kept", index, chi2)
            return None
        precise = measured_tilt_std_deg(fit.measured) < CONFIRMED_DEG
        keep = key.index == 0 and self.keep_initial_tilt
        # frame 0's tilt given loosely (a nominal mount, a stated std) and measured precisely:
        # corrected, as when contradicted (it is the mean's, or a guess; frame 0's own bobs)
        measure = key.index == 0 and precise and self.unsettled and not keep
        exact = key.index == 0 and tilt_std_deg(self.covariance) < self.sigmas[1]
        if exact and chi2 >= CONSISTENT_CHI2 and self._disputed_tilt is None:
            got = measured_tilt(fit.measured, key.plane)  # a tilt given as exact, contradicted
            if got is not None:
                self._disputed_tilt = np.diag(got[0] ** 2)
        if key.index == 0 and self.initial_tilt is None:
            self._tilt_checks += 1
            if precise or chi2 >= CONSISTENT_CHI2 or self._tilt_checks >= TILT_CHECK_FRAMES:
                self._record_initial_tilt(fit.measured, key.plane, chi2, index,
                                          not keep and (chi2 >= CONSISTENT_CHI2 or measure))
                if exact and UNCONFIRMED_CHI2 <= chi2 < CONSISTENT_CHI2:
                    self._unconfirmed(index, chi2, fit.measured, key.plane)
        if keep:
            return None
        if chi2 < CONSISTENT_CHI2 and not measure:
            if precise and self.unsettled:
                self.covariance = self._confirmed(fit.measured, key.plane)
            return None
        # Contradicted, or frame 0's loose tilt measured precisely: the tilt is corrected, a
        # tilt given as exact taken as known to the prior's width (the ground the images see
        # is not the plane under the wheels); the distance keeps its own uncertainty.
        cov = np.array(self.covariance, dtype=float)
        if tilt_std_deg(cov) < self.sigmas[1]:
            cov[1:, 1:] = self.mounting_tilt_covariance
            self._model_variance = max(self.sigmas[0] ** 2 - cov[0, 0], 0.0)
        try:
            belief = fuse([PlaneBelief.from_covariance(key.plane, cov), fit.measured])
            cov = belief.covariance
            new_key = replace(build_keyframe(key.index, key_image, camera, belief.plane, region,
                                             key.world_from_key, options, mask=mask),
                              link=key.link)
        except (ValueError, np.linalg.LinAlgError, TrackingError):
            return None
        new = estimate_motion(new_key.levels, pyramid, est.cur_from_key, options=options.estimator,
                              gain=est.gain, bias=est.bias, first_level=options.predicted_top_level)
        return new_key, new, cov

    def _unconfirmed(self, index: int, chi2: float, measured: PlaneBelief | None = None,
                     plane: Plane | None = None) -> None:
        """Frame ``index``'s images do not confirm frame 0's exact tilt (``chi2``; ``measured``
        the normal they give, against ``plane``): every tilt carries the plane model's error
        from here (for reporting), as large as the measurement cannot exclude: per tilt the
        measured difference and twice its std (the 95 % bound; a first frame's short
        baseline measures a slope's 0.5 deg departure as 0.27 +- 0.12), the largest of the
        frames asked so far; TILT_MODEL_ERROR_DEG on each tilt where nothing was measured.
        (A fixed 0.5 deg made a 1024² Navcam drive's rotation std 100 times its error.)"""
        got = None if measured is None or plane is None else measured_tilt(measured, plane)
        if got is None:
            error = np.eye(2) * math.radians(TILT_MODEL_ERROR_DEG) ** 2
        else:
            error = np.diag((np.abs(got[0]) + 2.0 * np.sqrt(np.clip(np.diag(got[1]), 0.0, None))) ** 2)
        if self._unconfirmed_tilt is not None and \
                np.trace(self._unconfirmed_tilt) >= np.trace(error):
            return
        first = self._unconfirmed_tilt is None
        self._unconfirmed_tilt = error
        if first:
            log.info("frame %d's images do not confirm init.yaml's ground tilt (chi-square "
                     "%.1f): the std columns carry a %.2f deg model error on it from here",
                     index, chi2, math.degrees(math.sqrt(0.5 * np.trace(error))))

    def _confirmed(self, measured: PlaneBelief, plane: Plane) -> np.ndarray:
        """The covariance of a later keyframe's ``plane`` the images confirm (``measured``):
        the measurement's tilt covariance and the tilt the two still differ by, the distance's
        as it was. (Frame 0's plane so confirmed is exact: the paper's known initial pose.)"""
        got = measured_tilt(measured, plane)
        cov = np.array(self.covariance, dtype=float)
        if got is None:
            return cov
        x, C = got
        cov[0, 1:] = cov[1:, 0] = 0.0
        cov[1:, 1:] = C + np.outer(x, x)
        return cov

    def loosened(self, covariance: np.ndarray) -> np.ndarray:
        """``covariance`` (3, 3) of a keyframe anchored on a frame captured after lost frames,
        its tilt known to no better than the bobbing's width: that frame's motion spans the gap
        on part of the points, and its error reaches the carried plane beyond its formal
        covariance (0.25 deg at 1024², MER seed 17). The next frame then measures the tilt
        (:meth:`test`)."""
        cov = np.array(covariance, dtype=float)
        if tilt_std_deg(cov) < self.sigmas[1]:
            cov[0, 1:] = cov[1:, 0] = 0.0
            cov[1:, 1:] = self.mounting_tilt_covariance
        return cov

    def _record_initial_tilt(self, measured: PlaneBelief, plane: Plane, chi2: float,
                             frame: int, adopted: bool) -> None:
        got = measured_tilt(measured, plane)
        if got is None:
            return
        x, s = np.degrees(got[0]), np.degrees(np.sqrt(np.clip(np.diag(got[1]), 0.0, None)))
        self.initial_tilt = InitialTilt((float(x[0]), float(x[1])), (float(s[0]), float(s[1])),
                                        float(chi2), frame, bool(adopted))
        words = ("contradict" if chi2 >= CONSISTENT_CHI2 else "agree with")
        log.info("the images %s init.yaml's ground tilt: measured %+.2f, %+.2f deg (std %.2f, "
                 "%.2f) from it, chi-square %.1f; %s", words, x[0], x[1], s[0], s[1], chi2,
                 "the tilt is corrected" if self.initial_tilt.adopted else "init.yaml's tilt is kept")

    def carried(self, key_plane: Plane, cur_from_key: np.ndarray, twist: np.ndarray,
                sensitivity: np.ndarray | None = None) -> tuple[Plane, np.ndarray | None]:
        """The ground of a keyframe anchored without the images' normal (after lost frames):
        ``(plane in its camera, covariance)``, the MAP of the keyframe's plane ``key_plane``
        (covariance :attr:`covariance`) carried by ``cur_from_key`` (twist covariance
        ``twist`` (6, 6), ``sensitivity`` as for :meth:`successor`) and the mounting prior,
        with the same process noise; the carried plane alone (covariance None) where they
        cannot be fused."""
        try:
            carried = propagated_plane(key_plane, self.covariance, cur_from_key, twist, sensitivity)
            fused = keyframe_plane(carried, prior=self.mounting,
                                   distance_change=self.distance_change * key_plane.distance,
                                   tilt_change=np.radians(TILT_CHANGE_DEG))
            return fused.plane, fused.covariance
        except (ValueError, np.linalg.LinAlgError):
            return key_plane.in_frame(cur_from_key), None

    def successor(self, key: Keyframe, image: np.ndarray, est: Estimate, cur_from_key: np.ndarray,
                  gain: float, bias: float, options: EstimatorOptions,
                  sensitivity: np.ndarray | None = None, noise_factor: float = 1.0
                  ) -> tuple[Plane, np.ndarray | None, float, float, PlaneLink | None]:
        """The plane of a keyframe anchored on the current frame (finest level ``image``,
        ``cur_from_key`` its pose): ``(plane in its camera, covariance, gain, bias, link)``,
        the MAP of the plane carried by the motion, the joint refinement's normal and the
        mounting prior (with :attr:`distance_change` and TILT_CHANGE_DEG of process noise on the
        carried plane; ``sensitivity`` (6, 3) ``est``'s plane sensitivity, through which the
        keyframe plane's error reaches the carried one, :func:`carrying_jacobian`; the motion's
        and the normal's std widened by ``noise_factor`` as in :meth:`test`); the brightness
        model is the refinement's; ``link`` what smoothing ``key``'s plane in hindsight needs
        (the carried plane, covariance and link None, where the beliefs cannot be combined)."""
        fit = refine_plane_and_motion(key.levels[0].points, image, cur_from_key, key.plane,
                                      gain=gain, bias=bias, options=options, iterations=4)
        pose = orthonormalize(fit.cur_from_key)
        measured = None if fit.measured is None else transported(fit.measured, pose)
        distance_change, tilt_change = self.distance_change * key.plane.distance, np.radians(TILT_CHANGE_DEG)
        def fused(f: float) -> tuple[PlaneBelief, PlaneBelief]:
            m = measured if f == 1.0 or measured is None else transported(widened(fit.measured, f), pose)
            return carried_map(key.plane, self.covariance, cur_from_key, est.covariance * f ** 2,
                               sensitivity, m, self.mounting, distance_change, tilt_change)
        try:  # the MAP at the noise the keyframe's gradients allow, the report's calibration at
            # the fits' own (so it counts no less model error than they leave): (carried, MAP)
            raw = fused(1.0)
            carried, belief = raw if noise_factor == 1.0 else fused(noise_factor)
            J = carrying_jacobian(propagation_jacobian(key.plane, cur_from_key)[1], sensitivity)
            predicted = carried.covariance + process_noise(distance_change, tilt_change)
            link = PlaneLink(self.covariance @ J.T @ np.linalg.inv(predicted),
                             to_chart(carried.plane, belief.plane),
                             propagated_distance=carried.plane.distance,
                             propagated_variance=float(predicted[0, 0]
                                                    - J[0, 0] ** 2 * self.covariance[0, 0]),
                             previous_variance=float(self.covariance[0, 0]),
                             mounting=(self._reference.distance, self.sigmas[0]),
                             latent_mount=self.latent_mount)
        except (ValueError, np.linalg.LinAlgError):
            return key.plane.in_frame(cur_from_key), None, fit.gain, fit.bias, None
        pulled = 0.0 if self._report_distance is None else self._report_distance[1]
        self.consistency.reanchored(*raw, self.mounting, distance_change, measured,
                                    carried_pull=J[0, 0] * pulled)
        self._next_report_distance = self._reported_distance_variance(
            J[0, 0], float(predicted[0, 0]), float(belief.covariance[0, 0]), distance_change)
        return belief.plane, belief.covariance, fit.gain, fit.bias, link

    def _reported_distance_variance(self, j: float, predicted: float, posterior: float,
                                    distance_change: float) -> tuple[float, float, float] | None:
        """The next keyframe's distance for reporting, ``(variance (m^2), c, the variance of
        the rest (m^2))``; None: the filter's.

        The filter carries the distance with DISTANCE_CHANGE_PLANAR of process noise per
        keyframe where frame 0's images confirmed the tilt: a weight for the MAP (chosen by
        ``benchmarks.held_out`` for accuracy), not an error. Where the re-anchors also find
        the ground seen planar (:attr:`ground_planar`), the carried distance changes only as
        the motion carries it, so the reported variance is that of the filter's estimate
        with the errors as they are. The filter weighs the carried distance (its variance
        ``predicted``, noise ``distance_change`` included) and the prior (variance ``v``, with
        ``1 / posterior = 1 / predicted + 1 / v``) as ``w = posterior / predicted`` and
        ``1 - w``. The carried one's error is the previous keyframe's carried (``j``: d carried
        / d previous) and the motion's share; the prior's is its offset from the ground
        (:meth:`PlaneCovarianceCalibration.prior_offset`, before it is measured the prior's
        width), common to every keyframe: its pulls add up, keyframe after keyframe, and the
        share ``c`` of it the estimate holds follows ``c = w j c_previous + 1 - w``. The rest,
        the carried noise and the prior's bobbing, adds in squares. (With the noise counted
        as an error, a 512² flat drive's distance went into ty and tz as 7 times their error;
        with the prior's pulls independent, a MER drive's distance went 23 mm off against a
        std of 4 mm.)"""
        pull, own = (0.0, float(self.covariance[0, 0])) if self._report_distance is None \
            else self._report_distance[1:]
        if not (self.consistency.ground_planar and self.distance_change <= DISTANCE_CHANGE_PLANAR):
            return None
        if not (0.0 < posterior < predicted):
            return None
        motion = max(predicted - distance_change ** 2 - j ** 2 * self.covariance[0, 0], 0.0)
        w = posterior / predicted
        rest = predicted * posterior / (predicted - posterior)
        offset = self.consistency.prior_offset()
        common, bobbing = (rest, 0.0) if offset is None else \
            (min(offset[0], rest), min(offset[1], rest))  # (beyond the width: the g of reported)
        pull = w * j * pull + (1.0 - w)
        own = w ** 2 * (j ** 2 * own + motion) + (1.0 - w) ** 2 * bobbing
        return float(own + pull ** 2 * common), pull, float(own)
