"""``monovo init``: the ground model of frame 0, saved for later runs."""

from __future__ import annotations

import click

from monovo_cli.cli.group import common
from monovo_cli.cli.options import (
    MODEL,
    mask_option,
    output_option,
    overwrite_option,
    sequence_inputs,
    track_options,
)


@click.command()
@sequence_inputs
@output_option("The model file to write (model.npz).")
@overwrite_option("Replace the model file if it exists.")
@mask_option
@track_options(MODEL)
@common
def init(verbosity, seq, params, topic, out, overwrite, mask, options):
    """Build the ground model and its observation points from frame 0 of SEQ.

    \b
    The model records the frame 0, init.yaml and options it was built from; 'monovo track
    --model' refuses it for another sequence or init.yaml. Give --mask to track too.
    """
    from monovo_cli.pipeline.track import init_model

    key = init_model(seq, params, out, options, topic=topic, mask=mask, overwrite=overwrite)
    if not verbosity.quiet:
        counts = ", ".join(str(len(kl.points)) for kl in key.levels)
        click.echo(f"wrote {out}: {len(key.levels)} levels, observation points {counts}, "
                   f"threshold {key.threshold:.3g}")
