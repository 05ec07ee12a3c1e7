"""The tracking options, and options dataclasses from plain (JSON-able) dicts.

:class:`TrackOptions` (with the :class:`~monovo_cli.core.estimator.estimate.EstimatorOptions` it
nests) is the one place where a tracking default is written. The command line builds it
from the options the user gave; ``monovo batch`` sends it to its workers as
``dataclasses.asdict(options)`` and rebuilds it there with :func:`options_from_dict`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from monovo_cli.core.estimator.estimate import EstimatorOptions

T = TypeVar("T")

ALL_POINTS = 1 << 30  # max_points meaning "no cap" (`--max-points all`)


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
    Capture range: after a failed prediction, at the standing start and while recovering,
    the rotation search and (``feature_hypothesis``) an ORB + homography motion over the
    known plane (:mod:`monovo_cli.core.recovery.features`) each start the direct estimator; the best
    fit wins. After ``reinit_after`` lost frames in a row a fresh keyframe is anchored on the
    current frame with the mounting plane (status ``reinit``), its pose bridged by the
    prediction.
    A frame is lost when fewer than ``min_inliers`` of its points agree within the noise,
    its msd exceeds ``msd_factor`` times the recent median, the normal matrix's condition
    number exceeds ``max_condition``, the finest level hits the iteration cap, or its motion
    exceeds ``max_step_m`` / ``max_step_deg``.
    With ``relief``, a keyframe that is left gets the heights of its ground off its plane,
    solved with the motion of the frame that leaves it where the images show them
    (:mod:`monovo_cli.core.estimator.relief`); they are carried to the next keyframe.
    With ``smooth``, what is written at the end of a run (trajectory.csv / .tum and the
    terrain products) has each keyframe's segment re-scaled with its plane smoothed over the
    whole drive (:mod:`monovo_cli.mapping.hindsight`); motion.csv stays causal either way.
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
    min_inliers: float = 0.3
    msd_factor: float = 6.0
    max_condition: float = 1e7
    max_step_m: float | None = None
    max_step_deg: float | None = None
    relief: bool = True
    smooth: bool = True
    estimator: EstimatorOptions = field(default_factory=EstimatorOptions)


def options_from_dict(cls: type[T], data: Mapping[str, Any]) -> T:
    """An instance of the frozen dataclass ``cls`` from ``data``, a dict of some of its fields.

    Fields missing from ``data`` keep the dataclass defaults; a field holding a dataclass
    (e.g. ``estimator``) may be given as a dict of some of its own fields, so that
    ``options_from_dict(cls, dataclasses.asdict(x)) == x`` and
    ``options_from_dict(TrackOptions, {"estimator": {"robust": "tukey"}})`` changes only the
    M-estimator. Values are not converted (JSON keeps ints, floats, strings, None).

    Raises ValueError naming the keys that are not fields (a programming error, not bad input).
    """
    defaults = cls()
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(f"unknown option(s) {', '.join(map(str, unknown))} of {cls.__name__}; "
                         f"expected some of {', '.join(names)}")
    values = {}
    for name, value in data.items():
        default = getattr(defaults, name)
        if dataclasses.is_dataclass(default) and isinstance(value, Mapping):
            value = options_from_dict(type(default), value)
        values[name] = value
    return cls(**values)
