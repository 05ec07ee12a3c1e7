"""An :class:`~monovo_cli.evaluation.metrics.Evaluation` as text: the paper's Tables 10.1 and
10.2 and the trajectory measures (``monovo eval``); a
:class:`~monovo_cli.evaluation.drive.DriveEvaluation` adds APE, RPE, the errors by travelled
distance and the reported std's band (:func:`format_drive`)."""

from __future__ import annotations

import math
from collections.abc import Callable

from monovo_cli.evaluation.drive import DriveEvaluation
from monovo_cli.evaluation.metrics import Evaluation


def _one_notation(values) -> Callable[[float], str]:
    """The format of every number of one table: fixed-point with at least 5 decimals and
    enough for 3 significant digits of its smallest non-zero value, or scientific for all
    when that would take more than 9 decimals -- so a mean and a std side by side always
    read alike."""
    small = min((abs(float(v)) for v in values if v != 0 and math.isfinite(v)), default=1.0)
    decimals = max(5, 2 - math.floor(math.log10(small)))
    if decimals > 9:
        return lambda x: f"{x:.3e}"
    return lambda x: f"{x:.{decimals}f}"


def format_report(ev: Evaluation) -> str:
    """``ev`` as text: the paper-style tables (Tables 10.1 / 10.2, per-axis mean and std of
    the relative-motion errors, m and deg; every number of a table in one notation) and the
    trajectory measures, one per line."""

    lines = [f"{ev.poses} poses matched within {ev.max_dt:g} s (of {ev.estimate_poses} "
             f"estimated, {ev.groundtruth_poses} true), {max(ev.poses - 1, 0)} relative "
             f"motions, true path length {ev.distance_m:.3f} m"]
    if ev.poses < max(ev.estimate_poses, ev.groundtruth_poses):
        lines.append("  (a partial match: the measures cover the matched poses only)")
    if ev.align == "sim3":
        lines.append(f"  estimate scaled by {ev.scale:.6g} (sim3 alignment) for every measure "
                     "but the unaligned ATE")
    lines.append("")
    for title, unit, axes, first in (("translation (Table 10.1)", "m", "TxTyTz", 0),
                                     ("rotation (Table 10.2)", "deg", "wxwywz", 3)):
        part = slice(first, first + 3)
        g = _one_notation([*ev.relative_mean[part], *ev.relative_std[part],
                           ev.relative_mean[part].mean(), ev.relative_std[part].mean()])
        lines += [f"Absolute relative-motion error, {title}",
                  f"  {'axis':<10}{f'mean ({unit})':>14}{f'std ({unit})':>14}"]
        for i in range(3):
            a = f"|E_{axes[2 * i:2 * i + 2]}|"
            lines.append(f"  {a:<10}{g(ev.relative_mean[first + i]):>14}"
                         f"{g(ev.relative_std[first + i]):>14}")
        lines += [f"  {'average':<10}{g(ev.relative_mean[part].mean()):>14}"
                  f"{g(ev.relative_std[part].mean()):>14}", ""]
    lines += ["Trajectory",
              f"  ATE RMSE, no alignment      {ev.ate_rmse:.6f} m (max {ev.ate_max:.6f} m)"]
    if ev.ate_rmse_aligned is not None:
        what = "SE(3) aligned" if ev.align == "se3" else "Sim(3) aligned"
        lines.append(f"  ATE RMSE, {what:<18}{ev.ate_rmse_aligned:.6f} m")
    elif ev.start_offset_m > 1e-6:
        lines.append(f"  (the trajectories start {ev.start_offset_m:.3g} m apart: another "
                     "world frame? aligning them compares their shapes)")
    pct = f"{ev.final_drift_pct:.3f} %" if math.isfinite(ev.final_drift_pct) else "n/a"
    rate = (f"{ev.rotation_drift_deg_per_m:.4f} deg/m"
            if math.isfinite(ev.rotation_drift_deg_per_m) else "n/a")
    lines += [f"  final drift                 {ev.final_drift_m:.6f} m = {pct} of the path",
              f"  final rotation error        {ev.final_rotation_deg:.4f} deg = {rate}"]
    return "\n".join(lines)


