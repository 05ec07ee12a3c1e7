"""The options and arguments shared by the commands, and their validation callbacks.

Each is declared once here; a command lists the ones it takes. A callback turns the text
into the value the library wants or raises ``click.BadParameter`` quoting the bad value.
"""

from __future__ import annotations

from pathlib import Path

import click

# --------------------------------------------------------------------------- every command


def common(f):
    """-q/--quiet and -v/--verbose on every command."""
    f = click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")(f)
    f = click.option("-v", "--verbose", is_flag=True, help="Debug logging and tracebacks.")(f)
    return f


def overwrite_option(help: str):
    """--overwrite, with what it replaces in this command's words."""
    return click.option("--overwrite", is_flag=True, help=help)


def output_option(help: str, *, path: bool = True, required: bool = True):
    """-o/--output, the command's output (a path, or text such as '-' when ``path`` is False)."""
    kind = click.Path(path_type=Path) if path else click.STRING
    return click.option("-o", "--output", "out", type=kind, required=required, help=help)


#: SEQ: a sequence (a directory of frames, or a folder holding frames/ and init.yaml).
seq_argument = click.argument("seq", type=click.Path(path_type=Path))

#: -p/--params: the init.yaml of SEQ.
params_option = click.option("-p", "--params", type=click.Path(path_type=Path), default=None,
                             help="init.yaml [default: the one beside the frames].")


def skip_bad_frames_option(otherwise: str):
    """--skip-bad-frames; ``otherwise`` says what happens without it."""
    return click.option("--skip-bad-frames", is_flag=True,
                        help="Record unreadable frames after the first as lost and go on "
                             f"[default: {otherwise}].")


# --------------------------------------------------------------------------- callbacks


def parse_size(ctx, param, value):  # noqa: ARG001
    """--size WxH -> (width, height) px."""
    if value is None:
        return None
    try:
        w, h = (int(v) for v in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WxH like 512x512, got {value!r}") from None
    return w, h


def parse_max_step(ctx, param, value):  # noqa: ARG001
    """--max-step METRES[,DEGREES] -> (m, deg) with None for what is not given."""
    if value is None:
        return None, None
    try:
        parts = [float(v) for v in value.split(",")]
    except ValueError:
        parts = []
    if not 1 <= len(parts) <= 2 or not all(p > 0 for p in parts):
        raise click.BadParameter(f"expected METRES or METRES,DEGREES (positive), got {value!r}")
    return parts[0], (parts[1] if len(parts) == 2 else None)


def parse_triangle(ctx, param, value):  # noqa: ARG001
    """--triangle x1,y1,x2,y2,x3,y3 -> a (3, 2) array of frame-0 pixels."""
    if value is None:
        return None
    import numpy as np

    try:
        nums = [float(v) for v in value.replace(" ", "").split(",")]
    except ValueError:
        nums = []
    if len(nums) != 6 or not all(np.isfinite(nums)):
        raise click.BadParameter(f"expected 6 numbers x1,y1,x2,y2,x3,y3 (frame-0 pixels), "
                                 f"got {value!r}")
    return np.array(nums).reshape(3, 2)


def relative_name(ctx, param, value):  # noqa: ARG001
    """batch: --prior / --covariance name a file inside each sequence / output folder."""
    if value is not None and (Path(value).is_absolute() or ".." in Path(value).parts):
        raise click.BadParameter(f"with batch, expected a path relative to each sequence's "
                                 f"folder (--prior) or output folder (--covariance), got "
                                 f"{str(value)!r}")
    return value


class MaxPoints(click.ParamType):
    """--max-points: an integer >= 50, or 'all' (no cap)."""

    name = "N|all"

    def convert(self, value, param, ctx):
        if isinstance(value, int):
            return value
        if str(value).strip().lower() == "all":
            from monovo_cli.core.odometry import ALL_POINTS

            return ALL_POINTS
        try:
            n = int(value)
        except ValueError:
            self.fail(f"expected an integer >= 50 or 'all', got {value!r}", param, ctx)
        if n < 50:
            self.fail(f"{n} is smaller than the minimum 50", param, ctx)
        return n


# --------------------------------------------------------------------------- tracking


def tracking_options(f):
    """Options of the sequence loop (track, and batch later)."""
    f = click.option("--covariance", type=click.Path(path_type=Path), default=None,
                     help="Write every frame's 6x6 covariance of (tx..rz) (m, rad) to this CSV.")(f)
    f = click.option("--prior", type=click.Path(path_type=Path), default=None,
                     help="A motion CSV (e.g. wheel odometry) used as each frame's initial guess.")(f)
    f = click.option("--max-step", callback=parse_max_step, default=None, metavar="M[,DEG]",
                     help="Mark a frame lost when its motion exceeds this many metres (and degrees).")(f)
    f = click.option("--no-photometric", is_flag=True,
                     help="Do not estimate a per-frame brightness gain and bias.")(f)
    f = click.option("--mask", type=click.Path(path_type=Path), default=None,
                     help="PNG of the frame size; its non-zero pixels are never used.")(f)
    return f


def model_options(f):
    """Options of the ground model and the estimator (init, track, batch)."""
    f = click.option("--reanchor-fraction", type=click.FloatRange(0.0, 1.0, max_open=True),
                     default=0.6, show_default=True,
                     help="Re-anchor when fewer of the keyframe's points than this stay in view.")(f)
    f = click.option("--robust", type=click.Choice(["huber", "tukey", "none"]), default="huber",
                     show_default=True, help="M-estimator of the IRLS weights.")(f)
    f = click.option("--max-points", type=MaxPoints(), default=None, metavar="N|all",
                     help="Cap on observation points at full resolution (the strongest "
                          "gradients, spread evenly); 'all': every pixel above the threshold "
                          "[default: one per 2 pixels].")(f)
    f = click.option("--threshold", type=click.FloatRange(min=0.0, min_open=True), default=None,
                     help="delta_1: Sobel magnitude (grey levels/px) an observation point needs "
                          "[default: 3x the noise's Sobel std, estimated from frame 0].")(f)
    f = click.option("--levels", type=click.IntRange(1, 8), default=None,
                     help="Pyramid levels [default: until the image is ~32 px].")(f)
    return f


def track_options(levels, threshold, max_points, robust, reanchor_fraction, *,
                  photometric=True, max_step=(None, None)):
    """TrackOptions from the command line's values."""
    from monovo_cli.core.estimate import EstimatorOptions
    from monovo_cli.core.odometry import TrackOptions

    return TrackOptions(levels=levels, threshold=threshold, max_points=max_points,
                        reanchor_fraction=reanchor_fraction, max_step_m=max_step[0],
                        max_step_deg=max_step[1],
                        estimator=EstimatorOptions(robust=robust, photometric=photometric))
