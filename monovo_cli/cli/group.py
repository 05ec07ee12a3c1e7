"""The ``monovo`` group: -q/-v, library errors to exit statuses, logging, signals, progress.

Exit status (docs/guide.md "Commands"): 0 success; 2 bad usage or bad input (one line on
stderr, its traceback only with -vv); 1 internal error (its traceback with -v); 3 the data
defeated the tracker (more than half of the frames lost); 130 on Ctrl-C, 143 on SIGTERM
(what was done is kept).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import logging
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NoReturn

import click

from monovo_cli.cli.config import config_option
from monovo_cli.cli.options import BadInput, Verbosity, verbosity_options
from monovo_cli.errors import MonovoError
from monovo_cli.version import __version__

#: The library's root logger: its records go to stderr while a command runs (:func:`common`).
LOGGER = "monovo_cli"

# The library names a setting by what it means (its messages serve any caller); the command
# line names it by its flag. Each pair is (the library's words, the command line's words),
# replaced in every library message a command shows (MonovoGroup, and monovo eval's report).
FLAG_WORDS = (
    ("lower the gradient threshold", "lower --threshold"),  # core.estimator.ground
    ("max_dt sets the tolerance", "--max-dt sets the tolerance"),  # evaluation.sync
    ("aligning them compares their shapes", "--align compares their shapes"),  # evaluation.report
    ("allow a partial match", "give --partial"),  # evaluation.sync
    ("name the format", "name it with --format (the estimate) or --gt-format"),  # io.trajectories
    ("allow overwriting or choose another output", "use --overwrite or another -o"),  # io.video
    ("(a tracking run writes one with its terrain products)",  # io.terrain
     "(written by 'monovo track SEQ -o DIR --terrain-out')"),
    ("name one as the image topic", "name one with --topic"),  # io.sources.bag
    ("rerun recording unreadable frames as lost and replacing these outputs",  # pipeline.tracking
     "rerun with --skip-bad-frames --overwrite to record bad frames as lost and go on"),
    ("rerun recording unreadable frames as lost",  # pipeline.tracking, with -o -
     "rerun with --skip-bad-frames to record bad frames as lost and go on"),
)


#: The key of ``click.Context.meta`` under which a command says what an interruption keeps
#: (:func:`kept_on_interrupt`); the default is files on disk.
KEPT_ON_INTERRUPT = "monovo.kept_on_interrupt"


def kept_on_interrupt(what: str) -> None:
    """Say, in the message of an interruption of the running command, what it keeps
    (``what``: e.g. "the rows of the frames done went to stdout")."""
    click.get_current_context().meta[KEPT_ON_INTERRUPT] = what


def continue_advice(resume: bool, overwrite: bool) -> str:
    """How to continue an interrupted run of a command that takes --resume, given whether
    it was run with --resume or --overwrite (which exclude each other)."""
    if resume:
        return "continue with the same command"
    return "continue with the same command" + (", --resume in place of --overwrite" if overwrite
                                               else " and --resume")


def _kept(ctx: click.Context) -> str:
    return ctx.meta.get(KEPT_ON_INTERRUPT, "the frames done so far are on disk")


#: monovo batch's words where they differ from :data:`FLAG_WORDS` (tried first): a sequence
#: stopped by a bad frame is redone by --resume, which keeps the complete ones.
BATCH_FLAG_WORDS = (
    ("rerun recording unreadable frames as lost and replacing these outputs",  # pipeline.tracking
     "rerun the batch with --resume --skip-bad-frames to record bad frames as lost and go on"),
)


def with_flags(text: str, words: tuple[tuple[str, str], ...] = FLAG_WORDS) -> str:
    """``text``, a library message, with the settings it names by their meaning named by their
    command-line flags instead (``words``: :data:`FLAG_WORDS`, or a command's own pairs
    before them)."""
    for library, command_line in words:
        text = text.replace(library, command_line)
    return text


class _FlagWords(logging.Filter):
    """Puts the flags into a library log record's message (:func:`with_flags`)."""

    def __init__(self, words: tuple[tuple[str, str], ...]) -> None:
        super().__init__()
        self.words = words

    def filter(self, record: logging.LogRecord) -> bool:
        record.msg, record.args = with_flags(record.getMessage(), self.words), None
        return True


@contextmanager
def flags_in_log(name: str, words: tuple[tuple[str, str], ...] = FLAG_WORDS) -> Iterator[None]:
    """While in the block, the records of the library logger ``name`` name settings by their
    command-line flags (:func:`with_flags` with ``words``), as the command's own error line
    does."""
    logger, words = logging.getLogger(name), _FlagWords(words)
    logger.addFilter(words)
    try:
        yield
    finally:
        logger.removeFilter(words)


