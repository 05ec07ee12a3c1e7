"""The ``monovo`` command line: parse, set up logging and progress, one library call per command.

Exit status (SPEC): 0 success; 2 bad usage or bad input (one line on stderr, no traceback);
1 internal error; 130 on Ctrl-C, 143 on SIGTERM (what was done is kept on disk).
"""

from __future__ import annotations

import errno
import logging
import signal
import sys
from pathlib import Path
from typing import NoReturn

import click

from monovo_cli import __version__
from monovo_cli.errors import MonovoError

log = logging.getLogger("monovo_cli")


class BadInput(click.ClickException):
    """A MonovoError at the edge: one line on stderr, exit status 2."""

    exit_code = 2


class Terminated(BaseException):
    """SIGTERM arrived (a BaseException, like KeyboardInterrupt, so no ``except Exception``
    in the library swallows it)."""


def _on_sigterm(signum, frame):  # noqa: ARG001
    raise Terminated()


_FULL_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
_ENVIRONMENT_ERRNOS = _FULL_ERRNOS | {errno.EROFS, errno.EIO, errno.EACCES, errno.EPERM}


class MonovoGroup(click.Group):
    """Turns library errors into one-line messages with the SPEC's exit statuses."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except MonovoError as exc:
            if ctx.meta.get("monovo.verbose"):
                log.exception("details")
            raise BadInput(str(exc)) from None
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except KeyboardInterrupt:
            click.echo("monovo: interrupted; the frames done so far are on disk", err=True)
            sys.exit(130)
        except Terminated:
            click.echo("monovo: terminated; the frames done so far are on disk", err=True)
            sys.exit(143)
        except BrokenPipeError:
            # The reader of -o - went away (e.g. '| head'): stop quietly like any Unix
            # filter killed by SIGPIPE; stdout is pointed at /dev/null so that Python's
            # final flush does not complain.
            _silence_stdout()
            sys.exit(141)
        except OSError as exc:
            if exc.errno not in _ENVIRONMENT_ERRNOS:
                _internal_error(ctx, exc)
            if ctx.meta.get("monovo.verbose"):
                log.exception("details")
            # A full disk, a read-only or failing device: the outputs cannot be written,
            # which the user can fix (exit 2), not a bug. No file name: a stream (motion.csv
            # or stdout), whose unflushed rest must not fail again at exit.
            if exc.filename is None:
                _silence_stdout()
            where = f"{exc.filename}: " if exc.filename is not None else "cannot write the outputs: "
            hint = ("; free some space or write elsewhere (the rows done so far are kept)"
                    if exc.errno in _FULL_ERRNOS else "")
            raise BadInput(f"{where}{exc.strerror}{hint}") from None
        except Exception as exc:
            _internal_error(ctx, exc)


def _internal_error(ctx: click.Context, exc: Exception) -> NoReturn:
    """A bug: one line on stderr and exit 1, or the traceback with -v."""
    if ctx.meta.get("monovo.verbose"):
        raise exc
    msg = f"internal error: {type(exc).__name__}: {exc} (run with -v for the traceback)"
    click.echo(f"Error: {msg}", err=True)
    sys.exit(1)


def _silence_stdout() -> None:
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # no real stdout (e.g. CliRunner)
        pass


def _common(f):
    """-q/--quiet and -v/--verbose on every command."""
    f = click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary.")(f)
    f = click.option("-v", "--verbose", is_flag=True, help="Debug logging and tracebacks.")(f)
    return f


def _setup(ctx: click.Context, quiet: bool, verbose: bool) -> None:
    ctx.meta["monovo.verbose"] = verbose
    ctx.meta["monovo.quiet"] = quiet
    level = logging.DEBUG if verbose else (logging.ERROR if quiet else logging.WARNING)
    logging.basicConfig(level=level, format="monovo: %(levelname)s: %(message)s", stream=sys.stderr)
    logging.getLogger("monovo_cli").setLevel(level)
    signal.signal(signal.SIGTERM, _on_sigterm)


class _Progress:
    """A tqdm bar on stderr driven by the library's ``progress(done, total)`` callback."""

    def __init__(self, quiet: bool, unit: str) -> None:
        self.quiet, self.unit, self.bar = quiet, unit, None

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit=self.unit, file=sys.stderr, dynamic_ncols=True,
                            leave=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _track_options(levels, threshold, max_points, robust, reanchor_fraction, *,
                   photometric=True, max_step=(None, None)):
    from monovo_cli.core.estimate import EstimatorOptions
    from monovo_cli.core.odometry import TrackOptions

    return TrackOptions(levels=levels, threshold=threshold, max_points=max_points,
                        reanchor_fraction=reanchor_fraction, max_step_m=max_step[0],
                        max_step_deg=max_step[1],
                        estimator=EstimatorOptions(robust=robust, photometric=photometric))


