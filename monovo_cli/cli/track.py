"""``monovo track``: every frame's motion, motion.csv and the trajectory."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common, continue_advice, kept_on_interrupt, progress_bar
from monovo_cli.cli.options import (
    LOOP,
    checkpoint_every_option,
    given,
    output_option,
    overwrite_option,
    sequence_inputs,
    side_inputs,
    skip_bad_frames_option,
    smooth_option,
    terrain_out_option,
    threads_option,
    track_options,
)


@click.command()
@sequence_inputs
@output_option("Output directory, or '-' to stream motion.csv rows to stdout.", path=False)
@click.option("--model", type=click.Path(path_type=Path), default=None,
              help="A model.npz from 'monovo init' to start from.")
@overwrite_option("Replace results already in the output directory.")
@click.option("--groundtruth", type=click.Path(path_type=Path), default=None, metavar="GT.tum",
              help="A TUM ground truth to draw beside the estimate in trajectory.png and to "
                   "evaluate the run against in report.html.")
@skip_bad_frames_option("stop with an error, keeping the rows done")
@terrain_out_option("with -o DIR")
@checkpoint_every_option("Every N frames write the trajectory files and the state to continue "
                         "from with --resume (with -o DIR)")
@click.option("--resume", is_flag=True,
              help="Continue the run interrupted in -o DIR from its last checkpoint, with the "
                   "same inputs and options; the outputs are those of an uninterrupted run. "
                   "Without a checkpoint, start from frame 0; a finished run is left as it is.")
@threads_option("all cores")
@side_inputs()
@smooth_option
@track_options(LOOP)
@common
def track(verbosity, seq, params, topic, out, model, overwrite, groundtruth, skip_bad_frames,
          terrain_out, checkpoint_every, resume, threads, mask, prior, covariance, smooth, options):
    """Estimate the motion of every frame of SEQ; write motion.csv and the trajectory.

    With -o DIR also trajectory.png, the path seen from above on the ground plane,
    report.html, the run on one page that opens offline, and with --terrain-out the terrain
    products.
    """
    from monovo_cli.pipeline.track import track_sequence

    to_stdout = out == "-"
    if to_stdout and (terrain_out or groundtruth is not None):
        from monovo_cli.errors import InputError

        why = ("--terrain-out writes files" if terrain_out else
               "--groundtruth is drawn beside the estimate in trajectory.png, a file")
        raise InputError(f"{why}: give an output directory (-o DIR), not -o -")
    if resume and (to_stdout or overwrite):
        from monovo_cli.errors import InputError

        raise InputError("--resume continues the run in an output directory: give -o DIR, "
                         "not -o -" if to_stdout else
                         "--resume continues the run in -o DIR, --overwrite starts it afresh: "
                         "give one of them")
    if to_stdout:
        kept_on_interrupt("the rows of the frames done so far went to stdout; no file was "
                          "written")
    elif checkpoint_every != 0:  # (0: no checkpoint to continue from)
        kept_on_interrupt(f"the frames done so far are in {out}; {continue_advice(resume, overwrite)}")

    def say_resumed(frame: int, total: int) -> None:
        if verbosity.quiet:
            return
        click.echo(f"monovo: resuming at frame {frame} of {total} from the checkpoint in {out}"
                   if frame else f"monovo: no checkpoint in {out}; starting at frame 0 of {total}",
                   err=True)

    with progress_bar(verbosity.quiet, "frame") as bar:
        s = track_sequence(seq, params, None if to_stdout else Path(out), options,
                           groundtruth=groundtruth, mask=mask, prior=prior, covariance=covariance,
                           model=model, overwrite=overwrite, skip_bad_frames=skip_bad_frames,
                           topic=topic, terrain_out=terrain_out, progress=bar,
                           resume=resume, resumed=say_resumed,
                           **given(smooth=smooth, checkpoint_every=checkpoint_every,
                                   threads=threads))
    if s is None:
        if not verbosity.quiet:
            click.echo(f"nothing to resume: the run in {out} is finished")
        _exit_as_finished(Path(out))
        return
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


def _exit_as_finished(out: Path) -> None:
    """A finished run found again by --resume exits as it did: 3 when more than half of its
    frames (motion.csv's rows) were lost, so a retry loop sees the same outcome."""
    from monovo_cli.core.status import FrameStatus, mostly_lost
    from monovo_cli.io.formats import read_motion_stats

    statuses = [status for status, _ in read_motion_stats(out / "motion.csv").values()]
    lost = sum(s == FrameStatus.LOST for s in statuses)
    if mostly_lost(lost, len(statuses)):
        click.echo(f"monovo: {lost} of {len(statuses)} frames lost (more than half); outputs "
                   f"kept in {out}", err=True)
        click.get_current_context().exit(3)
