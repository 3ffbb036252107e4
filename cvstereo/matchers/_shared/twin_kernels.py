"""One numba kernel compiled twice, serially and in parallel: a matcher runs the parallel compile only on more than
one thread (docs/guide/threads.md), so that its one-thread path is the serial code and starts no thread pool."""

from __future__ import annotations

import types

from numba import njit

__all__ = ["compile_twice"]


def compile_twice(fn, **options):
    """``fn`` compiled serially (``njit(cache=True, **options)``) and in parallel (``parallel=True`` too).

    Each compile is made from a copy of ``fn`` under its own name (``<name>_serial``, ``<name>_parallel``):
    numba's on-disk cache keys a function by its name and signature, not by its options, so that one
    name for both would load the serial code for the parallel compile.

    Returns
    -------
    serial, parallel : numba dispatchers
    """
    def twin(suffix):
        copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__ + suffix, fn.__defaults__, fn.__closure__)
        copy.__qualname__ = fn.__qualname__ + suffix
        copy.__doc__, copy.__module__ = fn.__doc__, fn.__module__
        return copy

    return (njit(cache=True, **options)(twin("_serial")),
            njit(cache=True, parallel=True, **options)(twin("_parallel")))
