"""``monovo init``: the ground model of frame 0, saved for later runs."""

from __future__ import annotations

import click

from monovo_cli.cli.group import common
from monovo_cli.cli.options import (
    MODEL,
    output_option,
    params_option,
    seq_argument,
    topic_option,
    track_options,
)


@click.command()
@seq_argument
@params_option
@topic_option
@output_option("The model file to write (model.npz).")
@track_options(MODEL)
@common
def init(verbosity, seq, params, topic, out, options):
    """Build the ground model and its observation points from frame 0 of SEQ."""
    from monovo_cli.pipeline.track import init_model

    key = init_model(seq, params, out, options, topic=topic)
    if not verbosity.quiet:
        counts = ", ".join(str(len(kl.points)) for kl in key.levels)
        click.echo(f"wrote {out}: {len(key.levels)} levels, observation points {counts}, "
                   f"threshold {key.threshold:.3g}")
