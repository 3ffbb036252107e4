"""How many threads a matcher runs on: the ``threads`` knob, its default, and numba's threading layer.

One knob, ``threads=N`` (:func:`cvstereo.matchers.registry.create_matcher`, :func:`cvstereo.match`, ``--threads N``),
sets both thread pools a matcher may use while it runs, numba's (parallel kernels) and OpenCV's (StereoBM, SGBM),
and restores them after: :func:`using_threads`, which :class:`~cvstereo.matchers.protocol.StreamMatcher` enters
around every ``feed`` and ``flush``. The matches do not depend on it (docs/guide/threads.md).

Default (:func:`default_threads`): the cores this process may use, or the environment variable
``CVSTEREO_THREADS`` (read once, at the first use), which the test suite sets to 1 so that its workers do not
compete for the cores. Sweep cells and benchmark children pass ``threads=1`` themselves.

The threading layer: numba's ``workqueue`` layer aborts the process when two Python threads launch parallel
kernels at the same time, which a live run (reader threads and the matcher) or several matchers in threads would
do. The layer chosen here tolerates it: TBB (the ``tbb`` wheel, a dependency where it exists), else OpenMP; only
where neither loads does numba fall back to ``workqueue``, and then parallel runs of this package take turns
(a lock) rather than crash.

The side thread (:func:`side_thread`): one Python thread beside the caller, on which a matcher on several threads
runs the second camera's half of a serial step (its signal level, fused's features: :func:`both_cameras`) while
the caller runs the first. A forked child makes its own.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import importlib
import numbers
import os
import sys
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["MAX_THREADS", "NOT_A_PARAMETER", "THREADS_ENV", "available_cores", "both_cameras", "check_threads",
           "default_threads", "pool_size", "side_thread", "threading_layer", "using_threads"]

#: The environment variable that sets the default of ``threads`` (read once, at the first use).
THREADS_ENV = "CVSTEREO_THREADS"

#: Said where ``threads`` is given as a matcher parameter (it is not one: the matches do not depend on it).
NOT_A_PARAMETER = ("threads is not a matcher parameter: give --threads N on the command line, or threads=N to "
                   "create_matcher / match")

#: The largest ``threads`` taken: beyond any machine's cores, so a larger value is a mistake (a matcher may split
#: its work into that many pieces).
MAX_THREADS = 1024

#: numba's layers that tolerate parallel kernels launched from several Python threads at once.
_THREADSAFE_LAYERS = ("tbb", "omp")

#: The TBB runtime numba's ``tbbpool`` needs, as the ``tbb`` wheel installs it (in the environment's lib folder,
#: where the dynamic linker does not look).
_TBB_LIBRARY = "libtbb.so.12"

#: Held by a parallel run where numba has only the ``workqueue`` layer (see the module's text).
_WORKQUEUE_TURNS = threading.RLock()

#: The side thread (:func:`side_thread`), made at its first use.
_SIDE: list[ThreadPoolExecutor] = []
_SIDE_MADE = threading.Lock()


def side_thread() -> ThreadPoolExecutor:
    """One Python thread beside the caller, for a matcher on several threads to run a second, independent piece of
    a serial step at the same time as the first (each camera's half, in kernels that release the GIL).

    One for the process, made at the first use; several matchers share it (their pieces take turns on it).
    """
    with _SIDE_MADE:
        if not _SIDE:
            _SIDE.append(ThreadPoolExecutor(max_workers=1, thread_name_prefix="cvstereo-side"))
        return _SIDE[0]


def both_cameras(step, *args, side_by_side: bool) -> list:
    """``[step(0, *args), step(1, *args)]``; with ``side_by_side`` the second on :func:`side_thread` while the caller
    runs the first (the two calls must be independent, and release the GIL to gain)."""
    if not side_by_side:
        return [step(0, *args), step(1, *args)]
    second = side_thread().submit(step, 1, *args)
    return [step(0, *args), second.result()]


def _forget_side_thread() -> None:
    """In a forked child: the parent's side thread does not exist there, and work given to its executor would
    wait forever; the child makes its own at its first use."""
    global _SIDE_MADE
    _SIDE.clear()
    _SIDE_MADE = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_side_thread)


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity, which a container or ``taskset`` narrows)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def check_threads(value, *, source: str = "threads") -> int:
    """``value`` as a number of threads: a whole number from 1 to :data:`MAX_THREADS`; a ValueError otherwise.

    Bools, fractions and strings are refused rather than converted (``int(2.5)`` would run 2 threads without a
    word). A value above :func:`available_cores` is taken: the matches do not depend on it, and numba's and
    OpenCV's pools run at most the threads numba has (:func:`using_threads`).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{source}={value!r}: give a whole number of threads >= 1 (e.g. {available_cores()}, "
                         "the cores here).")
    if not 1 <= value <= MAX_THREADS:
        raise ValueError(f"{source}={value}: give a whole number of threads from 1 to {MAX_THREADS} "
                         f"({available_cores()} cores here).")
    return int(value)