def _parse_max_step(ctx, param, value):  # noqa: ARG001
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


def _tracking_options(f):
    """Options of the sequence loop (track, and batch later)."""
    f = click.option("--covariance", type=click.Path(path_type=Path), default=None,
                     help="Write every frame's 6x6 covariance of (tx..rz) (m, rad) to this CSV.")(f)
    f = click.option("--prior", type=click.Path(path_type=Path), default=None,
                     help="A motion CSV (e.g. wheel odometry) used as each frame's initial guess.")(f)
    f = click.option("--max-step", callback=_parse_max_step, default=None, metavar="M[,DEG]",
                     help="Mark a frame lost when its motion exceeds this many metres (and degrees).")(f)
    f = click.option("--no-photometric", is_flag=True,
                     help="Do not estimate a per-frame brightness gain and bias.")(f)
    f = click.option("--mask", type=click.Path(path_type=Path), default=None,
                     help="PNG of the frame size; its non-zero pixels are never used.")(f)
    return f


class _MaxPoints(click.ParamType):
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


def _model_options(f):
    f = click.option("--reanchor-fraction", type=click.FloatRange(0.0, 1.0, max_open=True),
                     default=0.6, show_default=True,
                     help="Re-anchor when fewer of the keyframe's points than this stay in view.")(f)
    f = click.option("--robust", type=click.Choice(["huber", "tukey", "none"]), default="huber",
                     show_default=True, help="M-estimator of the IRLS weights.")(f)
    f = click.option("--max-points", type=_MaxPoints(), default=None, metavar="N|all",
                     help="Cap on observation points at full resolution (the strongest "
                          "gradients, spread evenly); 'all': every pixel above the threshold "
                          "[default: one per 2 pixels].")(f)
    f = click.option("--threshold", type=click.FloatRange(min=0.0, min_open=True), default=None,
                     help="delta_1: Sobel magnitude (grey levels/px) an observation point needs "
                          "[default: 3x the noise's Sobel std, estimated from frame 0].")(f)
    f = click.option("--levels", type=click.IntRange(1, 8), default=None,
                     help="Pyramid levels [default: until the image is ~32 px].")(f)
    return f


@click.group(cls=MonovoGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="monovo")
def main() -> None:
    """Monocular visual odometry over planar ground from intensity differences.

    \b
    A camera looks at the ground; monovo estimates its 6-DoF motion frame by frame
    (G. Martinez, intensity-difference based monocular visual odometry). Typical use:
      monovo synth demo --preset drive --frames 100
      monovo track demo -o out            # init.yaml found beside frames/
    """


@main.command()
@click.argument("out", type=click.Path(path_type=Path))
@click.option("--preset", type=click.Choice(["pairs", "drive"]), default="drive", show_default=True)
@click.option("--frames", type=click.IntRange(min=1), default=None,
              help="Frames of the drive, or number of pairs [default: 300 / 100].")
@click.option("--size", default=None, metavar="WxH",
              help="Image size [default: 512x512 drive, 688x544 pairs].")
@click.option("--noise-var", type=click.FloatRange(min=0.0), default=10.0, show_default=True,
              help="Variance of the added Gaussian noise (grey levels^2).")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--texture", type=click.Path(path_type=Path), default=None,
              help="A photo to use as ground texture instead of the procedural one.")
@click.option("--max-translation", type=click.FloatRange(min=0.0), default=None,
              help="pairs: translations uniform in +-this per axis, m [default: 10 m at 100 m].")
@click.option("--exposure", is_flag=True, help="Vary gain and bias from frame to frame.")
@click.option("--clean-frame0", is_flag=True,
              help="Frame 0 (of the drive, of each pair) without noise: the paper's synthetic "
                   "experiment, where the ground's texture is exactly known.")