class Terminated(BaseException):
    """SIGTERM arrived (a BaseException, like KeyboardInterrupt, so no ``except Exception``
    in the library swallows it)."""


def _on_sigterm(signum, frame):  # noqa: ARG001
    raise Terminated()


_FULL_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
_ENVIRONMENT_ERRNOS = _FULL_ERRNOS | {errno.EROFS, errno.EIO, errno.EACCES, errno.EPERM}


class MonovoGroup(click.Group):
    """Turns library errors into one-line messages with the documented exit statuses."""

    def invoke(self, ctx: click.Context):
        """Run the command; a MonovoError becomes one line with the flags put in (exit 2), an
        environment OSError too, anything else an internal error (exit 1)."""
        try:
            return super().invoke(ctx)
        except MonovoError as exc:
            if _verbose(ctx) >= 2:
                _details()
            raise BadInput(with_flags(str(exc))) from None
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except KeyboardInterrupt:
            click.echo(f"monovo: interrupted; {_kept(ctx)}", err=True)
            sys.exit(130)
        except Terminated:
            click.echo(f"monovo: terminated; {_kept(ctx)}", err=True)
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
            if _verbose(ctx) >= 2:
                _details()
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


def _details() -> None:
    """The traceback of the error being handled, on stderr (-vv), in the form of the log
    lines (the command's log handler is gone by now)."""
    import traceback

    click.echo("monovo: ERROR: details\n" + traceback.format_exc().rstrip(), err=True)


def _verbose(ctx: click.Context) -> int:
    """How many -v were given (0 when none)."""
    verbosity = ctx.find_object(Verbosity)
    return verbosity.verbose if verbosity is not None else 0


def _internal_error(ctx: click.Context, exc: Exception) -> NoReturn:
    """A bug: one line on stderr and exit 1, or the traceback with -v."""
    if _verbose(ctx):
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


def log_level(verbosity: Verbosity) -> int:
    """The ``monovo_cli`` loggers' level: INFO with -v, DEBUG with -vv, else WARNING (-q
    too: it hides the progress and the summary, never a warning)."""
    if verbosity.verbose:
        return logging.DEBUG if verbosity.verbose >= 2 else logging.INFO
    return logging.WARNING


def common(f):
    """-q/--quiet, -v/--verbose (see :class:`Verbosity`) and --config (see
    :mod:`~monovo_cli.cli.config`) on a command; while it runs,
    the library logs to stderr at their level (a handler of the ``monovo_cli`` logger, on the
    stderr of the moment) and SIGTERM stops it cleanly. The command gets the
    :class:`Verbosity` as its first argument. The ``monovo_cli`` logger's level and handlers
    are restored afterwards, so that a command run in-process (CliRunner) leaves no trace."""

    @functools.wraps(f)
    def command(*args, **kwargs):
        verbosity = click.get_current_context().ensure_object(Verbosity)
        level = log_level(verbosity)
        logger = logging.getLogger(LOGGER)
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("monovo: %(levelname)s: %(message)s"))
        saved = logger.level
        logger.setLevel(level)
        logger.addHandler(handler)
        signal.signal(signal.SIGTERM, _on_sigterm)
        try:
            return f(verbosity, *args, **kwargs)
        finally:
            logger.removeHandler(handler)
            logger.setLevel(saved)

    return config_option(verbosity_options(command))


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


def _stderr_is_terminal() -> bool:
    """Whether stderr is a terminal (a bar written to a file or a pipe is only noise)."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # no stderr, or a closed one
        return False


@contextmanager
def progress_bar(quiet: bool, unit: str) -> Iterator[_Progress]:
    """A ``progress(done, total)`` callback drawing a tqdm bar of ``unit`` on stderr (none
    when ``quiet`` or when stderr is not a terminal), closed on the way out whatever
    happens; the library's log lines (-v, warnings) are written above the bar by tqdm, not
    through it."""
    quiet = quiet or not _stderr_is_terminal()
    bar = _Progress(quiet, unit)
    if quiet:
        redirect = contextlib.nullcontext()
    else:
        from tqdm.contrib.logging import logging_redirect_tqdm

        redirect = logging_redirect_tqdm(loggers=[logging.getLogger(LOGGER)])
    try:
        with redirect:
            yield bar
    finally:
        bar.close()


@click.group(cls=MonovoGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="monovo")
@verbosity_options
@config_option
def main() -> None:
    """Monocular visual odometry over planar ground from intensity differences.

    \b
    A camera looks at the ground; monovo estimates its 6-DoF motion frame by frame
    (G. Martinez, intensity-difference based monocular visual odometry). Typical use:
      monovo synth demo --preset drive --frames 100
      monovo track demo -o out            # init.yaml found beside frames/
    """
