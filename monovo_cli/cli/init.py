"""``monovo init``: the ground model of frame 0, saved for later runs."""

from __future__ import annotations

import click

from monovo_cli.cli.group import common
from monovo_cli.cli.options import (
    MODEL,
    TrackOption,
    mask_option,
    output_option,
    overwrite_option,
    sequence_inputs,
    track_options,
)


class _InitCommand(click.Command):
    """Says of a tracking option given to init where it belongs, not only that init lacks it."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        try:
            return super().parse_args(ctx, args)
        except click.NoSuchOption as exc:
            from monovo_cli.cli.track import track

            if exc.option_name in {o for p in track.params if isinstance(p, TrackOption)
                                   for o in p.opts}:
                exc.message = (f"No such option {exc.option_name} for init: it is a tracking "
                               "choice, which a model does not hold; give it to 'monovo track' "
                               "(with --model too)")
                exc.possibilities = None
            raise


@click.command(cls=_InitCommand)
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