@click.option("--overwrite", is_flag=True, help="Replace OUT if it exists.")
@_common
@click.pass_context
def synth(ctx, out, preset, frames, size, noise_var, seed, texture, max_translation, exposure,
          clean_frame0, overwrite, quiet, verbose):
    """Write a synthetic sequence with ground truth into OUT."""
    _setup(ctx, quiet, verbose)
    from monovo_cli.synth.write import synthesize

    wh = None
    if size is not None:
        try:
            w, h = (int(v) for v in size.lower().split("x"))
        except ValueError:
            raise click.BadParameter(f"expected WxH like 512x512, got {size!r}",
                                     param_hint="--size") from None
        wh = (w, h)
    if not overwrite and out.is_dir() and any(out.iterdir()):
        from monovo_cli.errors import OutputError

        raise OutputError(f"{out}: already exists and is not empty; use --overwrite or another OUT")
    if overwrite and out.exists():
        import shutil

        if out.is_dir():
            shutil.rmtree(out)
        else:
            out.unlink()
    bar = _Progress(quiet, "frame")
    try:
        s = synthesize(out, preset=preset, frames=frames, size=wh, noise_var=noise_var,
                                 seed=seed, texture=texture, max_translation=max_translation,
                                 exposure=exposure, clean_frame0=clean_frame0, progress=bar)
    finally:
        bar.close()
    if not quiet:
        click.echo(f"wrote {s.sequences} sequence(s) of {s.frames_per_sequence} frames to {out}")


@main.command()
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("-p", "--params", type=click.Path(path_type=Path), default=None,
              help="init.yaml [default: the one beside the frames].")
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), required=True,
              help="The model file to write (model.npz).")
@_model_options
@_common
@click.pass_context
def init(ctx, seq, params, out, levels, threshold, max_points, robust, reanchor_fraction, quiet,
         verbose):
    """Build the ground model and its observation points from frame 0 of SEQ."""
    _setup(ctx, quiet, verbose)
    from monovo_cli.pipeline.track import init_model

    key = init_model(seq, params, out, _track_options(levels, threshold, max_points, robust,
                                                      reanchor_fraction))
    if not quiet:
        counts = ", ".join(str(len(kl.points)) for kl in key.levels)
        click.echo(f"wrote {out}: {len(key.levels)} levels, observation points {counts}, "
                   f"threshold {key.threshold:.3g}")


@main.command()
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("-p", "--params", type=click.Path(path_type=Path), default=None,
              help="init.yaml [default: the one beside the frames].")
@click.option("-o", "--output", "out", required=True,
              help="Output directory, or '-' to stream motion.csv rows to stdout.")
@click.option("--model", type=click.Path(path_type=Path), default=None,
              help="A model.npz from 'monovo init' to start from.")
@click.option("--overwrite", is_flag=True, help="Replace results already in the output directory.")
@click.option("--groundtruth", type=click.Path(path_type=Path), default=None, metavar="GT.tum",
              help="A TUM ground truth to draw beside the estimate in trajectory.png.")
@click.option("--skip-bad-frames", is_flag=True,
              help="Record unreadable frames after the first as lost and go on "
                   "[default: stop with an error, keeping the rows done].")
@_tracking_options
@_model_options
@_common
@click.pass_context
def track(ctx, seq, params, out, model, overwrite, skip_bad_frames, levels, threshold, max_points,
          robust, reanchor_fraction, quiet, verbose, groundtruth, mask, no_photometric, max_step,
          prior, covariance):
    """Estimate the motion of every frame of SEQ; write motion.csv and the trajectory.

    With -o DIR also trajectory.png, the path seen from above on the ground plane.
    """
    _setup(ctx, quiet, verbose)
    from monovo_cli.pipeline.track import track_sequence

    to_stdout = out == "-"
    bar = _Progress(quiet, "frame")
    try:
        s = track_sequence(seq, params, None if to_stdout else Path(out),
                           _track_options(levels, threshold, max_points, robust, reanchor_fraction,
                                          photometric=not no_photometric, max_step=max_step),
                           groundtruth=groundtruth, mask=mask, prior=prior, covariance=covariance,
                           model=model, overwrite=overwrite, skip_bad_frames=skip_bad_frames,
                           progress=bar)
    finally:
        bar.close()
    if not quiet:
        click.echo(f"tracked {s.frames} frames in {s.seconds:.1f} s ({s.fps:.1f} frames/s): "
                   f"mean msd {s.mean_msd:.2f}, {s.reanchored} re-anchored, {s.lost} lost, "
                   f"path length {s.distance_m:.3f} m"
                   + ("" if to_stdout else f"; outputs in {out}"), err=to_stdout)


