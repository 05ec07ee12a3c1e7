"""``monovo batch``: every sequence under a folder, on local processes or a Dask cluster."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import (
    BATCH_FLAG_WORDS,
    FLAG_WORDS,
    BadInput,
    common,
    continue_advice,
    flags_in_log,
    kept_on_interrupt,
    log_level,
    progress_bar,
    with_flags,
)
from monovo_cli.cli.options import (
    LOOP,
    checkpoint_every_option,
    given,
    output_option,
    overwrite_option,
    side_inputs,
    skip_bad_frames_option,
    smooth_option,
    terrain_out_option,
    threads_option,
    topic_option,
    track_options,
)


@click.command()
@click.argument("root", type=click.Path(path_type=Path))
@output_option("OUTROOT: each sequence's outputs go to OUTROOT/<its path under ROOT>/, "
               "plus OUTROOT/summary.csv.")
@click.option("--glob", "pattern", default=None, metavar="PATTERN",
              help="The sequences are the directories under ROOT matching PATTERN "
                   "(e.g. 'sol*/navcam', '**/left') [default: every folder holding frames/ "
                   "and init.yaml; one without init.yaml fails].")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Sequences tracked at once, one process each [default: the number of cores; "
                   "with --scheduler, the cluster's workers].")
@click.option("--scheduler", default=None, metavar="ADDR",
              help="Run on this Dask scheduler (tcp://HOST:8786); needs pip install "
                   "'monovo[dask]', and the workers must see ROOT and OUTROOT at the same paths.")
@click.option("--dask", "use_dask", is_flag=True,
              help="Run on a local Dask cluster of --workers processes.")
@click.option("--resume", is_flag=True,
              help="Skip the sequences whose outputs are complete and succeeded (done.json "
                   "checks out); redo the others, failed ones included.")
@overwrite_option("Redo every sequence, replacing its outputs.")
@skip_bad_frames_option("the sequence fails")
@terrain_out_option("in each sequence's output folder")
@checkpoint_every_option("Every N frames write each sequence's trajectory files and the state "
                         "'monovo track --resume' continues it from (batch --resume redoes an "
                         "unfinished sequence from frame 0)")
@threads_option("1: each worker tracks one sequence on one core")
@topic_option
@side_inputs(batch=True)
@smooth_option
@track_options(LOOP)
@common
def batch(verbosity, root, out, pattern, workers, scheduler, use_dask, resume, overwrite,
          skip_bad_frames, terrain_out, checkpoint_every, threads, topic, mask, prior, covariance,
          smooth, options):
    """Track every sequence under ROOT (each a folder holding frames/ and init.yaml,
    or a video or ROS bag beside an init.yaml).

    \b
    Outputs as 'monovo track' in OUTROOT/<relative path>/, then done.json last;
    OUTROOT/summary.csv has a row per sequence (status ok / skipped / failed).
    A folder holding frames/ but no init.yaml is named and counted failed.
    A failed sequence never stops the others. --prior and --covariance name a file
    inside each sequence folder / output folder; --mask is one PNG for all.
    Exit status (after finishing the rest): 0 all done; 1 some failed on an internal
    error or a lost worker; else 2 some had bad input; else 3 some lost more than half
    of their frames (outputs kept). --resume skips only the sequences done with success
    and tracks the failed ones again, so a rerun gives the same status.
      monovo batch archive -o results --workers 2
      monovo batch archive -o results --resume
      monovo batch archive -o results --scheduler tcp://head:8786
    """
    from monovo_cli.pipeline.batch import run_batch
    from monovo_cli.pipeline.batch_job import JobOptions

    if resume and overwrite:
        raise click.UsageError("--resume and --overwrite exclude each other: --resume keeps "
                               "the complete sequences, --overwrite redoes all")
    kept_on_interrupt(f"the sequences done so far are in {out} (summary.csv lists the pending "
                      f"ones); {continue_advice(resume, overwrite)}")
    job = JobOptions(track=options, mask=str(mask.resolve()) if mask else None,
                     prior=str(prior) if prior else None,
                     covariance=str(covariance) if covariance else None,
                     skip_bad_frames=skip_bad_frames, topic=topic, terrain_out=terrain_out,
                     **given(smooth=smooth, threads=threads, checkpoint_every=checkpoint_every))
    # each failure's warning, above the bar, with the flags put in
    words = (*BATCH_FLAG_WORDS, *FLAG_WORDS)
    with progress_bar(verbosity.quiet, "seq") as bar, \
            flags_in_log("monovo_cli.pipeline.batch", words):
        s = run_batch(root, out, job, pattern=pattern, workers=workers,
                      scheduler=scheduler, dask=use_dask, resume=resume, overwrite=overwrite,
                      log_level=log_level(verbosity), progress=bar)
    n, failed = len(s.results), s.failed
    if not verbosity.quiet:
        click.echo(f"{n} sequence(s) in {s.seconds:.1f} s: {s.count('ok')} tracked, "
                   f"{s.count('skipped')} skipped (complete), {len(failed)} failed; "
                   f"summary in {s.summary_path}")
    if verbosity.verbose:
        for r in s.internal_errors:
            if r.get("traceback"):
                click.echo(f"{r['sequence']}:\n{r['traceback']}", err=True)
    if failed:
        first = failed[0]
        # Each failure's error was logged above as it came (a warning, -q too): not again.
        msg = with_flags(f"{len(failed)} of {n} sequence(s) failed, first {first['sequence']} "
                         f"(its error above; all in {s.summary_path})", words)
        if s.internal_errors:
            click.echo(f"Error: {msg}", err=True)
            raise click.exceptions.Exit(1)
        if s.input_errors:
            raise BadInput(msg)
        click.echo(f"monovo: {msg}", err=True)  # outputs kept, as monovo track's status 3
        raise click.exceptions.Exit(3)
