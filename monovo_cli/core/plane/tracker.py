"""The keyframe plane along a drive: its covariance, its test on the first frames, and the
plane of every new keyframe (the tracker's side of :mod:`monovo_cli.core.plane.belief`).

A keyframe's plane starts as init.yaml's with the mounting prior's covariance. While it is
known only that loosely (tilt std above PLANE_SETTLED_DEG: frame 0, a re-initialisation),
:meth:`PlaneTracker.test` measures its normal on every frame; images that contradict it
(init.yaml holds the nominal plane and frame 0 is at a crest of the suspension, or on a
slope) correct it, images that confirm it (an exact init.yaml, e.g. the paper's pairs) make
it exact. At a re-anchor, :meth:`PlaneTracker.successor` gives the new keyframe's plane: the
MAP of the plane carried by the motion, the normal measured from the two images and the
mounting prior. docs/algorithm.md section 4 gives the reasons and thresholds.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from monovo_cli.core.estimator.estimate import Estimate, estimate_motion
from monovo_cli.core.keyframe import Keyframe, build_keyframe
from monovo_cli.core.options import EstimatorOptions, TrackOptions
from monovo_cli.core.plane.belief import (
    CONFIRMED_DEG,
    CONSISTENT_CHI2,
    DISTANCE_CHANGE,
    PLANE_SETTLED_DEG,
    TILT_CHANGE_DEG,
    PlaneBelief,
    PlaneLink,
    default_sigmas,
    exact_covariance,
    fuse,
    keyframe_plane,
    measured_tilt_std_deg,
    mounting_prior,
    process_noise,
    propagated_plane,
    propagation_jacobian,
    tilt_chi2,
    tilt_std_deg,
    to_chart,
    transported,
)
from monovo_cli.core.plane.fit import refine_plane_and_motion
from monovo_cli.core.plane.motion_covariance import PlaneCovarianceCalibration
from monovo_cli.errors import TrackingError
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import orthonormalize
from monovo_cli.geometry.plane import Plane


class PlaneTracker:
    """What the tracker believes about its keyframe's plane.

    ``mounting``: the mounting prior (``plane`` of init.yaml, ``sigma_distance`` m and
    ``sigma_deg``; None: :func:`~monovo_cli.core.plane.belief.default_sigmas`);
    ``covariance`` (3, 3): of the current keyframe plane's distance and tilts, in its chart;
    ``consistency`` calibrates it for the reported motion covariance (:attr:`reported_covariance`).
    """

    def __init__(self, plane: Plane, sigma_distance: float | None = None,
                 sigma_deg: float | None = None) -> None:
        self.mounting = mounting_prior(plane, *default_sigmas(plane, sigma_distance, sigma_deg))
        self.covariance = self.mounting.covariance
        self.consistency = PlaneCovarianceCalibration()

    @property
    def reported_covariance(self) -> np.ndarray:
        """(3, 3) :attr:`covariance` as the re-anchors so far say it is (for reporting only)."""
        return self.consistency.reported(self.covariance)

    @property
    def unsettled(self) -> bool:
        """The keyframe's tilt is known only from the prior: :meth:`test` it on each frame."""
        return tilt_std_deg(self.covariance) > PLANE_SETTLED_DEG

    def anchored(self, covariance: np.ndarray | None = None) -> None:
        """A new keyframe was anchored with a plane of ``covariance`` (None: the prior's)."""
        self.covariance = self.mounting.covariance if covariance is None else covariance

    def test(self, key: Keyframe, key_image: np.ndarray, pyramid: list[np.ndarray],
             est: Estimate, camera: PinholeCamera, region: tuple[int, int, int, int],
             options: TrackOptions, mask: np.ndarray | None = None
             ) -> tuple[Keyframe, Estimate, np.ndarray] | None:
        """Test the keyframe's tilt on the current frame (``pyramid``, estimate ``est``).

        If the normal of the joint refinement contradicts it (chi-square above
        CONSISTENT_CHI2), the two are fused and ``(keyframe rebuilt on the result from
        key_image at the same pose, the frame re-estimated against it, the fused covariance)``
        comes back for the caller to check and adopt; the plane keeps the prior's distance
        uncertainty. If the images confirm it to within CONFIRMED_DEG it is taken as exact
        (:attr:`covariance` shrinks). None unless the plane was corrected.
        """
        fit = refine_plane_and_motion(key.levels[0].points, pyramid[0], est.cur_from_key,
                                      key.plane, gain=est.gain, bias=est.bias,
                                      options=options.estimator, iterations=4)
        if fit.measured is None:
            return None
        if tilt_chi2(fit.measured, key.plane) < CONSISTENT_CHI2:
            if measured_tilt_std_deg(fit.measured) < CONFIRMED_DEG:
                self.covariance = exact_covariance(key.plane)
            return None
        try:
            belief = fuse([PlaneBelief.from_covariance(key.plane, self.covariance), fit.measured])
            cov = belief.covariance
            new_key = replace(build_keyframe(key.index, key_image, camera, belief.plane, region,
                                             key.world_from_key, options, mask=mask),
                              link=key.link)
        except (ValueError, np.linalg.LinAlgError, TrackingError):
            return None
        new = estimate_motion(new_key.levels, pyramid, est.cur_from_key, options=options.estimator,
                              gain=est.gain, bias=est.bias, first_level=options.predicted_top_level)
        return new_key, new, cov

    def successor(self, key: Keyframe, image: np.ndarray, est: Estimate,
                  cur_from_key: np.ndarray, gain: float, bias: float,
                  options: EstimatorOptions
                  ) -> tuple[Plane, np.ndarray | None, float, float, PlaneLink | None]:
        """The plane of a keyframe anchored on the current frame (finest level ``image``,
        ``cur_from_key`` its pose): ``(plane in its camera, covariance, gain, bias, link)``,
        the MAP of the plane carried by the motion, the joint refinement's normal and the
        mounting prior (with DISTANCE_CHANGE and TILT_CHANGE_DEG of process noise on the
        carried plane); the brightness model is the refinement's; ``link`` what smoothing
        ``key``'s plane in hindsight needs (:class:`~monovo_cli.core.plane.belief.PlaneLink`).
        If the beliefs cannot be combined the carried plane comes back with covariance None
        and no link."""
        fit = refine_plane_and_motion(key.levels[0].points, image, cur_from_key, key.plane,
                                      gain=gain, bias=bias, options=options, iterations=4)
        measured = None if fit.measured is None else \
            transported(fit.measured, orthonormalize(fit.cur_from_key))
        distance_change = DISTANCE_CHANGE * key.plane.distance
        tilt_change = np.radians(TILT_CHANGE_DEG)
        try:
            carried = propagated_plane(key.plane, self.covariance, cur_from_key, est.covariance)
            belief = keyframe_plane(carried, measured=measured, prior=self.mounting,
                                    distance_change=distance_change, tilt_change=tilt_change)
            J = propagation_jacobian(key.plane, cur_from_key)[1][:, :3]
            predicted = carried.covariance + process_noise(distance_change, tilt_change)
            link = PlaneLink(self.covariance @ J.T @ np.linalg.inv(predicted),
                             to_chart(carried.plane, belief.plane),
                             propagated_distance=carried.plane.distance,
                             propagated_variance=float(predicted[0, 0]
                                                    - J[0, 0] ** 2 * self.covariance[0, 0]),
                             previous_variance=float(self.covariance[0, 0]),
                             mounting=(self.mounting.plane.distance,
                                       float(np.sqrt(self.mounting.covariance[0, 0]))))
        except (ValueError, np.linalg.LinAlgError):
            return key.plane.in_frame(cur_from_key), None, fit.gain, fit.bias, None
        self.consistency.reanchored(carried, belief, self.mounting, distance_change)
        return belief.plane, belief.covariance, fit.gain, fit.bias, link
