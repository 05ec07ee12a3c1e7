"""``monovo track``: every frame's motion, motion.csv and the trajectory."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common, kept_on_interrupt, progress_bar
from monovo_cli.cli.options import (
    LOOP,
    given,
    output_option,
    overwrite_option,
    sequence_inputs,
    side_inputs,
    skip_bad_frames_option,
    smooth_option,
    track_options,
)


@click.command()
@sequence_inputs
@output_option("Output directory, or '-' to stream motion.csv rows to stdout.", path=False)
@click.option("--model", type=click.Path(path_type=Path), default=None,
              help="A model.npz from 'monovo init' to start from.")
@overwrite_option("Replace results already in the output directory.")
@click.option("--groundtruth", type=click.Path(path_type=Path), default=None, metavar="GT.tum",
              help="A TUM ground truth to draw beside the estimate in trajectory.png.")
@skip_bad_frames_option("stop with an error, keeping the rows done")
@click.option("--terrain-out", is_flag=True,
              help="Also write what tracking learned of the ground (with -o DIR): terrain.ply "
                   "(the keyframes' points with intensity, world frame) and the driven strip's "
                   "heights above frame 0's ground, heightmap.png and heightmap.csv.")
@side_inputs()
@smooth_option
@track_options(LOOP)
@common
def track(verbosity, seq, params, topic, out, model, overwrite, groundtruth, skip_bad_frames,
          terrain_out, mask, prior, covariance, smooth, options):
    """Estimate the motion of every frame of SEQ; write motion.csv and the trajectory.

    With -o DIR also trajectory.png, the path seen from above on the ground plane, and with
    --terrain-out the terrain products.
    """
    from monovo_cli.pipeline.track import track_sequence

    to_stdout = out == "-"
    if to_stdout and (terrain_out or groundtruth is not None):
        from monovo_cli.errors import InputError

        why = ("--terrain-out writes files" if terrain_out else
               "--groundtruth is drawn beside the estimate in trajectory.png, a file")
        raise InputError(f"{why}: give an output directory (-o DIR), not -o -")
    if to_stdout:
        kept_on_interrupt("the rows of the frames done so far went to stdout; no file was "
                          "written")
    with progress_bar(verbosity.quiet, "frame") as bar:
        s = track_sequence(seq, params, None if to_stdout else Path(out), options,
                           groundtruth=groundtruth, mask=mask, prior=prior, covariance=covariance,
                           model=model, overwrite=overwrite, skip_bad_frames=skip_bad_frames,
                           topic=topic, terrain_out=terrain_out, progress=bar,
                           **given(smooth=smooth))
    if not verbosity.quiet:
        click.echo(f"tracked {s.frames} frames in {s.seconds:.1f} s ({s.fps:.1f} frames/s): "
                   f"mean msd {s.mean_msd:.2f}, {s.reanchored} re-anchored, {s.reinit} re-initialised, "
                   f"{s.lost} lost, "
                   f"path length {s.path_length:.3f} m"
                   + ("" if to_stdout else f"; outputs in {out}"), err=to_stdout)
    if s.mostly_lost:
        where = "streamed rows kept" if to_stdout else f"outputs kept in {out}"
        click.echo(f"monovo: {s.lost} of {s.frames - 1} frames lost (more than half); {where}",
                   err=True)
        click.get_current_context().exit(3)
