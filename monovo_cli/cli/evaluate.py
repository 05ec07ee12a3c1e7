"""``monovo eval``: error tables of a trajectory against ground truth."""

from __future__ import annotations

import importlib
from pathlib import Path

import click

from monovo_cli.cli.group import common, with_flags
from monovo_cli.cli.options import LibraryDefault


@click.command(name="eval")
@click.argument("estimate", type=click.Path(path_type=Path))
@click.argument("groundtruth", type=click.Path(path_type=Path))
@click.option("--align", type=click.Choice(["none", "se3", "sim3"]), is_flag=False,
              flag_value="se3", default=None, metavar="[se3|sim3]",
              help="Also give the ATE after aligning the estimate onto the truth (Umeyama): "
                   "se3 (rigid; --align alone), or sim3 (with scale, for an up-to-scale run; "
                   "then every measure uses the scaled estimate). Give it after the files.")
@click.option("--max-dt", type=click.FloatRange(min=0.0, min_open=True), cls=LibraryDefault,
              default_text=lambda: "{} s, or half the median frame interval if less".format(
                  importlib.import_module("monovo_cli.evaluation.metrics").MAX_DT),
              help="Match each estimated pose to the true pose nearest in time within this "
                   "many seconds.")
@click.option("--json", "as_json", is_flag=True, help="Print the measures as JSON.")
@common
def eval_(verbosity, estimate, groundtruth, align, max_dt, as_json):
    """Error tables of the trajectory ESTIMATE against GROUNDTRUTH (both TUM files).

    \b
    Each estimated pose is matched to the true pose nearest in time (--max-dt); a run
    covering part of the ground truth is evaluated over the matched poses. Prints the
    paper-style per-axis relative-motion errors (Tables 10.1/10.2), the absolute
    trajectory error, the final drift and the rotation drift:
      monovo eval out/trajectory.tum demo/groundtruth.tum --align
      monovo eval out/trajectory.tum gps.tum --max-dt 0.05 --align sim3
    """
    from monovo_cli.evaluation.metrics import evaluate
    from monovo_cli.evaluation.report import format_report
    from monovo_cli.io.formats import read_tum

    ts_e, est = read_tum(estimate)
    ts_g, gt = read_tum(groundtruth)
    ev = evaluate(ts_e, est, ts_g, gt, align=align or "none", max_dt=max_dt,
                  names=(str(estimate), str(groundtruth)))
    if as_json:
        import json

        click.echo(json.dumps(ev.as_dict(), indent=2))
    else:
        click.echo(with_flags(format_report(ev)))
