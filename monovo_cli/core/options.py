"""The tracking options, and options dataclasses from plain (JSON-able) dicts.

:class:`TrackOptions` (with the :class:`EstimatorOptions` and :class:`FeatureOptions` it
nests) is the one place where a tracking default is written. The command line builds it
from the options the user gave (:func:`options_from_dict`). Standard library only, so that
reading or building options loads neither numpy nor OpenCV.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from monovo_cli.geometry.camera import PinholeCamera

T = TypeVar("T")

ALL_POINTS = 1 << 30  # max_points meaning "no cap" (`--max-points all`)


@dataclass(frozen=True)
class EstimatorOptions:
    """Gauss-Newton settings. ``min_msd_decrease`` is the paper's delta_2 (relative);
    ``step_tolerance_px`` and ``relaxation`` are the finest level's (a step moving the points
    less than that is the last; small steps are stretched by ``relaxation``, which leaves the
    fixed point as it is: :mod:`monovo_cli.core.estimator.estimate`)."""

    max_iterations: int = 30
    min_msd_decrease: float = 1e-6
    step_tolerance_px: float = 6e-3
    robust: str = "huber"            # "huber", "tukey" or "none"
    huber_k: float = 1.345
    tukey_c: float = 4.685
    photometric: bool = True
    min_valid_points: int = 20
    interpolation: str = "cubic"     # at the finest level: OpenCV's "cubic" (Keys), "linear"
    #                                  or "lanczos4" (image.sampling.INTERPOLATION)
    relaxation: float = 1.15


@dataclass(frozen=True)
class FeatureOptions:
    """Settings of :func:`~monovo_cli.core.recovery.features.feature_motion`.

    ``level``: detect on pyramid level ``level`` (``cv2.pyrDown``, each halves the image; 0 is
    full resolution), or with None on the coarsest level whose shorter side keeps at least
    ``detect_side`` px (:meth:`level_for`: the cost stays about the same at any frame size);
    ``features``: ORB's cap per image; ``fast_threshold``: ORB's FAST
    threshold (grey levels); ``ratio``: Lowe's ratio test on the two nearest Hamming
    neighbours (0: cross-check instead); ``ransac_px``: RANSAC inlier threshold in
    full-resolution pixels, scaled by ``2**level``; ``min_inliers`` / ``min_inlier_ratio``:
    below these the hypothesis is None; ``min_planarity``: the ratio of the two
    tangent singular values (:mod:`monovo_cli.core.recovery.features`, step 3) below which
    the matched surface is not taken for the plane; ``min_depression_deg``: keyframe pixels
    whose rays dip less than this below the plane's horizon are not used; ``refine``: the
    6-parameter Levenberg-Marquardt on the inliers after the homography; ``seed``: OpenCV's
    RNG seed.
    """

    level: int | None = 0
    detect_side: int = 256
    features: int = 2000
    fast_threshold: int = 10
    ratio: float = 0.8
    ransac_px: float = 3.0
    ransac_iterations: int = 2000
    min_inliers: int = 15
    min_inlier_ratio: float = 0.15
    min_planarity: float = 0.5
    min_depression_deg: float = 1.0
    refine: bool = True
    seed: int = 0

    def level_for(self, camera: PinholeCamera) -> int:
        """The pyramid level features are detected on for frames of ``camera``."""
        if self.level is not None:
            return int(self.level)
        level, side = 0, min(camera.width, camera.height)
        while side // 2 >= self.detect_side:
            level, side = level + 1, side // 2
        return level


def _tracking_features() -> FeatureOptions:
    """The tracker's feature settings: detected on the coarsest pyramid level whose shorter
    side keeps ``detect_side`` px, at most 1000 features per image."""
    return FeatureOptions(level=None, features=1000)


def _fine_features() -> FeatureOptions:
    """The tracker's second feature settings, when the first give no start that passes: the
    coarsest level whose shorter side keeps 512 px, at most 3000 features per image."""
    return FeatureOptions(level=None, detect_side=512, features=3000)


@dataclass(frozen=True)
class TrackOptions:
    """Tracking settings.

    ``threshold`` is the paper's delta_1 (Sobel magnitude, grey levels/px; None: from the
    keyframe's noise); ``max_points`` caps the finest level's observation points (None: one
    per ``pixels_per_point`` pixels of the image, the strongest gradients spread evenly);
    coarser levels, which only bring the estimate within reach of the finest, get one per
    ``coarse_pixels_per_point`` full-resolution pixels (a quarter per level). With a motion
    prediction, estimation starts at pyramid level ``predicted_top_level`` instead of the top
    (the prediction is within a pixel or two).
    Re-anchor when fewer than ``reanchor_fraction`` of the keyframe's points stay in view,
    the model covers < ``min_footprint`` of the image, or the fit has degraded: the frame's
    robust msd (the squared MAD scale of its differences) exceeds ``reanchor_msd_ratio``
    times the first measured against the keyframe (appearance changes, a surface that is not
    quite the plane) -- before the loss checks fire; a region the robust weights reject (a
    shadow fixed in the image) does not count.
    Capture range: after a failed prediction, at a standing start whose "no motion yet"
    fails the checks and while recovering,
    the rotation search and (``feature_hypothesis``) an ORB + homography motion over the
    known plane (:mod:`monovo_cli.core.recovery.features`) each start the direct estimator; the best
    fit wins. ``features`` are that hypothesis' settings, which also bridge lost frames
    (:mod:`monovo_cli.core.recovery.lost_frames`); by default they detect on the coarsest pyramid
    level whose shorter side keeps ``detect_side`` px, with fewer features than
    :class:`FeatureOptions`' own defaults, so that their cost does not grow with the frame
    size. While no start passes the checks, ``fine_features`` (None: none) give two more
    hypotheses from more features on a finer level, the second matched in the reference's
    view warped by the prediction: a texture of look-alike grains (gravel), which the coarse
    level blurs and a few steps' perspective distorts, still matches there. After
    ``reinit_after`` lost frames in a row a fresh keyframe is anchored on the current frame
    (status ``reinit``), its pose bridged by the prediction, its plane the keyframe's carried
    there fused with the mounting prior; with ``resolve_gaps`` the frame is first measured
    directly from the last good frame before the lost ones, and anchored there if that
    passes the checks (the trajectory written at the end then moves the lost frames onto
    the path measured).
    A frame is lost when fewer than ``min_inliers`` of its points agree within the noise,
    its robust msd (the squared MAD scale of its differences) exceeds ``msd_factor`` times
    the recent frames' median and the two images' noise, the normal matrix's condition
    number exceeds ``max_condition``, the finest level hits the iteration cap, or its motion
    exceeds ``max_step_m`` / ``max_step_deg``.
    With ``terrain_grid``, a keyframe that is left gets the heights of its ground off its plane,
    solved with the motion of the frame that leaves it where the images show them
    (:mod:`monovo_cli.core.estimator.terrain_grid`); they are carried to the next keyframe.
    ``keep_initial_tilt`` keeps init.yaml's ground tilt for frame 0 even where init.yaml says
    it is uncertain (``ground.nominal``) and the images contradict it; the images' measurement
    is still reported.
    """

    levels: int | None = None
    threshold: float | None = None
    max_points: int | None = None
    pixels_per_point: int = 2
    coarse_pixels_per_point: int = 16
    predicted_top_level: int = 2
    min_points: int = 50
    reanchor_fraction: float = 0.6
    min_footprint: float = 0.2
    reanchor_msd_ratio: float = 2.0
    feature_hypothesis: bool = True
    reinit_after: int = 2
    resolve_gaps: bool = True
    min_inliers: float = 0.3
    msd_factor: float = 6.0
    max_condition: float = 1e7
    max_step_m: float | None = None
    max_step_deg: float | None = None
    terrain_grid: bool = True
    keep_initial_tilt: bool = False
    estimator: EstimatorOptions = field(default_factory=EstimatorOptions)
    features: FeatureOptions = field(default_factory=_tracking_features)
    fine_features: FeatureOptions | None = field(default_factory=_fine_features)


def options_from_dict(cls: type[T], data: Mapping[str, Any]) -> T:
    """An instance of the frozen dataclass ``cls`` from ``data``, a dict of some of its fields.

    Fields missing from ``data`` keep the dataclass defaults; a field holding a dataclass
    (e.g. ``estimator``) may be given as a dict of some of its own fields, the others keeping
    that field's default, so that ``options_from_dict(cls, dataclasses.asdict(x)) == x`` and
    ``options_from_dict(TrackOptions, {"estimator": {"robust": "tukey"}})`` changes only the
    M-estimator. Values are not converted (JSON keeps ints, floats, strings, None).

    Raises ValueError naming the keys that are not fields (a programming error, not bad input).
    """
    return _replaced(cls(), data)


def _replaced(base: T, data: Mapping[str, Any]) -> T:
    """``base`` (a frozen dataclass instance) with the fields in ``data`` replaced, a nested
    dataclass field from a dict of some of its own fields (see :func:`options_from_dict`)."""
    names = [f.name for f in dataclasses.fields(base)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(map(str, unknown))} of "
                         f"{type(base).__name__}; expected some of {', '.join(names)}")
    values = {}
    for name, value in data.items():
        current = getattr(base, name)
        if dataclasses.is_dataclass(current) and isinstance(value, Mapping):
            value = _replaced(current, value)
        values[name] = value
    return dataclasses.replace(base, **values)
