"""benchmarks.held_out's sweep picks a constant's value by its errors on the tuning set alone.

The errors are a fake table (no tracking): the value in place must win or lose on its
errors like any other, not by a margin a challenger has to beat or a veto only it holds.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import held_out
from monovo_cli.core.options import TrackOptions

CONST = held_out.Constant("reanchor_msd_ratio", (1.5, 2.0, 3.0, 5.0), "nowhere",
                          option="reanchor_msd_ratio")
SEQS = [Path(name) for name in ("desk", "ramp", "flat", "rolling", "mer")]


def _sweep(monkeypatch, table: dict[float, list[float]]) -> float:
    """The value ``sweep`` chooses when ``table`` gives each value's final errors (% of the
    path) on the five sequences."""

    def error_pct(seq, options):
        return table[options.reanchor_msd_ratio][SEQS.index(seq)]

    monkeypatch.setattr(held_out, "error_pct", error_pct)
    return held_out.sweep(CONST, {}, SEQS)


def test_in_place_value_is_the_one_the_table_says():
    assert TrackOptions().reanchor_msd_ratio == 2.0  # the fake tables below count on it


@pytest.mark.parametrize("table, best", [
    # better by 5 % on every sequence: the value in place must not be kept by a margin
    ({1.5: [1.2] * 5, 2.0: [1.0] * 5, 3.0: [0.95] * 5, 5.0: [1.1] * 5}, 3.0),
    # a third of the error on four sequences, 2.5x on the fifth: the geometric mean decides
    # (no veto that only the value in place holds)
    ({1.5: [1.2] * 5, 2.0: [1.0] * 5, 3.0: [1.1] * 5, 5.0: [0.3, 0.3, 0.3, 0.3, 2.5]}, 5.0),
    # a tie with the value in place: the first in the order swept (the smallest) wins
    ({1.5: [0.8, 1.0, 1.0, 1.0, 1.25], 2.0: [1.0, 1.0, 1.0, 1.0, 1.0], 3.0: [1.1] * 5,
      5.0: [1.2] * 5}, 1.5),
])
def test_sweep_chooses_by_the_errors_alone(monkeypatch, table, best):
    assert _sweep(monkeypatch, table) == best


def test_sweep_keeps_the_value_in_place_when_it_is_best(monkeypatch):
    table = {1.5: [1.2] * 5, 2.0: [1.0] * 5, 3.0: [1.01] * 5, 5.0: [0.5, 2.0, 2.0, 2.0, 2.0]}
    assert _sweep(monkeypatch, table) == 2.0


def test_errors_below_the_floor_are_equal(monkeypatch):
    """Errors under FLOOR_PCT cannot decide: a value ahead only there ties, and the tie goes
    to the first value swept whatever the value in place."""
    low = held_out.FLOOR_PCT / 10
    table = {1.5: [held_out.FLOOR_PCT] * 5, 2.0: [low] * 5, 3.0: [low] * 5, 5.0: [1.0] * 5}
    assert _sweep(monkeypatch, table) == 1.5