def _parse_triangle(ctx, param, value):  # noqa: ARG001
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


@main.command()
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("-p", "--params", type=click.Path(path_type=Path), default=None,
              help="init.yaml [default: the one beside the frames].")
@click.option("-t", "--trajectory", type=click.Path(path_type=Path), required=True,
              help="The trajectory.csv (or .tum) of SEQ from 'monovo track'; status and msd "
                   "come from motion.csv beside it.")
@click.option("-o", "--output", "out", required=True,
              help="overlay.mp4 (H.264), overlay.gif, or a directory for PNG frames.")
@click.option("--triangle", callback=_parse_triangle, default=None, metavar="X1,Y1,X2,Y2,X3,Y3",
              help="Triangle vertices in frame-0 pixels, lifted onto the ground "
                   "[default: equilateral, centred in the ground region].")
@click.option("--points", is_flag=True,
              help="Also draw the observation points, coloured by intensity residual "
                   "(green: within the noise, red: 3 sqrt(2) sigma and more).")
@click.option("--fps", type=click.FloatRange(min=0.1, max=240.0), default=10.0, show_default=True)
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@_common
@click.pass_context
def overlay(ctx, seq, params, trajectory, out, triangle, points, fps, overwrite, quiet, verbose):
    """Render the glued triangle: a triangle on the ground moved with the estimated poses.

    \b
    If the estimates are right it stays glued to the ground (the paper's Figs. 10.4-10.7):
      monovo track demo -o out
      monovo overlay demo -t out/trajectory.csv -o out/overlay.mp4
    """
    _setup(ctx, quiet, verbose)
    from monovo_cli.pipeline.overlay import overlay_sequence

    bar = _Progress(quiet, "frame")
    try:
        s = overlay_sequence(seq, params, trajectory, out, triangle_px=triangle, points=points,
                             fps=fps, overwrite=overwrite, progress=bar)
    finally:
        bar.close()
    if not quiet:
        click.echo(f"wrote {s.frames} frames to {s.out} in {s.seconds:.1f} s")


@main.command(name="eval")
@click.argument("estimate", type=click.Path(path_type=Path))
@click.argument("groundtruth", type=click.Path(path_type=Path))
@click.option("--align", is_flag=True,
              help="Also give the ATE after a rigid SE(3) alignment (Umeyama, no scale).")
@click.option("--json", "as_json", is_flag=True, help="Print the measures as JSON.")
@_common
@click.pass_context
def eval_(ctx, estimate, groundtruth, align, as_json, quiet, verbose):
    """Error tables of the trajectory ESTIMATE against GROUNDTRUTH (both TUM files).

    \b
    Poses are matched by timestamp (both files must hold the same ones). Prints the
    paper-style per-axis relative-motion errors (Tables 10.1/10.2), the absolute
    trajectory error, the final drift and the rotation drift:
      monovo eval out/trajectory.tum demo/groundtruth.tum --align
    """
    _setup(ctx, quiet, verbose)
    from monovo_cli.core.evaluate import evaluate, format_report
    from monovo_cli.io.formats import read_tum

    ts_e, est = read_tum(estimate)
    ts_g, gt = read_tum(groundtruth)
    ev = evaluate(ts_e, est, ts_g, gt, align=align, names=(str(estimate), str(groundtruth)))
    if as_json:
        import json

        click.echo(json.dumps(ev.as_dict(), indent=2))
    else:
        click.echo(format_report(ev))


def _relative_name(ctx, param, value):  # noqa: ARG001
    """batch: --prior / --covariance name a file inside each sequence / output folder."""
    if value is not None and (Path(value).is_absolute() or ".." in Path(value).parts):
        raise click.BadParameter(f"with batch, expected a path relative to each sequence's "
                                 f"folder (--prior) or output folder (--covariance), got "
                                 f"{str(value)!r}")
    return value


@main.command()
@click.argument("root", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), required=True,
              help="OUTROOT: each sequence's outputs go to OUTROOT/<its path under ROOT>/, "
                   "plus OUTROOT/summary.csv.")
