"""An :class:`~monovo_cli.evaluation.metrics.Evaluation` as text: the paper's Tables 10.1 and
10.2 and the trajectory measures (``monovo eval``)."""

from __future__ import annotations

import math
from collections.abc import Callable

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
