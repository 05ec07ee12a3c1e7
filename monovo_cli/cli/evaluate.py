"""``monovo eval``: every error measure of a trajectory against ground truth, its plots, JSON."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common, with_flags
from monovo_cli.cli.options import BadInput, LibraryDefault, constant_default, overwrite_option

# monovo_cli.io.trajectories.FORMATS, written out so that the command line loads no numpy
# (tests/cli/test_eval.py checks that the two agree)
FORMATS = ("tum", "kitti", "euroc", "trajectory-csv", "motion-csv")


def parse_segments(ctx, param, value):  # noqa: ARG001
    """--segments 1,5,10 -> (1.0, 5.0, 10.0) m."""
    if value is None:
        return None
    import math

    try:
        lengths = tuple(float(v) for v in value.replace(" ", "").split(","))
    except ValueError:
        lengths = ()
    if not lengths or not all(math.isfinite(v) and v > 0 for v in lengths):
        raise click.BadParameter(f"expected positive lengths in metres separated by commas "
                                 f"(e.g. 1,5,10), got {value!r}")
    return tuple(sorted(set(lengths)))


class _Align(click.Choice):
    """--align's choices; a file name taken for one says that --align alone goes last."""

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value not in self.choices:
            self.fail(f"expected none, se3 or sim3, got {value!r}; --align alone (se3) goes after "
                      "the files: monovo eval EST GT --align", param, ctx)
        return super().convert(value, param, ctx)


@click.command(name="eval")
@click.argument("estimate", type=click.Path(path_type=Path))
@click.argument("groundtruth", type=click.Path(path_type=Path))
@click.option("--align", type=_Align(["none", "se3", "sim3"]), is_flag=False,
              flag_value="se3", default=None, metavar="[none|se3|sim3]",
              help="Also give the ATE after aligning the estimate onto the truth (Umeyama): "
                   "se3 (rigid; --align alone), or sim3 (with scale, for an up-to-scale run; "
                   "then every measure uses the scaled estimate); none: no alignment, as "
                   "without --align. The APE, its plots and the trajectory plot use the "
                   "aligned estimate. Give it after the files.")
@click.option("--max-dt", type=click.FloatRange(min=0.0, min_open=True), cls=LibraryDefault,
              default_text=lambda: "{} s, or half the median frame interval if less".format(
                  constant_default("monovo_cli.evaluation.metrics", "MAX_DT")()),
              help="Match each estimated pose to the true pose nearest in time within this "
                   "many seconds.")
@click.option("--segments", callback=parse_segments, metavar="L1,L2,...",
              cls=LibraryDefault,
              default_text=lambda: ",".join(f"{v:g}" for v in constant_default(
                  "monovo_cli.evaluation.segments", "DEFAULT_SEGMENTS")()) + " m",
              help="Segment lengths (m) of the errors by travelled distance (KITTI-style "
                   "translation % and deg/m).")
@click.option("--partial", is_flag=True,
              help="Evaluate over the matched poses even when they are fewer than half of "
                   "the estimate's or span less than half of its time (an error otherwise).")
@click.option("--format", "est_format", type=click.Choice(FORMATS), default=None,
              help="The estimate's format [default: told by its content; a folder is monovo's "
                   "output folder].")
@click.option("--gt-format", type=click.Choice(FORMATS), default=None,
              help="The ground truth's format [default: told by its content].")
@click.option("--times", "est_times", type=click.Path(path_type=Path), default=None,
              metavar="FILE",
              help="Timestamps of the estimate's poses, one per line in s (KITTI's times.txt), "
                   "for a file without its own.")
@click.option("--gt-times", type=click.Path(path_type=Path), default=None, metavar="FILE",
              help="Timestamps of the ground truth's poses, as --times.")
@click.option("--plots", "plots_dir", type=click.Path(path_type=Path), default=None,
              metavar="DIR", help="Write the plots (PNG) into DIR.")
@click.option("--json", "json_out", is_flag=False, flag_value="-", default=None,
              metavar="[FILE]",
              help="Print every figure as JSON instead of the text (--json alone), or write "
                   "it to FILE beside the text.")
@overwrite_option("Replace the --json FILE and the plots in --plots DIR if they exist.")
@common
def eval_(verbosity, estimate, groundtruth, align, max_dt, segments, partial, est_format,
          gt_format, est_times, gt_times, plots_dir, json_out, overwrite):
    """Every error measure of the trajectory ESTIMATE against GROUNDTRUTH.

    \b
    Inputs (told by content, or --format / --gt-format): TUM; KITTI poses (12 numbers a
    line); EuRoC CSV (ns timestamps); monovo's trajectory.csv, motion.csv (composed) or
    output folder (its trajectory.csv; the std of motion.csv beside it is tested too).
    Poses are paired by time, the true pose nearest each estimated one (--max-dt), or,
    when a file has no timestamps (KITTI without --times / --gt-times), by frame: pose i
    of the estimate with pose i of the truth. A match of fewer than half of the
    estimate's poses, or spanning less than half of its time, is an error unless
    --partial. Prints the paper-style per-axis relative-motion errors (Tables 10.1/10.2),
    ATE, drift, APE and RPE statistics, the errors over 1/5/10 m of travelled distance
    (KITTI-style %, deg/m) and the share of errors inside the reported ±3 std:
      monovo eval out demo/groundtruth.tum --plots out/eval
      monovo eval out/trajectory.tum demo/groundtruth.tum --align --json > errors.json
      monovo eval est_00.txt poses/00.txt --segments 100,200,400
      monovo eval out/trajectory.tum gps.tum --max-dt 0.05 --align sim3
    """
    from monovo_cli.pipeline.evaluate import PLOT_NAMES, EvalOptions, run_eval

    json_path = None if json_out in (None, "-") else Path(json_out)
    if not overwrite:  # before the work: every output of monovo is refused if it exists
        if json_path is not None and json_path.exists():
            raise BadInput(f"{json_path}: already exists; use --overwrite or another --json FILE")
        there = [n for n in PLOT_NAMES if plots_dir is not None and (plots_dir / n).exists()]
        if there:
            raise BadInput(f"{plots_dir}: already holds plots ({', '.join(there)}); use "
                           "--overwrite or another --plots DIR")
    options = EvalOptions(align=align or "none", max_dt=max_dt, partial=partial,
                          est_format=est_format, gt_format=gt_format, est_times=est_times,
                          gt_times=gt_times,
                          **({"segments": segments} if segments is not None else {}))
    result = run_eval(estimate, groundtruth, options, plots_dir=plots_dir,
                      json_path=json_path)
    if json_out == "-":
        import json

        click.echo(json.dumps(result.as_dict(), indent=2))
    else:
        click.echo(with_flags(result.text()))
    if result.plots and not verbosity.quiet:
        click.echo(f"wrote {len(result.plots)} plots to {plots_dir}", err=True)
