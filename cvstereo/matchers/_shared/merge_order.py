"""The one order in which the event matchers see both cameras' events, used by the kernels and the references.

Event-area and event-vector compare an event's own dynamic frame with the other camera's frame as it stands
at the event's time, so both cameras' events are processed in one merged order: by time, and at equal times
the left camera's events first, each camera's events in their array order **[choice]**.
:func:`left_is_next` is that rule; the numba kernels walk :func:`merged_stream` (built by
:func:`left_is_next_jit`, the same function compiled); :func:`merged_events` walks it in Python (kept for the 0.2
path ``calibration_free.merge_order``). The references merge on their own, by a sort
(:func:`cvstereo.matchers._shared.reference_frames.merged_events`), so that a slip in this rule shows.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numba import njit, prange

from cvstereo.matchers._shared.twin_kernels import compile_twice


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


#: The rows of :func:`merged_stream`'s array, one column per event: the camera (0 left, 1 right), the index into
#: that camera's array, t, x, y, p, and the frame slot of p (:func:`cvstereo.model.polarity.slot_of_p`).
ROW_CAM, ROW_INDEX, ROW_T, ROW_X, ROW_Y, ROW_P, ROW_SLOT = range(7)
#: How many rows.
STREAM_ROWS = 7


@njit(cache=True, inline="always")
def stream_event(stream, k):
    """The k-th event of a :func:`merged_stream`: ``(camera, index, t, x, y, p, slot)``, its rows in order.

    Inlined into the kernels' loops; it has no loop of its own, so that numba's pass that drops the reference
    counting of the inlined ``stream`` removes it (a helper with loops kept it around every event).
    """
    return (stream[ROW_CAM, k], stream[ROW_INDEX, k], stream[ROW_T, k], stream[ROW_X, k], stream[ROW_Y, k],
            stream[ROW_P, k], stream[ROW_SLOT, k])


def merged_stream(tl, xl, yl, pl, tr, xr, yr, pr, slot_of_p, buffer=None, pieces=1):
    """Both cameras' events as one stream in the merged order, the kernels' input.

    Parameters
    ----------
    tl, xl, yl, pl, tr, xr, yr, pr : int ndarray
        Columns of the left and the right camera's events (:func:`cvstereo.frames.dynamic.event_columns`, or
        the fields of the event arrays themselves), each camera's in time order.
    slot_of_p : (2,) int64 ndarray
        Frame slot of p = 0 (OFF) and p = 1 (ON); -1 where the polarity mode drops it.
    buffer : 1-D int64 ndarray, optional
        Memory to build the stream in, at least ``STREAM_ROWS * (len(tl) + len(tr))`` long (a caller that merges
        once per window reuses one instead of allocating one per window); a fresh array by default.
    pieces : int, optional
        Merge the stream in this many pieces at once (> 1: numba's parallel compile, for a matcher on as many
        threads); the same stream whatever their number.

    Returns
    -------
    (STREAM_ROWS, M) int64 ndarray
        Rows :data:`ROW_CAM`, :data:`ROW_INDEX`, :data:`ROW_T`, :data:`ROW_X`, :data:`ROW_Y`, :data:`ROW_P`,
        :data:`ROW_SLOT`, for the M events whose polarity is kept (a view of ``buffer`` when one is given).
    """
    n = tl.shape[0] + tr.shape[0]
    out = np.empty((STREAM_ROWS, n), np.int64) if buffer is None else buffer[: STREAM_ROWS * n].reshape(STREAM_ROWS, n)
    pieces = max(1, min(int(pieces), tl.shape[0]))
    return out[:, : _MERGE_KERNELS[pieces > 1](out, tl, xl, yl, pl, tr, xr, yr, pr, slot_of_p, pieces)]


def _merge_pieces(out, tl, xl, yl, pl, tr, xr, yr, pr, slot_of_p, pieces):  # pragma: no cover - compiled
    """Write :func:`merged_stream`'s rows into the columns of ``out`` (STREAM_ROWS, >= M) in ``pieces`` pieces, in
    parallel in the parallel compile; return M.

    Piece ``c`` begins at the left event ``c * nl // pieces`` and the first right event not earlier than it
    (:func:`left_is_next`: left first at equal times), so that the events before it are a prefix of the merged
    order; with a polarity dropped, a first pass counts what each piece keeps, where it writes from.
    """
    nl, nr = tl.shape[0], tr.shape[0]
    first_l = np.empty(pieces + 1, np.int64)
    first_r = np.empty(pieces + 1, np.int64)
    for c in range(pieces):
        first_l[c] = c * nl // pieces
        first_r[c] = 0 if c == 0 else np.searchsorted(tr, tl[first_l[c]])
    first_l[pieces], first_r[pieces] = nl, nr
    start = np.zeros(pieces + 1, np.int64)
    if pieces > 1:
        kept = np.empty(pieces, np.int64)
        both = slot_of_p[0] >= 0 and slot_of_p[1] >= 0
        for c in prange(pieces):
            kept[c] = first_l[c + 1] - first_l[c] + first_r[c + 1] - first_r[c]
            if not both:
                kept[c] = (_kept(pl, first_l[c], first_l[c + 1], slot_of_p)
                           + _kept(pr, first_r[c], first_r[c + 1], slot_of_p))
        for c in range(pieces):
            start[c + 1] = start[c] + kept[c]
    end = np.empty(pieces, np.int64)  # where each piece ended: start[c + 1] (pieces > 1), or M (one piece)
    for c in prange(pieces):
        end[c] = _merge_piece(out, tl, xl, yl, pl, tr, xr, yr, pr, slot_of_p, first_l[c], first_l[c + 1],
                              first_r[c], first_r[c + 1], start[c])
    return end[pieces - 1]


@njit(cache=True)
def _kept(p, first, stop, slot_of_p):  # pragma: no cover - compiled
    """How many of the events ``first .. stop - 1`` of polarities ``p`` have a frame slot."""
    n = 0
    for i in range(first, stop):
        n += slot_of_p[1 if p[i] > 0 else 0] >= 0
    return n


@njit(cache=True)
def _merge_piece(out, tl, xl, yl, pl, tr, xr, yr, pr, slot_of_p, il, nl, ir, nr, m):  # pragma: no cover - compiled
    """Merge the left events ``il .. nl - 1`` and the right ones ``ir .. nr - 1`` into the columns of ``out`` from
    ``m`` on; return the column after the last written."""
    while il < nl or ir < nr:
        if left_is_next_jit(il, nl, ir, nr, tl, tr):
            cam, i, t, x, y, p = 0, il, tl[il], xl[il], yl[il], pl[il]
            il += 1
        else:
            cam, i, t, x, y, p = 1, ir, tr[ir], xr[ir], yr[ir], pr[ir]
            ir += 1
        slot = slot_of_p[1 if p > 0 else 0]
        if slot >= 0:
            out[ROW_CAM, m], out[ROW_INDEX, m], out[ROW_T, m] = cam, i, t
            out[ROW_X, m], out[ROW_Y, m], out[ROW_P, m], out[ROW_SLOT, m] = x, y, p, slot
            m += 1
    return m


#: :func:`_merge_pieces`, serial (one piece) and parallel.
_MERGE_KERNELS = compile_twice(_merge_pieces)