def format_drive(dr: DriveEvaluation) -> str:
    """``dr`` as text: :func:`format_report`'s tables (its first line saying how the poses
    were paired), then the APE and RPE statistics, the KITTI-style errors over segments of
    travelled distance and, when the reported std is at hand, the share of per-axis errors
    inside its ±3σ band."""
    lines = format_report(dr.evaluation).split("\n")
    ev = dr.evaluation
    if not dr.by_time:
        lines[0] = (f"{ev.poses} poses paired by frame number (of {ev.estimate_poses} "
                    f"estimated, {ev.groundtruth_poses} true), {max(ev.poses - 1, 0)} relative "
                    f"motions, true path length {ev.distance_m:.3f} m")
    lines += ["", *format_errors(dr)]
    return "\n".join(lines)


def _stats_row(label: str, stats: dict) -> str:
    """One row of statistics in fixed notation, as many decimals as give the largest four
    significant digits (one notation per row, so the columns compare at a glance)."""
    keys = ("rmse", "mean", "median", "std", "max")
    top = max((abs(stats[k]) for k in keys if math.isfinite(stats[k])), default=0.0)
    decimals = max(0, 3 - math.floor(math.log10(top))) if top > 0 else 0
    return f"  {label:<24}" + "".join(f"{stats[k]:>12.{decimals}f}" for k in keys)


def format_errors(dr: DriveEvaluation) -> list[str]:
    """The lines of :func:`format_drive` after the tables: APE, RPE, segments, std band."""
    from monovo_cli.evaluation.metrics import error_stats

    ape_what = {"none": "no alignment", "se3": "SE(3) aligned",
                "sim3": "Sim(3) aligned"}[dr.evaluation.align]
    lines = ["Absolute and relative pose errors (evo's APE; RPE between consecutive poses)",
             f"  {'':<24}" + "".join(f"{k:>12}" for k in ("rmse", "mean", "median", "std",
                                                          "max")),
             _stats_row(f"APE, {ape_what} (m)", error_stats(dr.ape)),
             _stats_row("RPE translation (m)", error_stats(dr.rpe_t)),
             _stats_row("RPE rotation (deg)", error_stats(dr.rpe_r)), ""]
    s = dr.segments.summary()
    starts = ("every matched pose" if s["step_poses"] == 1
              else f"every {s['step_poses']}th matched pose")
    lines.append(f"Errors by travelled distance (KITTI-style; {starts} starts a segment of "
                 "each length)")
    lines.append(f"  {'segment':<12}{'pairs':>8}{'translation (%)':>18}{'rotation (deg/m)':>19}")

    def row(name: str, m: dict) -> str:
        t = "n/a" if m["translation_pct"] is None else f"{m['translation_pct']:.4f}"
        r = "n/a" if m["rotation_deg_per_m"] is None else f"{m['rotation_deg_per_m']:.5f}"
        return f"  {name:<12}{m['segments']:>8}{t:>18}{r:>19}"

    for m in s["by_length"]:
        lines.append(row(f"{m['length_m']:g} m", m))
    lines.append(row("all", s))
    if any(m["segments"] == 0 for m in s["by_length"]):
        lines.append(f"  (n/a: the drive's {dr.evaluation.distance_m:.3g} m hold no segment "
                     "that long)")
    if dr.band is not None:
        total, by_axis = dr.band.fraction_inside()
        lines += ["", f"Reported std: errors inside ±{dr.band.sigmas:g} std "
                      f"({len(dr.band.pose)} relative motions)"]
        if math.isfinite(total):
            lines.append("  " + "  ".join(f"{a} {100 * v:.1f} %" for a, v in
                                          zip(("tx", "ty", "tz", "rx", "ry", "rz"), by_axis))
                         + f"  all {100 * total:.1f} %")
    return lines
