"""The options and arguments shared by the commands, and their validation callbacks.

Each is declared once here; a command lists the ones it takes. A callback turns the text
into the value the library wants or raises ``click.BadParameter`` quoting the bad value.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

import monovo_cli.core.options as core_options
from monovo_cli.cli.library_source import library_value

# --------------------------------------------------------------------------- every command


@dataclass
class Verbosity:
    """-q/--quiet and -v/--verbose, given before the command's name (``monovo -q track``),
    after it (``monovo track -q``) or both: the ``obj`` of the group's click context, which
    the command's context shares."""

    quiet: bool = False
    verbose: int = 0  # how many -v: 1 what the run does (INFO), 2 debugging (DEBUG)


def _set_verbosity(ctx: click.Context, param: click.Parameter, value: bool | int) -> None:
    verbosity = ctx.ensure_object(Verbosity)  # on the group's context when it parses first
    if param.name == "verbose":
        verbosity.verbose += int(value or 0)
    elif value:
        verbosity.quiet = True


def verbosity_options(f):
    """-q/--quiet and -v/--verbose, on the group and on every command (see :class:`Verbosity`)."""
    f = click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_set_verbosity,
                     help="No progress bar, no summary; warnings and errors still print.")(f)
    return click.option("-v", "--verbose", count=True, default=None, expose_value=False,
                        callback=_set_verbosity,
                        help="Say what the run does (keyframes, the ground measured, timing) "
                             "and show an internal error's traceback; -vv also debug logging "
                             "and the traceback of any error.")(f)


class BadInput(click.ClickException):
    """A MonovoError at the edge: one line on stderr, exit status 2."""

    exit_code = 2


def overwrite_option(help: str):
    """--overwrite, with what it replaces in this command's words."""
    return click.option("--overwrite", is_flag=True, help=help)


def output_option(help: str, *, path: bool = True, required: bool = True):
    """-o/--output, the command's output (a path, or text such as '-' when ``path`` is False)."""
    kind = click.Path(path_type=Path) if path else click.STRING
    return click.option("-o", "--output", "out", type=kind, required=required, help=help)


#: SEQ: a sequence (a directory of frames, or a folder holding frames/ and init.yaml).
seq_argument = click.argument("seq", type=click.Path(path_type=Path))

#: --topic: the image topic of a ROS bag SEQ.
topic_option = click.option("--topic", default=None, metavar="NAME",
                            help="The image topic when SEQ is a ROS bag (sensor_msgs/Image or "
                                 "CompressedImage) [default: its only image topic].")

#: -p/--params: the init.yaml of SEQ.
params_option = click.option("-p", "--params", type=click.Path(path_type=Path), default=None,
                             help="init.yaml [default: the one beside the frames].")


def sequence_inputs(f):
    """SEQ, -p/--params and --topic: a sequence and its init.yaml (init, track, overlay)."""
    return seq_argument(params_option(topic_option(f)))


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
    """--max-step METRES[,DEGREES] -> (m, deg or None); None when not given."""
    if value is None:
        return None
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
    """--max-points: 'all' (no cap), or an integer at least TrackOptions' ``min_points`` (a
    keyframe with fewer points is refused)."""

    name = "N|all"

    def convert(self, value, param, ctx):
        if str(value).strip().lower() == "all":
            return core_options.ALL_POINTS
        least = core_options.TrackOptions().min_points
        try:  # text from the command line, a number from --config
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise ValueError(value)
            n = int(value)
        except (ValueError, TypeError):
            self.fail(f"expected an integer >= {least} or 'all', got {value!r}", param, ctx)
        if n < least:
            self.fail(f"{n} is smaller than the minimum {least}", param, ctx)
        return n


# --------------------------------------------------------------------------- library defaults


class LibraryDefault(click.Option):
    """An option whose default is written in the library only.

    Its click default is None, "not given": the command passes on only what was given
    (see :func:`given`) and the library's own default applies to the rest. Help shows the
    library's default as ``default_text()`` returns it, looked up only when help is shown
    (read from the library's source, see :func:`library_value`, so that help loads neither
    numpy nor OpenCV); None shows nothing.
    """

    def __init__(self, *args, default_text: Callable[[], str | None], **kwargs) -> None:
        super().__init__(*args, default=None, **kwargs)
        self.default_text = default_text

    def get_help_extra(self, ctx: click.Context):
        extra = super().get_help_extra(ctx)
        text = self.default_text()
        if text is not None:
            extra["default"] = text
        return extra