@click.option("--glob", "pattern", default=None, metavar="PATTERN",
              help="The sequences are the directories under ROOT matching PATTERN "
                   "(e.g. 'sol*/navcam', '**/left') [default: every folder holding frames/ "
                   "and init.yaml].")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Sequences tracked at once, one process each [default: the number of cores; "
                   "with --scheduler, the cluster's workers].")
@click.option("--scheduler", default=None, metavar="ADDR",
              help="Run on this Dask scheduler (tcp://HOST:8786); needs pip install "
                   "'monovo[dask]', and the workers must see ROOT and OUTROOT at the same paths.")
@click.option("--dask", "use_dask", is_flag=True,
              help="Run on a local Dask cluster of --workers processes.")
@click.option("--resume", is_flag=True,
              help="Skip the sequences whose outputs are complete (done.json checks out); "
                   "redo the others.")
@click.option("--overwrite", is_flag=True, help="Redo every sequence, replacing its outputs.")
@click.option("--skip-bad-frames", is_flag=True,
              help="Record unreadable frames after the first as lost and go on "
                   "[default: the sequence fails].")
@_tracking_options
@_model_options
@_common
@click.pass_context
def batch(ctx, root, out, pattern, workers, scheduler, use_dask, resume, overwrite,
          skip_bad_frames, mask, no_photometric, max_step, prior, covariance, levels, threshold,
          max_points, robust, reanchor_fraction, quiet, verbose):
    """Track every sequence under ROOT (each a folder holding frames/ and init.yaml).

    \b
    Outputs as 'monovo track' in OUTROOT/<relative path>/, then done.json last;
    OUTROOT/summary.csv has a row per sequence (status ok / skipped / failed).
    A failed sequence never stops the others. --prior and --covariance name a file
    inside each sequence folder / output folder; --mask is one PNG for all.
    Exit status: 0 all done; 2 some sequences had bad input (after finishing the
    rest); 1 some failed on an internal error or a lost worker.
      monovo batch archive -o results --workers 2
      monovo batch archive -o results --resume
      monovo batch archive -o results --scheduler tcp://head:8786
    """
    _setup(ctx, quiet, verbose)
    import contextlib

    from monovo_cli.pipeline.batch import run_batch

    if resume and overwrite:
        raise click.UsageError("--resume and --overwrite exclude each other: --resume keeps "
                               "the complete sequences, --overwrite redoes all")
    for name, value in (("--prior", prior), ("--covariance", covariance)):
        try:
            _relative_name(ctx, None, value)
        except click.BadParameter as exc:
            exc.param_hint = name
            raise
    options = {"levels": levels, "threshold": threshold, "max_points": max_points,
               "robust": robust, "reanchor_fraction": reanchor_fraction,
               "photometric": not no_photometric, "max_step_m": max_step[0],
               "max_step_deg": max_step[1], "mask": str(mask.resolve()) if mask else None,
               "prior": str(prior) if prior else None,
               "covariance": str(covariance) if covariance else None,
               "skip_bad_frames": skip_bad_frames}
    level = logging.DEBUG if verbose else (logging.ERROR if quiet else logging.WARNING)
    bar = _Progress(quiet, "seq")
    if quiet:
        redirect = contextlib.nullcontext()
    else:  # warnings about failed sequences above the bar, not through it
        from tqdm.contrib.logging import logging_redirect_tqdm

        redirect = logging_redirect_tqdm()
    try:
        with redirect:
            s = run_batch(root, out, options, pattern=pattern, workers=workers,
                          scheduler=scheduler, dask=use_dask, resume=resume, overwrite=overwrite,
                          log_level=level, progress=bar)
    finally:
        bar.close()
    n, failed = len(s.results), s.failed
    if not quiet:
        click.echo(f"{n} sequence(s) in {s.seconds:.1f} s: {s.count('ok')} tracked, "
                   f"{s.count('skipped')} skipped (complete), {len(failed)} failed; "
                   f"summary in {s.summary_path}")
    if verbose:
        for r in s.internal_errors:
            if r.get("traceback"):
                click.echo(f"{r['sequence']}:\n{r['traceback']}", err=True)
    if failed:
        first = failed[0]
        msg = (f"{len(failed)} of {n} sequence(s) failed, first {first['sequence']}: "
               f"{first['error']} (all in {s.summary_path})")
        if s.internal_errors:
            click.echo(f"Error: {msg}", err=True)
            ctx.exit(1)
        raise BadInput(msg)
