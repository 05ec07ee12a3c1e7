"""What ``monovo init`` and ``monovo track`` check before they write anything.

Each check raises a one-line :class:`~monovo_cli.errors.MonovoError` naming the file, so a
bad side input never leaves a half-made output folder behind:

* :func:`check_covariance_path` -- ``--covariance`` names a file in an existing (or the
  output) directory, not ``-``;
* :func:`existing_results` -- what in an output folder counts as results to protect (not
  the header-only motion.csv of a run that failed before its first frame);
* :func:`groundtruth_poses` -- ``--groundtruth`` is the ground truth of this sequence (its
  timestamps match the frames');
* :func:`model_keyframe` -- ``--model`` was built from this sequence's frame 0 with this
  init.yaml and these options; ``--mask`` applies to its points.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from monovo_cli.core.keyframe import Keyframe, mask_keyframe
from monovo_cli.core.options import TrackOptions
from monovo_cli.errors import InputError, OutputError
from monovo_cli.image.pyramid import num_levels
from monovo_cli.io.sources import FrameSource
from monovo_cli.pipeline.tracking import OpenedSequence

log = logging.getLogger(__name__)

#: TrackOptions fields that shape the ground model that ``monovo init`` builds.
MODEL_FIELDS = {"levels": "--levels", "threshold": "--threshold", "max_points": "--max-points"}


# ----------------------------------------------------------------------------- outputs


def check_covariance_path(covariance: Path | None, out_dir: Path | None) -> None:
    """OutputError unless ``covariance`` can be created: not ``-`` (it is not streamed), not
    a directory, in a directory that exists or is the output directory ``out_dir`` (which
    track creates)."""
    if covariance is None:
        return
    path = Path(covariance)
    if path.name == "-":
        raise OutputError("--covariance -: the covariance is written to a file, not streamed; "
                          "give a file name (e.g. OUTDIR/covariance.csv)")
    if path.is_dir():
        raise OutputError(f"{path}: is a directory; give --covariance a file name")
    parent = path.parent
    if out_dir is not None and parent.resolve() == Path(out_dir).resolve():
        return
    if not parent.is_dir():
        raise OutputError(f"{path}: no such directory {parent}; create it or write the "
                          "covariance into the output directory")


def _data_rows(path: Path) -> int:
    """Non-empty lines after the header of a CSV (0 for an unreadable file)."""
    try:
        with open(path, newline="") as f:
            return max(sum(1 for line in f if line.strip()) - 1, 0)
    except (OSError, UnicodeDecodeError):
        return 0


def existing_results(out_dir: Path, names: Sequence[str]) -> list[str]:
    """The result files ``names`` in ``out_dir`` that a new run must not silently replace.

    A motion.csv without a data row (a run of ours that failed before its first frame, e.g.
    on a bad frame 1) holds nothing to keep, nor do the frame-0-only trajectory files beside
    it: they are not counted, so that rerunning after the failure is not refused.
    """
    out_dir = Path(out_dir)
    found = [n for n in names if (out_dir / n).exists()]
    motion = out_dir / "motion.csv"
    if motion.is_file() and _data_rows(motion) == 0 and "trajectory.png" not in found:
        return []
    return found


# ----------------------------------------------------------------------------- ground truth


def groundtruth_poses(path: Path, frames: FrameSource) -> np.ndarray:
    """The ``--groundtruth`` TUM file's poses (M, 4, 4) matched to the frames by timestamp
    (nearest within :func:`~monovo_cli.evaluation.sync.default_max_dt` of the frames), in frame
    order. InputError when none matches -- the ground truth of another sequence -- and a
    warning when only some do."""
    from monovo_cli.evaluation.sync import default_max_dt, match_timestamps
    from monovo_cli.io.formats import read_tum

    ts, poses = read_tum(Path(path))
    tol = default_max_dt(frames.timestamps)
    ie, ig = match_timestamps(frames.timestamps, ts, max_dt=tol,
                              names=(f"the frames of {frames.dir}", str(path)),
                              hint="give the ground truth of these frames (timestamps from "
                                   "times.txt, the labels or the container; else k for frame k)")
    if len(ie) < len(frames):
        log.warning("%s: matches only %d of the %d frames of %s (timestamps within %g s); "
                    "trajectory.png draws those", path, len(ie), len(frames), frames.dir, tol)
    return poses[ig[np.argsort(ie)]]


# ----------------------------------------------------------------------------- the model


def _differs(a, b, tol: float = 1e-6) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape != b.shape or not np.allclose(a, b, rtol=tol, atol=tol)


def _show(values) -> str:
    return "[" + ", ".join(f"{float(v):.6g}" for v in np.ravel(values)) + "]"


def model_keyframe(path: Path, opened: OpenedSequence, options: TrackOptions,
                   usable: np.ndarray | None) -> Keyframe:
    """The frame-0 keyframe of the ``--model`` file ``path``, checked against the sequence.

    InputError (one line, naming the model) when it was built for another camera, plane or
    region than the sequence's init.yaml, from another frame 0 than its own, or with other
    model options (``--levels``, ``--threshold``, ``--max-points``) than those given in
    ``options`` (None: not given): the model's points are used as built. ``usable`` (the
    ``--mask``, (H, W) bool) is applied to its points.
    """
    from monovo_cli.io.model import image_sha256, load_model, read_model_record

    frames, cfg = opened.frames, opened.config
    cam, region, key = load_model(path)
    record = read_model_record(path)
    fix = "build one with 'monovo init' for these frames and this init.yaml"
    c = cfg.camera
    if (cam.width, cam.height) != (c.width, c.height):
        raise InputError(f"{path}: model is for {cam.width}x{cam.height} frames, init.yaml for "
                         f"{c.width}x{c.height}; build one for these frames with 'monovo init'")
    mine = [cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion]
    theirs = [c.fx, c.fy, c.cx, c.cy, *c.distortion]
    if _differs(mine, theirs):
        raise InputError(f"{path}: model is for another camera (fx fy cx cy distortion "
                         f"{_show(mine)}) than {cfg.path} ({_show(theirs)}); {fix}")
    if _differs(key.plane.normal, cfg.plane.normal) or _differs(key.plane.distance,
                                                                cfg.plane.distance):
        raise InputError(f"{path}: model is for another ground plane (normal "
                         f"{_show(key.plane.normal)}, distance {key.plane.distance:.6g}) than "
                         f"{cfg.path} (normal {_show(cfg.plane.normal)}, distance "
                         f"{cfg.plane.distance:.6g}); {fix}")
    if tuple(region) != tuple(cfg.region):
        raise InputError(f"{path}: model is for ground.region {list(region)}, {cfg.path} says "
                         f"{list(cfg.region)}; {fix}")
    if record["frame0_sha256"] is None:
        log.warning("%s: written by an older monovo, it does not say which frame 0 it was "
                    "built from; it is not checked against %s", path, frames.frame_name(0))
    elif record["frame0_sha256"] != image_sha256(opened.first.image):
        raise InputError(f"{path}: model was built from another frame 0 than "
                         f"{frames.frame_name(0)} (is it the model of another sequence?); {fix}")
    _check_model_options(path, key, cam, record["options"], options)
    if usable is not None:
        key = mask_keyframe(key, cam, usable, min_points=options.min_points)
    elif record["mask_sha256"] is not None:
        log.warning("%s: built with a --mask; give it to track too, or later keyframes use "
                    "every pixel", path)
    return key


def _check_model_options(path: Path, key: Keyframe, camera, built: dict | None,
                         options: TrackOptions) -> None:
    """InputError when an option shaping the model is given to track with another value than
    the model was built with."""
    from monovo_cli.core.keyframe import point_budget

    for field, flag in MODEL_FIELDS.items():
        given = getattr(options, field)
        if given is None:
            continue
        if built is None:
            raise InputError(f"{path}: {flag} given with --model, but the model does not say "
                             f"which {flag} built it (an older monovo); give it to "
                             "'monovo init' instead, or leave out --model")
        init_options = TrackOptions(**{f: built.get(f) for f in MODEL_FIELDS})
        if field == "threshold":
            same, was = abs(given - key.threshold) <= 1e-9 * max(1.0, key.threshold), \
                f"{key.threshold:.6g}"
        elif field == "max_points":
            was_n = point_budget(init_options, camera)
            same, was = point_budget(options, camera) == was_n, str(was_n)
        else:
            was_n = init_options.levels or num_levels(camera.width, camera.height)
            same, was = given == was_n, str(was_n)
        if not same:
            raise InputError(f"{path}: {flag} {given:g} differs from the model's ({was}): "
                             f"--model uses its points as 'monovo init' built them; give "
                             f"{flag} to 'monovo init', or leave out --model")