def keyword_default(module: str, function: str, name: str) -> Callable[[], str]:
    """``default_text`` of :class:`LibraryDefault`: the default of the keyword argument
    ``name`` of ``module.function`` (see :func:`library_value`)."""

    def text() -> str:
        return str(library_value(module, function, name))

    return text


def constant_default(module: str, name: str) -> Callable[[], object]:
    """The module-level constant ``module.name`` (see :func:`library_value`), looked up when
    called."""

    def value() -> object:
        return library_value(module, None, name)

    return value


def given(**values: Any) -> dict[str, Any]:
    """The keyword arguments that were given (are not None), to pass on to the library."""
    return {k: v for k, v in values.items() if v is not None}


# --------------------------------------------------------------------------- tracking


def track_default(field: str) -> Any:
    """The default of the TrackOptions field ``field`` (dotted: ``estimator.robust``)."""
    value = core_options.TrackOptions()
    for part in field.split("."):
        value = getattr(value, part)
    return value


class TrackOption(LibraryDefault):
    """An option setting the TrackOptions field ``field`` (dotted for a nested one), or the
    fields of a tuple ``field`` from a tuple value. Help shows the dataclass default unless
    ``default_text`` says it in words."""

    def __init__(self, *args, field: str | tuple[str, ...],
                 default_text: Callable[[], str | None] | None = None, **kwargs) -> None:
        super().__init__(*args, default_text=default_text or self._dataclass_default, **kwargs)
        self.field = field

    def _dataclass_default(self) -> str | None:
        if self.is_flag or isinstance(self.field, tuple):
            return None
        value = track_default(self.field)
        return None if value is None else str(value)


def build_track_options(values: dict[str | tuple[str, ...], Any]):
    """TrackOptions from ``{field: value}`` of :class:`TrackOption` s: the values given (not
    None), the dataclass defaults for the rest."""
    nested: dict[str, Any] = {}
    for field, value in values.items():
        if value is None:
            continue
        pairs = zip(field, value) if isinstance(field, tuple) else [(field, value)]
        for name, v in pairs:
            if v is not None:
                *parents, leaf = name.split(".")
                node = nested
                for parent in parents:
                    node = node.setdefault(parent, {})
                node[leaf] = v
    return core_options.options_from_dict(core_options.TrackOptions, nested)


def _max_step_default() -> str:
    """--max-step's default in words: the TrackOptions limits, or no limit."""
    metres, degrees = track_default("max_step_m"), track_default("max_step_deg")
    if metres is None:
        return "no limit"
    return f"{metres:g}" + ("" if degrees is None else f",{degrees:g}")


def _track_option(*decls: str, **attrs: Any):
    return click.option(*decls, cls=TrackOption, **attrs)


_TRACK_OPTIONS = {
    "levels": _track_option(
        "--levels", field="levels", type=click.IntRange(1, 8), help="Pyramid levels.",
        default_text=lambda: "until the image is ~{} px".format(
            keyword_default("monovo_cli.image.pyramid", "num_levels", "min_size")())),
    "threshold": _track_option(
        "--threshold", field="threshold", type=click.FloatRange(min=0.0, min_open=True),
        help="delta_1: Sobel magnitude (grey levels/px) an observation point needs.",
        default_text=lambda: "3x the noise's Sobel std, estimated from frame 0"),
    "max_points": _track_option(
        "--max-points", field="max_points", type=MaxPoints(), metavar="N|all",
        help="Cap on observation points at full resolution (the strongest gradients, spread "
             f"evenly), at least {track_default('min_points')} (a keyframe needs as many); "
             "'all': every pixel above the threshold.",
        default_text=lambda: f"one per {track_default('pixels_per_point')} pixels"),
    "robust": _track_option(
        "--robust", field="estimator.robust", type=click.Choice(["huber", "tukey", "none"]),
        help="M-estimator of the IRLS weights."),
    "reanchor_fraction": _track_option(
        "--reanchor-fraction", field="reanchor_fraction",
        type=click.FloatRange(0.0, 1.0, max_open=True),
        help="Re-anchor when fewer of the keyframe's points than this stay in view."),
    "photometric": _track_option(
        "--no-photometric", "photometric", field="estimator.photometric", flag_value=False,
        help="Do not estimate a per-frame brightness gain and bias."),
    "terrain_grid": _track_option(
        "--plane-only", "terrain_grid", field="terrain_grid", flag_value=False,
        help="Keep the paper's one plane per keyframe: no terrain grid (heights on a grid) solved "
             "with the motion where the ground is not flat."),
    "keep_initial_tilt": _track_option(
        "--keep-tilt", "keep_initial_tilt", field="keep_initial_tilt", flag_value=True,
        help="Keep init.yaml's ground tilt for frame 0 even where the first frames' images "
             "contradict it (the measured tilt is still logged at -v and kept in run.yaml)."),
    "max_step": _track_option(
        "--max-step", field=("max_step_m", "max_step_deg"), callback=parse_max_step,
        metavar="M[,DEG]", default_text=_max_step_default,
        help="Mark a frame lost when its motion exceeds this many metres (and degrees)."),
}
#: The options that shape the ground model, its observation points (init): what a model.npz
#: holds and 'track --model' uses as it was built.
MODEL = ("levels", "threshold", "max_points")
#: ... and the choices of the tracking (track, batch), which a model does not hold.
LOOP = (*MODEL, "robust", "reanchor_fraction", "photometric", "terrain_grid", "keep_initial_tilt",
        "max_step")


