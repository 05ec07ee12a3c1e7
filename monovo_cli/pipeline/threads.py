"""One BLAS thread while tracking, so that the outputs do not depend on the thread count.

OpenBLAS (likewise MKL and BLIS) splits a factorisation or a product of large matrices (the
terrain grid's normal equations, over hundreds of vertex heights), and a long dot product, among
its threads, and the order of the floating-point sums follows the split: the last bits of a
result depend on how many threads there are (``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``,
the machine's cores), and after Gauss-Newton iterations and keyframe decisions so does the
trajectory. The environment variables are read once, when a library loads; here each BLAS
library loaded in the process is set to one thread through its own API for the time of
:func:`one_blas_thread` (nested or from several Python threads: the first entry sets, the
last exit restores the count found). The tracker's products are skinny (8 x N), which BLAS
threads barely speed up.

OpenCV's thread count needs no such care for the bytes: the OpenCV functions the tracker
calls work per pixel or per point (remap, filters, pyramids, perspectiveTransform) or run
serially (ORB, the matcher, findHomography with its fixed RANSAC seed). It is set for the
time, though (:func:`opencv_threads`): OpenCV's pool has a thread per core by default, and
its idle workers wait by yielding the processor over and over, so a run asked for one
thread (``--threads 1``) kept a second core busy (1.25 cores of CPU time at 256 px, a
fifth of it in the kernel).

A BLAS whose thread count has no known API (Apple's Accelerate) is left as it is: set its
variable (``VECLIB_MAXIMUM_THREADS=1``) before Python starts for the same guarantee.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

log = logging.getLogger(__name__)


# (a part of the library's file name, its (get, set) thread-count functions by the names
# its builds export: numpy's and SciPy's wheels prefix and suffix OpenBLAS's symbols)
_APIS: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("openblas", (("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
                  ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
                  ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
                  ("openblas_get_num_threads", "openblas_set_num_threads"))),
    ("mkl_rt", (("MKL_Get_Max_Threads", "MKL_Set_Num_Threads"),)),
    ("blis", (("bli_thread_get_num_threads", "bli_thread_set_num_threads"),)),
)

_controls: list[tuple[Callable[[], int], Callable[[int], object]]] | None = None


def _library_files() -> list[str]:
    """The files of the shared libraries loaded in the process (Linux), else those bundled
    with numpy's wheel."""
    try:
        with open("/proc/self/maps") as maps:
            return sorted({parts[5].strip() for parts in (line.split(maxsplit=5) for line in maps)
                           if len(parts) == 6 and parts[5].startswith("/")})
    except OSError:
        pass
    import numpy

    base = Path(numpy.__file__).parent
    return [str(p) for folder in (base / ".dylibs", base.parent / "numpy.libs")
            if folder.is_dir() for p in sorted(folder.iterdir())]


def _find_controls() -> list[tuple[Callable[[], int], Callable[[int], object]]]:
    """(get, set) of the thread count of every known BLAS library loaded in the process."""
    import numpy  # noqa: F401  (its BLAS loaded before the search)

    found = []
    mode = getattr(os, "RTLD_NOLOAD", 0)  # only a library already loaded, never a copy
    for path in _library_files():
        name = Path(path).name.lower()
        for part, names in _APIS:
            if part not in name:
                continue
            try:
                lib = ctypes.CDLL(path, mode=mode)
            except OSError:
                continue
            for get_name, set_name in names:
                get, set_ = getattr(lib, get_name, None), getattr(lib, set_name, None)
                if get is not None and set_ is not None:
                    if part == "blis":
                        get.restype, set_.argtypes = ctypes.c_int64, [ctypes.c_int64]
                    else:
                        get.restype, set_.argtypes = ctypes.c_int, [ctypes.c_int]
                    found.append((get, set_))
                    break
    if not found:
        log.debug("no BLAS library with a known thread API is loaded: its thread count is "
                  "left as the environment set it")
    return found


class _Held:
    """A setting held while any of nested or concurrent bodies runs: the first to enter makes
    it, the last to leave undoes it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._undo: Callable[[], None] | None = None

    @contextlib.contextmanager
    def held(self, make: Callable[[], Callable[[], None]]) -> Iterator[None]:
        """Run the body with the setting ``make`` makes (it returns the undoing) in force."""
        with self._lock:
            if self._depth == 0:
                self._undo = make()
            self._depth += 1
        try:
            yield
        finally:
            with self._lock:
                self._depth -= 1
                if self._depth == 0 and self._undo is not None:
                    self._undo()
                    self._undo = None


_blas, _opencv = _Held(), _Held()


def _blas_on_one_thread() -> Callable[[], None]:
    global _controls
    if _controls is None:
        _controls = _find_controls()
    saved = [(set_, int(get())) for get, set_ in _controls]
    for set_, _ in saved:
        set_(1)

    def restore() -> None:
        for set_, count in saved:
            set_(max(count, 1))
    return restore


def one_blas_thread() -> contextlib.AbstractContextManager[None]:
    """Run the body with every loaded BLAS library on one thread; their thread counts are
    restored when the last body (of nested or concurrent ones) is left."""
    return _blas.held(_blas_on_one_thread)


def opencv_threads(count: int) -> contextlib.AbstractContextManager[None]:
    """Run the body with OpenCV's pool at ``count`` threads (1: none beside the caller); of
    nested or concurrent bodies the first sets the count, and the count found is restored
    when the last is left."""
    import cv2

    def set_count() -> Callable[[], None]:
        saved = cv2.getNumThreads()
        cv2.setNumThreads(max(int(count), 1))
        return lambda: cv2.setNumThreads(saved)
    return _opencv.held(set_count)
