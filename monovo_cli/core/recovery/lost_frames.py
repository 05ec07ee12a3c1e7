"""LostFrameRecovery frames the direct fit cannot estimate with the feature hypothesis (recovery).

A lost frame carries the tracker's prediction, the last accepted motion repeated (constant
velocity). A rover that stops driving to turn in place breaks that prediction at the worst
moment, and the re-initialisations that follow anchor their fresh keyframes where the
prediction put them (docs/algorithm.md section 8, "LostFrameRecovery a lost frame"). The feature
hypothesis (:mod:`monovo_cli.core.recovery.features`) does not depend on the motion's size,
so it bridges them:

* a :class:`TrustedFrame` is the latest frame whose pose the tracker trusts: the keyframe
  while tracking, a bridged lost frame while recovering. The current frame's hypothesis is
  computed against it, over the keyframe's plane carried to it, and chained through its
  pose to ``cur_from_key`` (:func:`bridge`);
* a lost frame keeps the prediction if the prediction reprojects the hypothesis' inliers
  about as well as the hypothesis does (:meth:`ChainedHypothesis.agrees`), otherwise it takes the
  hypothesis' pose: the features veto a prediction they contradict, and do not replace one
  they confirm (the prediction is the smoother of the two over small motions);
* a lost frame so bridged is the next frame's reference: after two MER steps the keyframe
  is out of sight, but the previous frame is not, and a re-initialisation anchors its fresh
  keyframe at the bridged pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from monovo_cli.core.options import FeatureOptions
from monovo_cli.core.recovery.features import FeatureMotion, feature_motion
from monovo_cli.core.recovery.predicted_view import predicted_view_motion
from monovo_cli.geometry.camera import PinholeCamera
from monovo_cli.geometry.lie import orthonormalize, se3_inv
from monovo_cli.geometry.plane import Plane

AGREE_RMS_FACTOR = 2.0  # a pose agrees with a hypothesis within this x its RMS (or RANSAC's px)


@dataclass(frozen=True)
class TrustedFrame:
    """A frame the feature hypothesis is computed against: ``image`` (H, W) grey and
    ``from_key`` (4x4) its pose ``ref_from_key`` relative to the current keyframe (identity
    for the keyframe itself)."""

    image: np.ndarray
    from_key: np.ndarray


@dataclass(frozen=True)
class ChainedHypothesis:
    """The current frame's feature hypothesis, chained to the keyframe.

    ``cur_from_key`` (4x4) = ``motion.cur_from_key`` (cur_from_ref) @ ``ref_from_key``;
    ``ref_plane`` the keyframe's plane in the reference camera (the hypothesis' plane);
    ``image`` the current frame (the next reference if the frame is bridged);
    ``tolerance_px`` RANSAC's inlier threshold in full-resolution pixels.
    """

    image: np.ndarray
    cur_from_key: np.ndarray
    motion: FeatureMotion
    ref_plane: Plane
    ref_from_key: np.ndarray
    tolerance_px: float

    def reprojection_px(self, cur_from_key: np.ndarray, camera: PinholeCamera) -> float:
        """RMS (undistorted full-resolution px) of the hypothesis' inliers reprojected with
        ``cur_from_key`` (4x4) instead of its own pose: their reference points on
        ``ref_plane`` into the current frame (inf if any falls behind the camera)."""
        cur_from_ref = cur_from_key @ se3_inv(self.ref_from_key)
        X = self.ref_plane.intersect(self.motion.key_rays)
        ok = np.all(np.isfinite(X), axis=1)
        X = X[ok] @ cur_from_ref[:3, :3].T + cur_from_ref[:3, 3]
        if not len(X) or np.any(X[:, 2] <= 1e-9):
            return float("inf")
        d = (X[:, :2] / X[:, 2:] - self.motion.cur_rays[ok, :2]) * [camera.fx, camera.fy]
        return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))

    def agrees(self, cur_from_key: np.ndarray, camera: PinholeCamera) -> bool:
        """Whether ``cur_from_key`` reprojects the inliers within ``AGREE_RMS_FACTOR`` times
        the hypothesis' own RMS, or within RANSAC's threshold if that is larger."""
        limit = max(AGREE_RMS_FACTOR * self.motion.rms_px, self.tolerance_px)
        return self.reprojection_px(cur_from_key, camera) <= limit


def chained_hypothesis(ref: TrustedFrame, image: np.ndarray, camera: PinholeCamera, key_plane: Plane, *,
           options: FeatureOptions, mask: np.ndarray | None = None,
           region: tuple[int, int, int, int] | None = None,
           predicted: np.ndarray | None = None) -> ChainedHypothesis | None:
    """The feature hypothesis of ``image`` (H, W) against ``ref``, chained to the keyframe.

    ``key_plane`` is the ground in the keyframe camera; ``options``, ``mask`` and ``region``
    as for :func:`~monovo_cli.core.recovery.features.feature_motion`; ``predicted`` (4x4) a
    predicted ``cur_from_key``: the features are then matched in the reference's view
    (:mod:`monovo_cli.core.recovery.predicted_view`). None when the features give no
    hypothesis.
    """
    ref_plane = key_plane.in_frame(ref.from_key)
    if predicted is None:
        motion = feature_motion(ref.image, image, camera, ref_plane, mask=mask, region=region,
                                options=options)
    else:
        motion = predicted_view_motion(ref.image, image, camera, ref_plane,
                                       predicted @ se3_inv(ref.from_key), mask=mask,
                                       region=region, options=options)
    if motion is None:
        return None
    return ChainedHypothesis(image, motion.cur_from_key @ ref.from_key, motion, ref_plane,
                  np.array(ref.from_key, dtype=float),
                  options.ransac_px * 2.0 ** options.level_for(camera))


class LostFrameRecovery:
    """The tracker's side: the reference frame, and the hypothesis of the frame at hand.

    ``camera`` the frames' camera; ``options`` the feature settings (``TrackOptions.features``),
    ``mask`` (H, W, non-zero = usable) and ``region`` (``[x0, y0, x1, y1]`` px) as for
    :func:`bridge`.
    """

    def __init__(self, camera: PinholeCamera, *, options: FeatureOptions,
                 mask: np.ndarray | None = None,
                 region: tuple[int, int, int, int] | None = None) -> None:
        self.camera, self.mask, self.region, self.options = camera, mask, region, options
        self.reference: TrustedFrame | None = None
        self.current: tuple[int, ChainedHypothesis] | None = None  # (frame index, its hypothesis)

    def anchored(self, image: np.ndarray) -> None:
        """A keyframe was anchored on ``image``: it is the reference from now on."""
        self.reference = TrustedFrame(image, np.eye(4))

    def hypothesis(self, index: int, image: np.ndarray, key_plane: Plane, *,
                   options: FeatureOptions | None = None,
                   predicted: np.ndarray | None = None) -> np.ndarray | None:
        """``cur_from_key`` (4x4) of frame ``index`` (``image`` (H, W)) by the features
        against the reference, ``key_plane`` the keyframe's plane; None without one.
        ``options`` other feature settings than the tracker's (a finer second try),
        ``predicted`` the predicted ``cur_from_key`` to match in the reference's view by
        (:func:`chained_hypothesis`); the frame's hypothesis is the last one found."""
        b = None if self.reference is None else chained_hypothesis(
            self.reference, image, self.camera, key_plane, options=options or self.options,
            mask=self.mask, region=self.region, predicted=predicted)
        if b is not None or self.current is None or self.current[0] != index:
            self.current = None if b is None else (index, b)  # (a failed second try keeps the first)
        return None if b is None else b.cur_from_key

    def lost_pose(self, index: int, prediction: np.ndarray) -> np.ndarray:
        """The pose ``cur_from_key`` (4x4) of lost frame ``index``: ``prediction``, or its
        hypothesis where the two disagree (:meth:`ChainedHypothesis.agrees`). A frame with a hypothesis
        becomes the reference: its pose was confirmed or given by the features."""
        if self.current is None or self.current[0] != index:
            return prediction
        b = self.current[1]
        pose = prediction if b.agrees(prediction, self.camera) else orthonormalize(b.cur_from_key)
        self.reference = TrustedFrame(b.image, pose)
        return pose
