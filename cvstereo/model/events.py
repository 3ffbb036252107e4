"""The event model: one dtype for the whole library, validation, time slicing and packet iteration.

An event stream is a numpy structured array of :data:`EVENT_DTYPE`, time-ordered (``t`` non-decreasing):

>>> import numpy as np
>>> from cvstereo.model.events import EVENT_DTYPE, as_events
>>> ev = as_events(np.array([(10, 3, 4, -1)], dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")]))
>>> ev.dtype == EVENT_DTYPE, int(ev["p"][0])
(True, 0)
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.model.columns import check_coordinates, check_polarity, check_times, labelled
from cvstereo.model.sensor_size import DEFAULT_RESOLUTION as DEFAULT_RESOLUTION
from cvstereo.model.sensor_size import MAX_RESOLUTION as MAX_RESOLUTION
from cvstereo.model.sensor_size import check_resolution as check_resolution

__all__ = ["EVENT_DTYPE", "StereoPacket", "as_events", "count_before", "distinct_sorted", "empty_events",
           "events_from_columns", "is_time_ordered", "iter_stereo_packets", "make_events", "paired_window_segments",
           "time_slice", "validate_events", "window_segments"]

#: The event dtype of docs/formats.md: t (us), x (column, 0 = left), y (row, 0 = top), p (1 = ON, 0 = OFF).
EVENT_DTYPE = np.dtype([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])

_FIELDS = ("t", "x", "y", "p")


def empty_events(n: int = 0) -> np.ndarray:
    """Return a zero-filled event array of length ``n``."""
    return np.zeros(n, dtype=EVENT_DTYPE)


def make_events(t, x, y, p) -> np.ndarray:
    """Build an event array from four columns (no validation; see :func:`as_events`).

    Parameters
    ----------
    t, x, y, p : array_like
        Columns of equal length; ``p`` is 1/0 (ON/OFF).

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE
    """
    t = np.asarray(t)
    out = np.empty(t.shape[0], dtype=EVENT_DTYPE)
    out["t"] = t
    out["x"] = x
    out["y"] = y
    out["p"] = p
    return out


def as_events(data, *, resolution: tuple[int, int] | None = DEFAULT_RESOLUTION, source: str = "events",
              index_offset: int = 0, t_floor: int | None = None) -> np.ndarray:
    """Convert and validate an event array.

    Accepts a structured array with the fields ``t, x, y, p`` under any integer widths and order (tonic's
    ``x, y, t, p`` included), ``p`` as bool, 1/0 or +1/-1. Returns a new array of :data:`EVENT_DTYPE`.
    Values are checked as given, before the cast (:func:`events_from_columns`).

    Parameters
    ----------
    data : (N,) structured ndarray
        The events.
    resolution : (width, height) or None, keyword-only
        Coordinates must lie in ``[0, width) x [0, height)``; None skips the range check.
    source : str, keyword-only
        Named in error messages (a file name, "left camera", ...).
    index_offset : int, keyword-only
        Added to indices in error messages, for arrays that are chunks of a longer stream.
    t_floor : int, optional, keyword-only
        The last time of the preceding chunk: the first event must not be earlier.

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE

    Raises
    ------
    EventFormatError
        Missing fields, non-integer fields, polarity other than 0/1/-1, negative or out-of-range
        coordinates, times beyond int64, timestamps going backwards. The message names the source, field and
        first index.
    """
    arr = np.asarray(data)
    names = arr.dtype.names
    if names is None:
        raise EventFormatError(
            f"{source}: expected a structured array with fields t, x, y, p; got dtype {arr.dtype}. "
            "Build one with cvstereo.model.events.make_events(t, x, y, p)."
        )
    missing = [f for f in _FIELDS if f not in names]
    if missing:
        raise EventFormatError(
            f"{source}: missing field(s) {', '.join(missing)}; an event array needs t, x, y, p "
            f"(it has {', '.join(names)})."
        )
    if arr.ndim != 1:
        raise EventFormatError(f"{source}: expected a 1-D event array, got shape {arr.shape}.")
    return events_from_columns(arr["t"], arr["x"], arr["y"], arr["p"], resolution=resolution, source=source,
                               index_offset=index_offset, t_floor=t_floor)


def events_from_columns(t, x, y, p, *, resolution: tuple[int, int] | None = DEFAULT_RESOLUTION,
                        source: str = "events", index_offset: int = 0, labels: dict[str, str] | None = None,
                        t_offset: int = 0, t_floor: int | None = None) -> np.ndarray:
    """Check four raw columns value by value, then cast them into a new array of :data:`EVENT_DTYPE`.

    The columns keep the dtype they were stored in until every value has been checked against what the
    event dtype can hold (:mod:`cvstereo.model.columns`): a cast would turn int32 65541 into x = 5, uint16 65535
    into -1, uint64 2**63 into a negative time and a polarity of 256 into OFF, silently.

    Parameters
    ----------
    t, x, y, p : (N,) ndarray
        Integer columns (``p`` may be bool); floats are refused here (see
        :func:`cvstereo.model.columns.whole_numbers` and :func:`cvstereo.model.columns.times_to_us`).
    resolution, source, index_offset : keyword-only
        As for :func:`as_events`.
    labels : dict, optional, keyword-only
        How to name each field in messages, e.g. ``{"x": "/events/x"}`` for a file's dataset.
    t_offset : int, keyword-only
        Added to every time (a file's time base, as DSEC's ``/t_offset``); the sums must fit int64.
    t_floor : int, optional, keyword-only
        The last time of the preceding chunk, as stored (before ``t_offset``): the first time must not be
        earlier. Order is checked on the stored values, so that a message quotes what the file holds.

    Raises
    ------
    EventFormatError
    """
    names = labelled(labels)
    if resolution is not None:
        resolution = check_resolution(resolution, source=f"{source}: resolution")
    columns = {"t": np.asarray(t), "x": np.asarray(x), "y": np.asarray(y), "p": np.asarray(p)}
    for f, values in columns.items():
        kind = values.dtype.kind
        if kind not in "iub" or (kind == "b" and f != "p") or values.ndim != 1:
            raise EventFormatError(f"{source}: {names[f]} has dtype {values.dtype} and shape {values.shape}; "
                                   f"{_FIX_KIND[f]}")
    if len({v.shape[0] for v in columns.values()}) != 1:
        raise EventFormatError(f"{source}: the columns have different lengths "
                               f"({', '.join(f'{names[f]}: {v.shape[0]}' for f, v in columns.items())}).")
    check_times(columns["t"], t_offset=t_offset, source=source, label=names["t"], index_offset=index_offset)
    check_coordinates(columns["x"], columns["y"], resolution, source=source, labels=labels,
                      index_offset=index_offset)
    check_polarity(columns["p"], source=source, label=names["p"], index_offset=index_offset)
    _check_order(columns["t"], source, names["t"], index_offset, t_floor)
    out = np.empty(columns["t"].shape[0], dtype=EVENT_DTYPE)
    out["t"] = columns["t"]
    if t_offset:
        out["t"] += t_offset
    out["x"] = columns["x"]
    out["y"] = columns["y"]
    out["p"] = columns["p"] > 0
    return out


#: What to do about a field of the wrong kind: times have a unit that a cast would lose, the rest do not.
_FIX_KIND = {
    "t": "times must be integer microseconds: for float times say their unit with "
         "cvstereo.model.arrays.events_from(data, time_unit='s') (or 'ms', 'us', 'ns').",
    **{f: f"it must be a 1-D integer column (cast it, e.g. events['{f}'].astype('int64'), if it holds whole numbers)."
       for f in "xyp"},
}


def validate_events(events: np.ndarray, *, resolution: tuple[int, int] | None = DEFAULT_RESOLUTION,
                    source: str = "events", index_offset: int = 0, t_floor: int | None = None,
                    labels: dict[str, str] | None = None) -> None:
    """Check an array of :data:`EVENT_DTYPE` against the contract; raise on the first violation.

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
    resolution : (width, height) or None, keyword-only
    source : str, keyword-only
        Named in error messages.
    index_offset : int, keyword-only
        Added to indices in error messages.
    t_floor : int or None, keyword-only
        The last timestamp of the preceding chunk: the first event must not be earlier.
    labels : dict, optional, keyword-only
        How to name each field in messages (see :func:`events_from_columns`).

    Raises
    ------
    EventFormatError
    """
    if events.dtype != EVENT_DTYPE:
        raise EventFormatError(f"{source}: dtype {events.dtype} is not EVENT_DTYPE; convert with as_events().")
    if events.ndim != 1:
        raise EventFormatError(f"{source}: expected a 1-D event array, got shape {events.shape}.")
    if events.size == 0:
        return
    check_coordinates(events["x"], events["y"], resolution, source=source, labels=labels, index_offset=index_offset)
    _check_order(events["t"], source, labelled(labels)["t"], index_offset, t_floor)


def _check_order(t: np.ndarray, source: str, label: str, index_offset: int, t_floor: int | None) -> None:
    """Raise naming the first time earlier than the one before it (or than ``t_floor``, the previous chunk's)."""
    if t.size == 0:
        return
    if t_floor is not None and t[0] < t_floor:
        raise EventFormatError(
            f"{source}: {label} at index {index_offset} is {int(t[0])}, earlier than the preceding event "
            f"({t_floor}); timestamps must not go backwards."
        )
    back = t[1:] < t[:-1]
    if back.any():
        i = int(np.argmax(back)) + 1
        raise EventFormatError(
            f"{source}: {label} at index {i + index_offset} is {int(t[i])}, earlier than index "
            f"{i - 1 + index_offset} ({int(t[i - 1])}); timestamps must not go backwards "
            "(sort with np.sort(events, order='t', kind='stable') if the order is known to be wrong)."
        )


def time_slice(events: np.ndarray, t_start: int | None = None, t_stop: int | None = None) -> slice:
    """Return the index slice of the events with ``t_start <= t < t_stop`` (absolute times, us).

    Either bound may be None (open). Uses binary search, so ``events`` must be time-ordered.

    Examples
    --------
    >>> ev = make_events([0, 5, 10, 15], [0] * 4, [0] * 4, [1] * 4)
    >>> ev[time_slice(ev, 5, 15)]["t"].tolist()
    [5, 10]
    """
    t = events["t"]
    lo = 0 if t_start is None else int(np.searchsorted(t, t_start, side="left"))
    hi = len(t) if t_stop is None else int(np.searchsorted(t, t_stop, side="left"))
    return slice(lo, max(lo, hi))


def distinct_sorted(values: np.ndarray) -> np.ndarray:
    """The distinct values of a sorted array, in order (``np.unique`` without its sort).

    >>> distinct_sorted(np.array([0, 0, 3, 3, 3, 7])).tolist()
    [0, 3, 7]
    """
    if values.size == 0:
        return values
    return values[np.concatenate([[True], values[1:] != values[:-1]])]


def is_time_ordered(t: np.ndarray) -> bool:
    """Whether the times ``t`` never decrease (one pass; the matchers' output and every stream are)."""
    return t.size < 2 or bool(np.all(t[1:] >= t[:-1]))


def count_before(t: np.ndarray, cut: int | None) -> int:
    """How many of the time-ordered ``t`` lie before ``cut`` (none when there is no cut yet).

    Usually all or none of them (a packet's ``until`` is the cut): then without a search, which would first copy
    a strided field.
    """
    if cut is None or t.size == 0 or t[0] >= cut:
        return 0
    if t[-1] < cut:
        return t.size
    return int(np.searchsorted(t, cut, side="left"))


def window_segments(t: np.ndarray, window_us: int) -> list[tuple[int, int, int]]:
    """Split a time-ordered array into runs of one absolute window: ``[(k, start, stop), ...]``.

    The runs' ends come from a binary search for each window start between the first and the last time, not
    from the window index of every element (an int64 division per event: a few % of the event matchers'
    time outside their kernels at 640x480).
    """
    if t.size == 0:
        return []
    w = int(window_us)
    k0, k1 = int(t[0]) // w, int(t[-1]) // w
    if k0 == k1:  # the usual packet: no search (it would copy a strided field first)
        return [(k0, 0, int(t.size))]
    ks = np.arange(k0, k1 + 1, dtype=np.int64)
    cuts = np.searchsorted(t, ks[1:] * w, side="left")  # first element of each window after the first
    starts = np.concatenate([[0], cuts]).tolist()
    stops = np.concatenate([cuts, [t.size]]).tolist()
    return [(k, a, b) for k, a, b in zip(ks.tolist(), starts, stops, strict=True) if b > a]


def paired_window_segments(t_left: np.ndarray, t_right: np.ndarray, window_us: int
                           ) -> list[tuple[int, tuple[int, int], tuple[int, int]]]:
    """Both cameras' runs of each absolute window that holds an event of either: ``[(k, (a, b), (c, d)), ...]``
    in window order, ``t_left[a:b]`` and ``t_right[c:d]`` the window's times (``(0, 0)``: none).

    >>> paired_window_segments(np.array([5, 15, 25]), np.array([12, 14]), 10)
    [(0, (0, 1), (0, 0)), (1, (1, 2), (0, 2)), (2, (2, 3), (0, 0))]
    """
    runs = [{k: (a, b) for k, a, b in window_segments(t, window_us)} for t in (t_left, t_right)]
    return [(k, runs[0].get(k, (0, 0)), runs[1].get(k, (0, 0))) for k in sorted(runs[0].keys() | runs[1].keys())]


class StereoPacket(NamedTuple):
    """A time slice of both cameras.

    Every event of the stream after this packet has ``t >= until``; events of this packet have ``t < until``.
    ``left_disparity`` / ``right_disparity`` are the ground truth of the packet's events, or None.
    """

    left: np.ndarray
    right: np.ndarray
    until: int
    left_disparity: np.ndarray | None = None
    right_disparity: np.ndarray | None = None


class _Side:
    """Buffered view of one camera's chunk iterator (events and an optional parallel truth array)."""

    def __init__(self, chunks: Iterator):
        self._chunks = chunks
        self.events = empty_events()
        self.truth: np.ndarray | None = None
        self.done = False

    def fill_until(self, t_stop: int) -> None:
        # Pull chunks until the buffer holds an event at or past t_stop, so the window is complete.
        while not self.done and (self.events.size == 0 or self.events["t"][-1] < t_stop):
            try:
                item = next(self._chunks)
            except StopIteration:
                self.done = True
                break
            events, truth = item if isinstance(item, tuple) else (item, None)
            self.events = np.concatenate([self.events, events])
            if truth is not None or self.truth is not None:
                old = self.truth if self.truth is not None else np.full(self.events.size - events.size, np.nan,
                                                                        np.float32)
                new = truth if truth is not None else np.full(events.size, np.nan, np.float32)
                self.truth = np.concatenate([old, np.asarray(new, np.float32)])

    def take_before(self, t_stop: int) -> tuple[np.ndarray, np.ndarray | None]:
        t = self.events["t"]
        # searchsorted copies a strided field view whole, which made streaming a long in-memory recording
        # quadratic; search a prefix that grows until it holds t_stop (packets are short).
        hi = 4096
        while hi < t.size and t[hi - 1] < t_stop:
            hi *= 4
        n = int(np.searchsorted(t[:hi], t_stop, side="left"))
        events, self.events = self.events[:n], self.events[n:]
        truth = None
        if self.truth is not None:
            truth, self.truth = self.truth[:n], self.truth[n:]
        return events, truth

    def first_t(self) -> int | None:
        return int(self.events["t"][0]) if self.events.size else None


def iter_stereo_packets(left: Iterable, right: Iterable, packet_us: int = 10_000) -> Iterator[StereoPacket]:
    """Cut two time-ordered camera streams into aligned packets on the absolute clock.

    Packets cover ``[k*P, (k+1)*P)``; windows in which neither camera has an event are skipped.
    Memory stays bounded by the chunk size and the packet length, however long the streams.

    Parameters
    ----------
    left, right : iterable
        Each yields event arrays (chunks, time-ordered across chunks), or ``(events, truth)`` tuples
        where ``truth`` is a float array of the same length or None. A single array is accepted too.
    packet_us : int
        Packet length P in microseconds.

    Yields
    ------
    StereoPacket
    """
    if packet_us <= 0:
        raise ValueError(f"packet_us must be positive, got {packet_us}.")
    sides = [_Side(_as_chunk_iter(left)), _Side(_as_chunk_iter(right))]
    k: int | None = None
    while True:
        for side in sides:
            side.fill_until(-(2**62) if k is None else k * packet_us)
        firsts = [t for t in (s.first_t() for s in sides) if t is not None]
        if not firsts:
            return
        # Skip windows in which neither camera has an event.
        k_first = min(firsts) // packet_us
        k = k_first if k is None else max(k, k_first)
        stop = (k + 1) * packet_us
        for side in sides:
            side.fill_until(stop)
        (le, ld), (re, rd) = (s.take_before(stop) for s in sides)
        yield StereoPacket(le, re, stop, ld, rd)
        k += 1


def _as_chunk_iter(stream) -> Iterator:
    if isinstance(stream, np.ndarray):
        return iter([stream])
    if isinstance(stream, tuple) and len(stream) == 2 and isinstance(stream[0], np.ndarray):
        return iter([stream])
    return iter(stream)
