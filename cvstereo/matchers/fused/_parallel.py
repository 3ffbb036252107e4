"""One kernel source, two builds: serial (one thread, ``prange`` is a plain ``range``) and parallel.

The fused matcher calls the parallel build only when it runs on more than one thread
(:meth:`~cvstereo.matchers.fused.matcher.FusedMatcher.match_window`), so that the one-thread path is the serial
build and keeps its speed. Work is split into *chunks* that take every ``n``-th row, so that each thread gets a
share of the busy rows wherever the events are, or (the fused matcher's column paths) a range of adjacent column
blocks, so that a chunk's pixels of a row lie together in memory; the number of chunks follows the thread count,
but no result depends on it: a chunk's rows are computed exactly as they would be alone.
"""

from __future__ import annotations

import types

from numba import njit
from numba import types as nb_types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["CHUNKS_PER_THREAD", "COLUMN_BLOCK", "chunk_count", "chunks_for", "serial_and_parallel", "take_turn"]

#: Columns per block where columns are split into blocks (the fused matcher's column paths, a range of blocks a
#: chunk, and active-pixel mask, a block a task).
COLUMN_BLOCK = 32

#: Chunks per thread: several, so that a thread whose chunks end early is not left idle for long.
CHUNKS_PER_THREAD = 4


def serial_and_parallel(fn):
    """``fn`` compiled twice, ``(serial, parallel)``, both cached on disk and releasing the GIL.

    numba names a function's cache files after its qualified name and ignores ``parallel`` in the key, so the
    parallel build is compiled from a copy of ``fn`` under the name ``<name>_parallel``: the two builds never
    read each other's cache. The copy sees the module's globals as they are when this is called, with
    ``PARALLEL_BUILD = True`` added (a constant to numba: code under ``if PARALLEL_BUILD`` or ``if not
    PARALLEL_BUILD`` is left out of the other build before it is compiled): call it after every name ``fn`` uses
    is defined, at the end of its module.
    """
    twin = types.FunctionType(fn.__code__, {**fn.__globals__, "PARALLEL_BUILD": True}, fn.__name__ + "_parallel",
                              fn.__defaults__, fn.__closure__)
    twin.__qualname__ = fn.__qualname__ + "_parallel"
    twin.__doc__ = fn.__doc__
    twin.__module__ = fn.__module__
    return njit(cache=True, nogil=True)(fn), njit(cache=True, nogil=True, parallel=True)(twin)


def chunks_for(threads: int) -> int:
    """How many chunks to split the work of ``threads`` threads into (:data:`CHUNKS_PER_THREAD` per thread, and one
    on one thread, where the serial builds run the chunks one after the other); given to the kernels by the caller,
    since numba cannot cache a kernel that asks for its thread count."""
    return 1 if threads == 1 else CHUNKS_PER_THREAD * threads


@njit(cache=True, nogil=True)
def chunk_count(n, chunks):
    """How many of ``chunks`` chunks ``n`` rows (or blocks) are split into: at most ``n``, at least 1."""
    return max(1, min(n, chunks))


@intrinsic
def take_turn(typingctx, counters, i):
    """``counters[i] += 1`` as one atomic step (sequentially consistent) of an int64 array; returns the count
    before it.

    Two threads that each finish a share of the same piece of work (the two directions of a row) each take a turn;
    the one that sees the other's turn taken (``1``) does what needs both shares, and sees their writes: the
    atomic step orders every write before it, in either thread, before every read after it.
    """
    if not (isinstance(counters, nb_types.Array) and counters.dtype == nb_types.int64 and counters.ndim == 1):
        return None
    sig = nb_types.int64(counters, nb_types.intp)

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        at = cgutils.get_item_pointer(context, builder, array_type, array, [args[1]])
        return builder.atomic_rmw("add", at, context.get_constant(nb_types.int64, 1), "seq_cst")

    return sig, codegen
