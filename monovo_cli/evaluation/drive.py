"""Every measure of a drive against ground truth at once, with the series the plots draw.

:func:`evaluate_drive` pairs the poses (by time, or by frame number for trajectories without
timestamps), refuses a match that covers too little of the estimate unless a partial match
is allowed (:func:`~monovo_cli.evaluation.sync.check_coverage`), and takes over the matched
poses: the paper's tables, ATE and drift (:func:`~monovo_cli.evaluation.metrics.
evaluate_matched`), the APE per pose after the alignment asked for, the RPE between
consecutive matched poses (evo's ``evo_rpe --delta 1``), the KITTI-style errors over
segments of travelled distance (:mod:`~monovo_cli.evaluation.segments`) and, when the
tracker's reported standard deviations are given, the per-axis errors of its relative
motions against the ±3σ band (:class:`StdBand`).

Frames: every pose is ``world_from_cam`` (4, 4) in its own trajectory's world; with an
alignment the estimate is mapped onto the truth's world by ``gt_from_est``. With "sim3"
every measure but the unaligned ATE uses the estimate's translations times the scale, and
the reported translation std with them. Pure: arrays in, numbers out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from monovo_cli.errors import InputError
from monovo_cli.evaluation.metrics import (
    AXES,
    Evaluation,
    ate,
    error_stats,
    evaluate_matched,
    relative_pose_errors,
)
from monovo_cli.evaluation.segments import (
    DEFAULT_SEGMENTS,
    DEFAULT_STEP,
    SegmentErrors,
    distances,
    segment_errors,
)
from monovo_cli.evaluation.sync import (
    MIN_COVERAGE,
    check_coverage,
    coverage,
    default_max_dt,
    match_frames,
    match_timestamps,
)
from monovo_cli.geometry.lie import se3_inv, so3_log

SIGMAS = 3.0  # the band's half-width in reported standard deviations


@dataclass(frozen=True)
class StdBand:
    """The tracker's relative motions ``T_{k-1}_k`` against the truth's, per axis.

    ``pose`` (M,) the matched pose index n of each motion (from pose n-1 to n, frames k-1
    and k); ``errors`` (M, 6) signed ``est - gt``, (tx, ty, tz) m and rotation-vector
    components (rx, ry, rz) deg, as the paper's tables take them; ``std`` (M, 6) the
    standard deviations the tracker reported for them, same units; ``sigmas`` the band's
    half-width in std.
    """

    pose: np.ndarray
    errors: np.ndarray
    std: np.ndarray
    sigmas: float = SIGMAS

    def inside(self) -> np.ndarray:
        """(M, 6) bool: ``|error| <= sigmas * std``."""
        return np.abs(self.errors) <= self.sigmas * self.std

    def fraction_inside(self) -> tuple[float, np.ndarray]:
        """The fraction of all per-axis errors inside the band, and per axis (6,)."""
        ins = self.inside()
        if not ins.size:
            return float("nan"), np.full(6, np.nan)
        return float(ins.mean()), ins.mean(axis=0)

    def as_dict(self) -> dict:
        """Plain numbers: ``sigmas``, ``motions``, ``inside_fraction``, and per axis
        ``inside_fraction_by_axis`` and ``normalised_std`` (std of error / reported std:
        1 when the reported std is honest)."""
        total, by_axis = self.fraction_inside()
        norm = np.std(self.errors / self.std, axis=0) if len(self.errors) else np.full(6, np.nan)
        return {"sigmas": self.sigmas, "motions": len(self.pose),
                "inside_fraction": _num(total),
                "inside_fraction_by_axis": {a: _num(v) for a, v in zip(AXES, by_axis)},
                "normalised_std": {a: _num(v) for a, v in zip(AXES, norm)}}


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class DriveEvaluation:
    """Every measure of one drive (module docstring) and the series behind them.

    ``evaluation`` the tables, ATE and drift; ``by_time`` whether poses were paired by
    time (else by frame number); ``keys`` (N,) the matched estimated poses' timestamps (s)
    or frames; ``i_est``, ``i_gt`` (N,) their indices in the two inputs; ``est`` (N, 4, 4)
    the matched estimate mapped onto the truth's world (aligned if asked, scaled with
    "sim3"); ``gt`` (N, 4, 4) the matched truth; ``distance`` (N,) m along the truth from
    the first matched pose; ``ape`` (N,) m the position errors of ``est``; ``rpe_t``,
    ``rpe_r`` (N-1,) m and deg between consecutive matched poses; ``segments`` the
    KITTI-style errors; ``band`` the reported std's test (None without std);
    ``partial`` whether the match covers less than the coverage rule asks.
    """

    evaluation: Evaluation
    by_time: bool
    keys: np.ndarray
    i_est: np.ndarray
    i_gt: np.ndarray
    est: np.ndarray
    gt: np.ndarray
    distance: np.ndarray
    ape: np.ndarray
    rpe_t: np.ndarray
    rpe_r: np.ndarray
    segments: SegmentErrors
    band: StdBand | None
    partial: bool = False

    def as_dict(self) -> dict:
        """Plain numbers for JSON, stable keys: :meth:`Evaluation.as_dict`'s, then
        ``pairing`` ("time" or "frame"), ``partial``, ``ape`` (m, after the alignment),
        ``rpe`` (per consecutive matched pose: ``translation_m``, ``rotation_deg``; each
        rmse/mean/median/std/min/max), ``segments`` (:meth:`SegmentErrors.summary`) and
        ``std_band`` (:meth:`StdBand.as_dict`, or None)."""
        d = self.evaluation.as_dict()
        if not self.by_time:
            d["max_dt_s"] = None
        d.update({
            "pairing": "time" if self.by_time else "frame",
            "partial": self.partial,
            "ape": {"alignment": d["alignment"],
                    "translation_m": {k: _num(v) for k, v in error_stats(self.ape).items()}},
            "rpe": {"delta_poses": 1,
                    "translation_m": {k: _num(v) for k, v in error_stats(self.rpe_t).items()},
                    "rotation_deg": {k: _num(v) for k, v in error_stats(self.rpe_r).items()}},
            "segments": self.segments.summary(),
            "std_band": None if self.band is None else self.band.as_dict(),
        })
        return d


@dataclass(frozen=True)
class ReportedMotions:
    """The tracker's own relative motions, for the std band: ``frames`` (M,) k of each
    motion ``prev_from_cur`` (M, 4, 4) ``T_{k-1}_k`` (m) with its reported ``std`` (M, 6)
    (tx, ty, tz) m and (rx, ry, rz) deg (NaN: none)."""

    frames: np.ndarray
    prev_from_cur: np.ndarray
    std: np.ndarray


def std_band(est_frames: np.ndarray, gt_world_from_cam: np.ndarray, motions: ReportedMotions,
             *, scale: float = 1.0, sigmas: float = SIGMAS) -> StdBand:
    """The :class:`StdBand` of the reported ``motions`` against the truth: for every pair of
    consecutive matched poses n-1, n whose frames (``est_frames`` (N,) ints) are k-1 and k
    and whose motion k has a finite, positive std, the per-axis error of ``T_{k-1}_k``
    against ``inv(G_{n-1}) G_n`` (``gt`` (N, 4, 4)); translations and their std times
    ``scale``."""
    at = {int(k): j for j, k in enumerate(motions.frames)}
    rows, errs, stds = [], [], []
    for n in range(1, len(est_frames)):
        k = int(est_frames[n])
        j = at.get(k)
        if j is None or int(est_frames[n - 1]) != k - 1:
            continue
        s = np.asarray(motions.std[j], float) * np.r_[scale, scale, scale, 1.0, 1.0, 1.0]
        if not (np.all(np.isfinite(s)) and np.all(s > 0)):
            continue
        e, g = motions.prev_from_cur[j], se3_inv(gt_world_from_cam[n - 1]) @ gt_world_from_cam[n]
        err = np.r_[scale * e[:3, 3] - g[:3, 3],
                    np.degrees(so3_log(e[:3, :3]) - so3_log(g[:3, :3]))]
        rows.append(n)
        errs.append(err)
        stds.append(s)
    return StdBand(np.array(rows, dtype=int), np.array(errs).reshape(-1, 6),
                   np.array(stds).reshape(-1, 6), sigmas)


def evaluate_drive(keys_est: np.ndarray, est_world_from_cam: np.ndarray, keys_gt: np.ndarray,
                   gt_world_from_cam: np.ndarray, *, by_time: bool = True,
                   align: str = "none", max_dt: float | None = None,
                   segments: Sequence[float] = DEFAULT_SEGMENTS,
                   segment_step: int = DEFAULT_STEP, partial: bool = False,
                   est_frames: np.ndarray | None = None,
                   motions: ReportedMotions | None = None,
                   names: tuple[str, str] = ("estimate", "ground truth")) -> DriveEvaluation:
    """Every measure of the estimate against the truth (module docstring).

    ``keys_*`` (N,), (M,): timestamps s when ``by_time``, else frame numbers (ints), of the
    poses ``*_world_from_cam`` (N, 4, 4), (M, 4, 4); ``align`` "none", "se3" or "sim3";
    ``max_dt`` s the time tolerance (None: :func:`~monovo_cli.evaluation.sync.
    default_max_dt`); ``segments`` the lengths (m) and ``segment_step`` the first-pose step
    of :func:`~monovo_cli.evaluation.segments.segment_errors`; ``partial`` allows a match
    below the coverage rule; ``est_frames`` (N,) the estimate's frame numbers and
    ``motions`` its reported motions, for the std band. InputError when fewer than 2 poses
    match, or too few without ``partial``.
    """
    est = np.asarray(est_world_from_cam, dtype=float)
    gt = np.asarray(gt_world_from_cam, dtype=float)
    for a, t, name in ((est, keys_est, names[0]), (gt, keys_gt, names[1])):
        if a.ndim != 3 or a.shape[1:] != (4, 4) or len(a) != len(t):
            raise InputError(f"{name}: expected (N, 4, 4) poses with N timestamps, got {a.shape} "
                             f"and {len(t)}")
    tol = float("nan")
    if by_time:
        tol = default_max_dt(keys_est) if max_dt is None else float(max_dt)
        ie, ig = match_timestamps(keys_est, keys_gt, max_dt=tol, names=names)
    else:
        ie, ig = match_frames(keys_est, keys_gt, names=names)
    how = f"within {tol:g} s" if by_time else "by frame number"
    if len(ie) < 2:
        raise InputError(f"{names[0]}: only {len(ie)} pose(s) match the {names[1]} {how}; "
                         "evaluation needs at least 2")
    poses_frac, span_frac = coverage(keys_est, ie)
    if not partial:
        check_coverage(keys_est, ie, by_time=by_time, max_dt=tol, names=names)
    ev = evaluate_matched(est[ie], gt[ig], align=align, max_dt=tol,
                          estimate_poses=len(est), groundtruth_poses=len(gt))
    e, g = est[ie].copy(), gt[ig]
    if ev.alignment is not None:
        e = ev.alignment @ e  # c R p + t on positions; rotations R (c divided out below)
        e[:, :3, :3] /= ev.scale
    ape, _ = ate(e, g)
    rpe_t, rpe_r = relative_pose_errors(e, g)
    band = None
    if motions is not None and est_frames is not None:
        band = std_band(np.asarray(est_frames)[ie], g, motions, scale=ev.scale)
    return DriveEvaluation(
        evaluation=ev, by_time=by_time, keys=np.asarray(keys_est, dtype=float)[ie],
        i_est=ie, i_gt=ig, est=e, gt=g, distance=distances(g), ape=ape, rpe_t=rpe_t,
        rpe_r=rpe_r, segments=segment_errors(e, g, segments, step=segment_step), band=band,
        partial=bool(min(poses_frac, span_frac) < MIN_COVERAGE))
