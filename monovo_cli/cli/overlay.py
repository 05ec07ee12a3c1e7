"""``monovo overlay``: the glued-triangle video."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common, progress_bar
from monovo_cli.cli.options import (
    LibraryDefault,
    given,
    keyword_default,
    output_option,
    overwrite_option,
    parse_triangle,
    sequence_inputs,
)


@click.command()
@sequence_inputs
@click.option("-t", "--trajectory", type=click.Path(path_type=Path), required=True,
              help="The trajectory.csv (or .tum) of SEQ from 'monovo track'; status and msd "
                   "come from motion.csv beside it.")
@output_option("overlay.mp4 (H.264), overlay.gif, or a directory for PNG frames.", path=False)
@click.option("--triangle", callback=parse_triangle, default=None, metavar="X1,Y1,X2,Y2,X3,Y3",
              help="Triangle vertices in frame-0 pixels, lifted onto the ground "
                   "[default: equilateral, centred in the ground region].")
@click.option("--points", is_flag=True,
              help="Also draw the observation points, coloured by intensity residual "
                   "(green: within the noise, red: 3 sqrt(2) sigma and more).")
@click.option("--fps", type=click.FloatRange(min=0.1, max=240.0), cls=LibraryDefault,
              default_text=keyword_default("monovo_cli.pipeline.overlay", "overlay_sequence", "fps"),
              help="Frames per second of the MP4 or GIF.")
@click.option("--scale", type=click.FloatRange(0.0, 1.0, min_open=True), cls=LibraryDefault,
              default_text=keyword_default("monovo_cli.pipeline.overlay", "overlay_sequence",
                                           "scale"),
              help="Resize the output frames by this factor (e.g. 0.5 for a small GIF).")
@click.option("--every", type=click.IntRange(min=1), cls=LibraryDefault, metavar="N",
              default_text=keyword_default("monovo_cli.pipeline.overlay", "overlay_sequence",
                                           "every"),
              help="Write every N-th frame only (0, N, 2N, ...); --fps stays the rate of the "
                   "frames written.")
@click.option("--terrain", type=click.Path(path_type=Path), default=None,
              metavar="DIR|heightmap.csv",
              help="Drape the triangle over this height map (heightmap.csv of 'monovo track "
                   "--terrain-out', or its output directory); on the plane where it has no "
                   "data.")
@overwrite_option("Replace the output if it exists.")
@common
def overlay(verbosity, seq, params, topic, trajectory, out, triangle, points, fps, scale, every,
            terrain, overwrite):
    """Render the glued triangle: a triangle on the ground moved with the estimated poses.

    \b
    If the estimates are right it stays glued to the ground (the paper's Figs. 10.4-10.7).
    A new triangle is placed at every keyframe (re-anchored frame) and whenever the
    current one leaves the view, so every frame of a long drive shows one:
      monovo track demo -o out
      monovo overlay demo -t out/trajectory.csv -o out/overlay.mp4
      monovo overlay demo -t out/trajectory.csv -o out/overlay.gif --scale 0.5 --every 2
      monovo track hills -o out --terrain-out
      monovo overlay hills -t out/trajectory.csv -o out/overlay.mp4 --terrain out
    """
    from monovo_cli.pipeline.overlay import overlay_sequence

    with progress_bar(verbosity.quiet, "frame") as bar:
        s = overlay_sequence(seq, params, trajectory, out, triangle_px=triangle, points=points,
                             overwrite=overwrite, topic=topic, terrain=terrain, progress=bar,
                             **given(fps=fps, scale=scale, every=every))
    if not verbosity.quiet:
        click.echo(f"wrote {s.frames} frames to {s.out} in {s.seconds:.1f} s "
                   f"({s.triangles} triangle{'s' if s.triangles > 1 else ''})")
