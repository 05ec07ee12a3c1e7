"""``monovo eval``: error tables of a trajectory against ground truth."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common


@click.command(name="eval")
@click.argument("estimate", type=click.Path(path_type=Path))
@click.argument("groundtruth", type=click.Path(path_type=Path))
@click.option("--align", is_flag=True,
              help="Also give the ATE after a rigid SE(3) alignment (Umeyama, no scale).")
@click.option("--json", "as_json", is_flag=True, help="Print the measures as JSON.")
@common
def eval_(verbosity, estimate, groundtruth, align, as_json):
    """Error tables of the trajectory ESTIMATE against GROUNDTRUTH (both TUM files).

    \b
    Poses are matched by timestamp (both files must hold the same ones). Prints the
    paper-style per-axis relative-motion errors (Tables 10.1/10.2), the absolute
    trajectory error, the final drift and the rotation drift:
      monovo eval out/trajectory.tum demo/groundtruth.tum --align
    """
    from monovo_cli.core.evaluate import evaluate, format_report
    from monovo_cli.io.formats import read_tum

    ts_e, est = read_tum(estimate)
    ts_g, gt = read_tum(groundtruth)
    ev = evaluate(ts_e, est, ts_g, gt, align=align, names=(str(estimate), str(groundtruth)))
    if as_json:
        import json

        click.echo(json.dumps(ev.as_dict(), indent=2))
    else:
        click.echo(format_report(ev))
