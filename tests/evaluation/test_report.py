"""monovo eval's text: the tables read alike, a mean beside its std."""

import re

import numpy as np

from monovo_cli.evaluation.metrics import Evaluation
from monovo_cli.evaluation.report import format_report


def _evaluation(mean, std) -> Evaluation:
    return Evaluation(poses=10, relative_mean=np.array(mean, float),
                      relative_std=np.array(std, float), ate_rmse=0.01, ate_max=0.02,
                      ate_rmse_aligned=None, alignment=None, distance_m=1.0, final_drift_m=0.01,
                      final_drift_pct=1.0, final_rotation_deg=0.1, rotation_drift_deg_per_m=0.1,
                      estimate_poses=10, groundtruth_poses=10)


def _table_numbers(report: str) -> list[list[str]]:
    """The numbers of each table row (the axis rows and the average)."""
    rows = [ln for ln in report.splitlines() if re.match(r"\s+(\|E_|average)", ln)]
    assert len(rows) == 8
    return [ln.split()[1:] for ln in rows]


def _notation(number: str) -> tuple[str, int]:
    if "e" in number:
        return "scientific", 3
    return "fixed", len(number.split(".")[1])


def test_means_and_stds_share_one_notation_per_table():
    # a mean of millimetres beside stds of micrometres (a near-constant error), and rotation
    # errors of a thousandth of a degree with one exactly zero
    report = format_report(_evaluation([4e-3, 2e-3, 1e-3, 0.03, 0.0, 1e-3],
                                       [2e-6, 3e-6, 1e-6, 0.002, 0.0, 5e-4]))
    rows = _table_numbers(report)
    for table in (rows[:4], rows[4:]):
        notations = {_notation(n) for row in table for n in row}
        assert len(notations) == 1, table
    # 3 significant digits of the smallest: 1e-6 in fixed point
    assert rows[2] == ["0.00100000", "0.00000100"]
    assert all("e" not in n for row in rows for n in row)


def test_tiny_errors_are_all_scientific_and_common_ones_keep_five_decimals():
    rows = _table_numbers(format_report(_evaluation([1e-13, 2e-13, 0.0, 0.01, 0.02, 0.03],
                                                    [1e-14, 1e-14, 0.0, 0.001, 0.002, 0.003])))
    assert rows[0] == ["1.000e-13", "1.000e-14"]
    assert rows[2] == ["0.000e+00", "0.000e+00"]
    assert rows[4] == ["0.01000", "0.00100"]