def pool_size() -> int:
    """The most threads that run at once: numba's pool (``NUMBA_NUM_THREADS``, the cores unless set otherwise).

    A matcher's ``threads`` above it still splits its work as asked (the matches do not depend on it); numba's
    and OpenCV's counts are capped at it (:func:`using_threads`).
    """
    return int(numba.config.NUMBA_NUM_THREADS)


@functools.cache
def default_threads() -> int:
    """The ``threads`` of a matcher built without one: ``$CVSTEREO_THREADS`` if set, else :func:`available_cores`.

    Read once per process, so that a matcher's thread count does not change under a running program.

    Raises
    ------
    ValueError
        ``CVSTEREO_THREADS`` is set to something else than a whole number from 1 to :data:`MAX_THREADS`.
    """
    text = os.environ.get(THREADS_ENV, "").strip()
    if not text:
        return available_cores()
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"environment variable {THREADS_ENV}={text!r}: give a whole number of threads >= 1, "
                         "or unset it (default: the cores this process may use).") from None
    return check_threads(value, source=f"environment variable {THREADS_ENV}")


def _preload_tbb() -> None:
    """Load the ``tbb`` wheel's runtime by its path (an environment's or a ``--user`` install's lib folder), so
    that numba's ``tbbpool`` finds it by its soname."""
    import site

    if not sys.platform.startswith("linux"):
        return
    for base in (sys.prefix, site.getuserbase()):
        path = os.path.join(base, "lib", _TBB_LIBRARY)
        if os.path.exists(path):
            with contextlib.suppress(OSError):
                ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
                return


def _loadable(module: str) -> bool:
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


@functools.cache
def _choose_layer() -> str:
    """Set numba's threading layer once, before any parallel kernel starts it; return what was chosen.

    ``threadsafe`` is numba's own choice of TBB, else OpenMP; a layer the user set (``NUMBA_THREADING_LAYER``) is
    kept. Without either, ``workqueue`` (and parallel runs take turns: :func:`using_threads`).
    """
    if numba.config.THREADING_LAYER != "default":
        return str(numba.config.THREADING_LAYER)
    _preload_tbb()
    if any(_loadable(f"numba.np.ufunc.{name}pool") for name in _THREADSAFE_LAYERS):
        numba.config.THREADING_LAYER = "threadsafe"
    else:
        numba.config.THREADING_LAYER = "workqueue"
    return str(numba.config.THREADING_LAYER)


def threading_layer() -> str:
    """numba's threading layer for this process: the one running (``tbb``, ``omp``, ``workqueue``) once a parallel
    kernel has started it, else the choice made for it (``threadsafe``: TBB, else OpenMP)."""
    chosen = _choose_layer()
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel kernel has run yet
        return chosen


#: What :func:`using_threads` returns where nothing is to be set: one object, no generator per call (a live
#: stream's small packets each enter it).
_NOTHING_TO_SET = contextlib.nullcontext()


def using_threads(threads: int) -> contextlib.AbstractContextManager[None]:
    """Run the block with numba's and OpenCV's thread counts set to ``threads``; restore them after.

    ``threads == 1`` leaves numba's pool alone (and unstarted): a matcher runs its serial kernels then. Above 1,
    numba's count is that of the calling Python thread (``numba.set_num_threads``). Both are capped at
    :func:`pool_size`. OpenCV's count (``cv2.setNumThreads``) is set only where cv2 is imported already; it is one
    per process, so matchers running in threads at once share the last one set.
    Where numba has only the ``workqueue`` layer, parallel runs take turns.
    """
    if threads == 1:
        cv2 = sys.modules.get("cv2")
        if cv2 is None or cv2.getNumThreads() == 1:
            return _NOTHING_TO_SET
    return _set_threads(threads)


@contextlib.contextmanager
def _set_threads(threads: int) -> Iterator[None]:
    """:func:`using_threads` where a count is to be set."""
    running = min(threads, pool_size())
    restores = []
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and (before_cv := cv2.getNumThreads()) != running:  # unchanged: nothing to restore
        cv2.setNumThreads(running)
        restores.append(lambda: cv2.setNumThreads(before_cv))
    turns = contextlib.nullcontext()
    if threads > 1:
        if _choose_layer() == "workqueue":
            turns = _WORKQUEUE_TURNS
        if (before := numba.get_num_threads()) != running:
            numba.set_num_threads(running)
            restores.append(lambda: numba.set_num_threads(before))
    try:
        with turns:
            yield
    finally:
        for restore in reversed(restores):
            restore()


# Chosen at import: the matchers import this module before any of their parallel kernels can run.
_choose_layer()
