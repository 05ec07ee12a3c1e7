"""``monovo synth``: a synthetic sequence with ground truth."""

from __future__ import annotations

from pathlib import Path

import click

from monovo_cli.cli.group import common, progress_bar
from monovo_cli.cli.options import (
    LibraryDefault,
    given,
    keyword_default,
    overwrite_option,
    parse_size,
)


def _default(name: str):
    return keyword_default("monovo_cli.synth.write", "synthesize", name)


@click.command()
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--preset", type=click.Choice(["pairs", "drive", "mer"]), cls=LibraryDefault,
              default_text=_default("preset"),
              help="mer: MER-like 0.6-0.75 m steps and 12-18 deg turns in place, 45 deg field "
                   "of view, over --terrain.")
@click.option("--frames", type=int, default=None,
              help="Frames of the drive (at least 2), or number of pairs (at least 1) "
                   "[default: 300 drive, 100 mer / pairs].")
@click.option("--size", callback=parse_size, default=None, metavar="WxH",
              help="Image size [default: 512x512 drive, 1024x1024 mer, 688x544 pairs].")
@click.option("--terrain", type=click.Choice(["flat", "rolling", "slope", "rocks"]), default=None,
              help="Drive over a ray-cast height field, the rover tilting with it and bobbing "
                   "[default: the plane; flat for mer].")
@click.option("--noise-var", type=click.FloatRange(min=0.0), cls=LibraryDefault,
              default_text=_default("noise_var"),
              help="Variance of the added Gaussian noise (grey levels^2).")
@click.option("--seed", type=int, cls=LibraryDefault, default_text=_default("seed"),
              help="Seed of the random texture, motion and noise (0 or more): the same seed "
                   "writes the same sequence.")
@click.option("--texture", default=None, metavar="PNG|gravel",
              help="A photo to use as ground texture, or a built-in one: procedural [default] "
                   "or gravel.")
@click.option("--max-translation", type=click.FloatRange(min=0.0), default=None,
              help="pairs: translations uniform in +-this per axis, m [default: 10 m at 100 m].")
@click.option("--exposure", is_flag=True, help="Vary gain and bias from frame to frame.")
@click.option("--psf", type=float, cls=LibraryDefault, default_text=_default("psf"),
              metavar="SIGMA_PX",
              help="Blur of the camera's optics before the pixel: the standard deviation of a "
                   "Gaussian point spread function, in pixels (0: none).")
@click.option("--clean-frame0", is_flag=True,
              help="Frame 0 (of the drive, of each pair) without noise: the paper's synthetic "
                   "experiment, where the ground's texture is exactly known.")
@click.option("--init-pose", type=click.Choice(["frame0", "nominal"]), cls=LibraryDefault,
              default_text=_default("init_pose"),
              help="What init.yaml's ground holds for a drive: frame 0's true ground, or the "
                   "rover's nominal mount (written with 'ground.nominal: true').")
@click.option("--crest", type=float, default=None, metavar="METRES",
              help="A drive over --terrain (or mer): frame 0's bobbing height above the mean, "
                   "within +-0.02 m, its pitch and roll at their means [default: frame 0 at a "
                   "crest of the height, pitch and roll, as far from the mean as they bob].")
@overwrite_option("Replace OUT if it exists.")
@common
def synth(verbosity, out, preset, frames, size, terrain, noise_var, seed, texture, max_translation,
          exposure, psf, clean_frame0, init_pose, crest, overwrite):
    """Write a synthetic sequence with ground truth into OUT."""
    from monovo_cli.synth.write import synthesize

    if not overwrite and out.is_dir() and any(out.iterdir()):
        from monovo_cli.errors import OutputError

        raise OutputError(f"{out}: already exists and is not empty; use --overwrite or another OUT")
    if overwrite and out.exists():
        import shutil

        if out.is_dir():
            shutil.rmtree(out)
        else:
            out.unlink()
    with progress_bar(verbosity.quiet, "frame") as bar:
        s = synthesize(out, frames=frames, size=size, texture=texture, terrain=terrain,
                       max_translation=max_translation, exposure=exposure,
                       clean_frame0=clean_frame0, crest=crest, progress=bar,
                       **given(preset=preset, noise_var=noise_var, seed=seed, psf=psf,
                               init_pose=init_pose))
    if not verbosity.quiet:
        click.echo(f"wrote {s.sequences} sequence(s) of {s.frames_per_sequence} frames to {out}")
