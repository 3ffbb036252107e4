"""The one order in which the event matchers see both cameras' events, used by the kernels and the references.

Event-area and event-vector compare an event's own dynamic frame with the other camera's frame as it stands
at the event's time, so both cameras' events are processed in one merged order: by time, and at equal times
the left camera's events first, each camera's events in their array order **[choice]**.
:func:`left_is_next` is that rule; the numba kernels call :func:`left_is_next_jit`, the same function
compiled, and the references walk :func:`merged_events`.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numba import njit


def left_is_next(il: int, nl: int, ir: int, nr: int, tl, tr) -> bool:
    """Whether the next event in the merged order is the left camera's ``il``-th (else the right's ``ir``-th).

    Parameters
    ----------
    il, nl : int
        Index of the next unprocessed left event, and the number of left events.
    ir, nr : int
        The same for the right camera.
    tl, tr : (nl,), (nr,) int ndarray
        Time stamps of the left and right events.

    Examples
    --------
    >>> tl, tr = np.array([5, 7]), np.array([5])
    >>> [bool(left_is_next(il, 2, ir, 1, tl, tr)) for il, ir in ((0, 0), (1, 0), (1, 1))]   # 5 left, 5 right, 7
    [True, False, True]
    """
    return ir >= nr or (il < nl and tl[il] <= tr[ir])


#: :func:`left_is_next` compiled for the kernels (inlined into each, so that it costs no call).
left_is_next_jit = njit(cache=True, inline="always")(left_is_next)


def merged_events(left: np.ndarray, right: np.ndarray) -> Iterator[tuple[int, int, np.void]]:
    """Both cameras' events in the merged order.

    Yields
    ------
    (camera, index, event)
        camera 0 = left, 1 = right; index into that camera's array.
    """
    i = j = 0
    tl, tr = left["t"], right["t"]
    while i < left.size or j < right.size:
        if left_is_next(i, left.size, j, right.size, tl, tr):
            yield 0, i, left[i]
            i += 1
        else:
            yield 1, j, right[j]
            j += 1
