"""The eval command's pipeline: two trajectory files in, every error measure and its plots out.

:func:`evaluate_files` reads the estimate and the ground truth (:mod:`monovo_cli.io.
trajectories`: TUM, KITTI poses, EuRoC CSV, monovo's CSVs or output folder), pairs them by
time, or by frame number when either has no timestamps, and evaluates the drive
(:func:`~monovo_cli.evaluation.drive.evaluate_drive`); :func:`write_eval_plots` draws the
result's PNGs (:mod:`monovo_cli.viz.eval_plots`; :func:`eval_plot_images` gives them as
images, for a page that embeds them). Both are what ``monovo eval`` calls, and
what a report embedding the figures calls.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from monovo_cli.core.run import TrackRun
from monovo_cli.errors import OutputError
from monovo_cli.evaluation.drive import DriveEvaluation, ReportedMotions, evaluate_drive
from monovo_cli.evaluation.segments import DEFAULT_SEGMENTS, DEFAULT_STEP
from monovo_cli.io.trajectories import PoseFile, read_pose_file

PLOT_NAMES = ("eval_trajectory.png", "eval_errors_time.png", "eval_errors_distance.png",
              "eval_axes_std.png")


@dataclass(frozen=True)
class EvalOptions:
    """How to evaluate: ``align`` "none", "se3" or "sim3"; ``max_dt`` the time tolerance s
    (None: the default); ``segments`` the segment lengths m and ``segment_step`` the
    first-pose step of the errors by distance; ``partial`` allows a match covering less
    than half of the estimate; ``est_format``/``gt_format`` a format of
    :data:`~monovo_cli.io.trajectories.FORMATS` (None: detected); ``est_times``/``gt_times``
    a times file (one timestamp in s per pose) for a file without timestamps."""

    align: str = "none"
    max_dt: float | None = None
    segments: tuple[float, ...] = DEFAULT_SEGMENTS
    segment_step: int = DEFAULT_STEP
    partial: bool = False
    est_format: str | None = None
    gt_format: str | None = None
    est_times: Path | None = None
    gt_times: Path | None = None


@dataclass(frozen=True)
class EvalResult:
    """The ``estimate`` and ``groundtruth`` as read, the ``drive``'s measures, and the
    ``plots`` written (by :func:`run_eval`)."""

    estimate: PoseFile
    groundtruth: PoseFile
    drive: DriveEvaluation
    plots: tuple[Path, ...] = ()

    def as_dict(self) -> dict:
        """Plain numbers for JSON, stable keys: :meth:`DriveEvaluation.as_dict`'s, and
        ``inputs`` (each file's ``path`` and ``format``)."""
        d = self.drive.as_dict()
        d["inputs"] = {side: {"path": str(pf.path), "format": pf.format}
                       for side, pf in (("estimate", self.estimate),
                                        ("groundtruth", self.groundtruth))}
        return d

    def text(self) -> str:
        """The report as text (:func:`~monovo_cli.evaluation.report.format_drive`)."""
        from monovo_cli.evaluation.report import format_drive

        return format_drive(self.drive)


def evaluate_files(est_path: Path, gt_path: Path, options: EvalOptions | None = None
                   ) -> EvalResult:
    """Every measure of the trajectory in ``est_path`` against ``gt_path``.

    Poses are paired by time when both files have timestamps, else by frame number (a
    KITTI file's line index). With monovo's motion.csv at hand the estimate's reported std
    is tested too. InputError (one line) on a bad file or a match too small.
    """
    o = options or EvalOptions()
    est = read_pose_file(Path(est_path), o.est_format, times=o.est_times)
    gt = read_pose_file(Path(gt_path), o.gt_format, times=o.gt_times)
    by_time = est.timestamps is not None and gt.timestamps is not None
    keys_e = est.timestamps if by_time else est.frames
    keys_g = gt.timestamps if by_time else gt.frames
    motions = None
    if est.motions is not None:
        m = est.motions
        motions = ReportedMotions(m.frames, m.prev_from_cur, m.std)
    drive = evaluate_drive(keys_e, est.world_from_cam, keys_g, gt.world_from_cam,
                           by_time=by_time, align=o.align, max_dt=o.max_dt,
                           segments=o.segments, segment_step=o.segment_step,
                           partial=o.partial, est_frames=est.frames, motions=motions,
                           names=(str(est_path), str(gt_path)))
    return EvalResult(est, gt, drive)


def evaluate_run(run: TrackRun, gt_path: Path, options: EvalOptions | None = None, *,
                 name: str = "the run") -> EvalResult:
    """:func:`evaluate_files` of a run in memory (its ``trajectory``, and its motions with
    their reported std for the band) against ``gt_path``: what ``monovo eval`` gives on the
    files the run writes, without reading them back. ``name`` names the run in messages."""
    o = options or EvalOptions()
    gt = read_pose_file(Path(gt_path), o.gt_format, times=o.gt_times)
    frames = np.asarray(run.index, dtype=np.int64)
    est = PoseFile(Path(name), "run", run.trajectory, run.timestamp, frames)
    std = np.array(run.std, dtype=float)
    std[:, 3:] = np.degrees(std[:, 3:])  # reported as motion.csv's columns: m and deg
    motions = ReportedMotions(frames[1:], run.prev_from_cur[1:], std[1:])
    by_time = gt.timestamps is not None
    drive = evaluate_drive(run.timestamp if by_time else frames, run.trajectory,
                           gt.timestamps if by_time else gt.frames, gt.world_from_cam,
                           by_time=by_time, align=o.align, max_dt=o.max_dt,
                           segments=o.segments, segment_step=o.segment_step,
                           partial=o.partial, est_frames=frames, motions=motions,
                           names=(name, str(gt_path)))
    return EvalResult(est, gt, drive)


def eval_plot_images(result: EvalResult) -> dict[str, np.ndarray]:
    """The plots of ``result`` as BGR uint8 images (H, W, 3), by file name (:data:`PLOT_NAMES`,
    in that order): ``eval_trajectory.png`` (both paths from above, after the alignment
    asked for), ``eval_errors_time.png`` and ``eval_errors_distance.png`` (APE and RPE over
    time or frame, and over distance, with the segment errors), ``eval_axes_std.png``
    (per-axis errors of the reported motions with their ±3σ band; only when the reported
    std is at hand)."""
    from monovo_cli.viz.eval_plots import (
        plot_axis_errors,
        plot_errors_over,
        plot_paths_from_above,
    )

    dr = result.drive
    name = result.estimate.path.name
    x_time = "time (s)" if dr.by_time else "frame"
    ape = {"none": "APE, no alignment (m)", "se3": "APE, SE(3) aligned (m)",
           "sim3": "APE, Sim(3) aligned (m)"}[dr.evaluation.align]
    images = {
        PLOT_NAMES[0]: plot_paths_from_above(
            dr.est[:, :3, 3], dr.gt[:, :3, 3],
            title=f"{name} against {result.groundtruth.path.name}"),
        PLOT_NAMES[1]: plot_errors_over(dr.keys, dr.ape, dr.rpe_t, dr.rpe_r, xlabel=x_time,
                                        title=f"{name}: errors over {x_time.split()[0]}",
                                        ape_label=ape),
        PLOT_NAMES[2]: plot_errors_over(dr.distance, dr.ape, dr.rpe_t, dr.rpe_r,
                                        xlabel="distance travelled (m)", ape_label=ape,
                                        title=f"{name}: errors over distance",
                                        segments=(dr.distance[dr.segments.first],
                                                  100.0 * dr.segments.translation,
                                                  dr.segments.length)),
    }
    if dr.band is not None and len(dr.band.pose):
        images[PLOT_NAMES[3]] = plot_axis_errors(
            dr.keys[dr.band.pose], dr.band.errors, dr.band.std, sigmas=dr.band.sigmas,
            xlabel=x_time, title=f"{name}: relative-motion errors and the reported "
                                 f"±{dr.band.sigmas:g} std")
    return images


def write_eval_plots(result: EvalResult, out_dir: Path) -> list[Path]:
    """The plots of ``result`` (:func:`eval_plot_images`) as PNGs in ``out_dir`` (made if
    missing), each written atomically. Returns the paths written."""
    from monovo_cli.io.video import write_png_atomic

    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputError(f"{out_dir}: is a file; the plots need a folder") from None
    written = []
    for fname, img in eval_plot_images(result).items():
        write_png_atomic(out_dir / fname, img)
        written.append(out_dir / fname)
    return written


def run_eval(est_path: Path, gt_path: Path, options: EvalOptions | None = None, *,
             plots_dir: Path | None = None, json_path: Path | None = None) -> EvalResult:
    """``monovo eval``'s job: :func:`evaluate_files`, then its plots into ``plots_dir``
    (:func:`write_eval_plots`) and its JSON (:meth:`EvalResult.as_dict`) into ``json_path``
    (atomically), each when given."""
    result = evaluate_files(est_path, gt_path, options)
    if json_path is not None:
        import json

        from monovo_cli.io.atomic import atomic_write_text

        atomic_write_text(Path(json_path), json.dumps(result.as_dict(), indent=2) + "\n")
    if plots_dir is not None:
        result = replace(result, plots=tuple(write_eval_plots(result, plots_dir)))
    return result
