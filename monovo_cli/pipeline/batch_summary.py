"""``summary.csv`` of a batch: one row per sequence (docs/scale-out.md)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

SUMMARY_FILE = "summary.csv"
SUMMARY_COLUMNS = ("sequence", "frames", "status", "frames_per_s", "mean_msd", "lost", "error",
                   "reanchored", "distance_m", "seconds")


def _cell(value: Any, spec: str) -> str:
    return "" if value is None else format(value, spec)


def summary_rows(results: Sequence[dict[str, Any]]) -> list[list[str]]:
    """``summary.csv`` rows (:data:`SUMMARY_COLUMNS`) of result dicts whose ``sequence`` is
    the name to show."""
    rows = []
    for r in results:
        error = " ".join(str(r.get("error") or "").split())  # one line, whatever it held
        rows.append([r["sequence"], _cell(r.get("frames"), "d"), r["status"],
                     _cell(r.get("fps"), ".2f"), _cell(r.get("mean_msd"), ".4f"),
                     _cell(r.get("lost"), "d"), error, _cell(r.get("reanchored"), "d"),
                     _cell(r.get("distance_m"), ".4f"), _cell(r.get("seconds"), ".2f")])
    return rows


def write_summary(path: Path, results: Sequence[dict[str, Any]]) -> None:
    """Write ``summary.csv`` atomically: a header, then one row per result (see
    :func:`summary_rows`); status ``ok``, ``skipped`` (complete from an earlier run, its
    figures from then), ``failed`` (``error`` says why) or ``pending`` (not run: the batch
    was interrupted)."""
    from monovo_cli.io.atomic import atomic_write_text

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(SUMMARY_COLUMNS)
    w.writerows(summary_rows(results))
    atomic_write_text(Path(path), buf.getvalue())