def track_options(names: tuple[str, ...]):
    """The TrackOptions options ``names`` (:data:`MODEL` or :data:`LOOP`) on a command,
    which receives them as one argument ``options``: a TrackOptions with the values given
    and the dataclass defaults for the rest, so that no default is written here."""

    def decorate(f):
        @functools.wraps(f)
        def command(*args, **kwargs):
            params = click.get_current_context().command.params
            values = {p.field: kwargs.pop(p.name) for p in params if isinstance(p, TrackOption)}
            return f(*args, options=build_track_options(values), **kwargs)

        for name in reversed(names):
            command = _TRACK_OPTIONS[name](command)
        return command

    return decorate


#: --no-smooth: an output choice, not a tracking one (track, batch); the command passes it on
#: only when given (``given(smooth=smooth)``).
smooth_option = click.option(
    "--no-smooth", "smooth", cls=LibraryDefault, flag_value=False, default_text=lambda: None,
    help="Write trajectory.csv/.tum (and the terrain products) as the motions were streamed, "
         "without re-scaling them with the keyframe planes smoothed over the whole drive.")

def terrain_out_option(where: str):
    """--terrain-out: the terrain products too (track, batch); ``where`` they are written."""
    return click.option(
        "--terrain-out", is_flag=True,
        help=f"Also write what tracking learned of the ground ({where}): terrain.ply "
             "(the keyframes' points with intensity, world frame) and the driven strip's "
             "heights above frame 0's ground, heightmap.png and heightmap.csv.")


def checkpoint_every_option(help: str):
    """--checkpoint-every N (track, batch), with what it writes in this command's words."""
    return click.option(
        "--checkpoint-every", type=click.IntRange(min=0), metavar="N", cls=LibraryDefault,
        default_text=keyword_default("monovo_cli.pipeline.track", "track_sequence",
                                     "checkpoint_every"),
        help=f"{help}; 0: only at the end, no checkpoint.")


def threads_option(default: str):
    """--threads N, the threads of one run (track; batch: of each sequence's), ``default``
    in words."""
    return click.option(
        "--threads", type=click.IntRange(min=1), metavar="N", cls=LibraryDefault,
        default_text=lambda: default,
        help="Threads for one run: OpenCV's while tracking, and from 2 on, frames are decoded "
             "on a thread of their own while the one before is estimated. The outputs are the "
             "same bytes whatever N.")


#: --mask: pixels never used (init, track, batch).
mask_option = click.option("--mask", type=click.Path(path_type=Path), default=None,
                           help="PNG of the frame size; its non-zero pixels are never used.")


def side_inputs(*, batch: bool = False):
    """--mask, --prior and --covariance (track, batch); with ``batch``, --prior and
    --covariance name a file inside each sequence / output folder."""
    check = relative_name if batch else None

    def decorate(f):
        f = click.option("--covariance", type=click.Path(path_type=Path), default=None,
                         callback=check, help="Write every frame's 6x6 covariance of (tx..rz) "
                                              "(m, deg, as motion.csv) to this CSV.")(f)
        f = click.option("--prior", type=click.Path(path_type=Path), default=None,
                         callback=check, help="A motion CSV (e.g. wheel odometry) used as each "
                                              "frame's initial guess.")(f)
        return mask_option(f)

    return decorate
