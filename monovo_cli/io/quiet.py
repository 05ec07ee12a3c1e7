"""Silencing native libraries' stderr while an image is decoded.

OpenCV logs, and codecs such as libpng print straight to file descriptor 2; a bad frame
would scatter their lines around monovo's one-line error. :func:`quiet_native_stderr`
points fd 2 at /dev/null (and OpenCV's log level at silent) for the time of a decode;
concurrent decodes (threads) share one redirection, reference-counted.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator

import cv2


class _QuietState:
    """TrustedFrame count of the decodes in flight: the first silences, the last restores."""

    lock = threading.Lock()
    depth = 0
    saved_fd: int | None = None
    log_level: int | None = None


def _silence() -> None:
    with _QuietState.lock:
        _QuietState.depth += 1
        if _QuietState.depth > 1:
            return
        _QuietState.log_level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        try:
            sys.stderr.flush()
        except (AttributeError, OSError, ValueError):
            pass
        try:
            saved = os.dup(2)
        except OSError:  # no usable fd 2: nothing to protect
            return
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, 2)
            finally:
                os.close(devnull)
        except OSError:
            os.close(saved)
            return
        _QuietState.saved_fd = saved


def _unsilence() -> None:
    with _QuietState.lock:
        _QuietState.depth -= 1
        if _QuietState.depth > 0:
            return
        if _QuietState.saved_fd is not None:
            os.dup2(_QuietState.saved_fd, 2)
            os.close(_QuietState.saved_fd)
            _QuietState.saved_fd = None
        if _QuietState.log_level is not None:
            cv2.utils.logging.setLogLevel(_QuietState.log_level)
            _QuietState.log_level = None


@contextlib.contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Silence OpenCV's log and native codecs (libpng prints straight to fd 2) while decoding,
    so that a bad frame yields one clean error line on stderr. Concurrent decodes (threads)
    share one redirection."""
    _silence()
    try:
        yield
    finally:
        _unsilence()
