"""The event model: one dtype for the whole library, validation, time slicing and packet iteration.

An event stream is a numpy structured array of :data:`EVENT_DTYPE`, time-ordered (``t`` non-decreasing):

>>> import numpy as np
>>> from cvstereo.events import EVENT_DTYPE, as_events
>>> ev = as_events(np.array([(10, 3, 4, -1)], dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")]))
>>> ev.dtype == EVENT_DTYPE, int(ev["p"][0])
(True, 0)
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple

import numpy as np

from cvstereo.errors import EventFormatError

#: The event dtype of formats.md: t (us), x (column, 0 = left), y (row, 0 = top), p (1 = ON, 0 = OFF).
EVENT_DTYPE = np.dtype([("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])

#: Sensor size of the DVS128 / eDVS128, (width, height).
DEFAULT_RESOLUTION = (128, 128)

#: The largest sensor size accepted anywhere a resolution comes in (files, options, matchers), (width, height).
MAX_RESOLUTION = (2048, 2048)

_FIELDS = ("t", "x", "y", "p")


def check_resolution(resolution, *, source: str = "resolution", error: type[Exception] = ValueError) -> tuple[int, int]:
    """Return ``resolution`` as two ints, or raise unless it is a sensor size this library accepts.

    Width and height must be whole numbers with ``1 <= width <= MAX_RESOLUTION[0]`` and
    ``1 <= height <= MAX_RESOLUTION[1]``: every buffer a matcher or reader allocates is sized by it, so
    a size no sensor has (100000x100000 would ask for tens of GB) is refused where it comes in.

    Parameters
    ----------
    resolution : (width, height)
    source : str, keyword-only
        What to name in the message (a file and key, an option).
    error : exception class, keyword-only
        Raised on a bad value (a ValueError subclass, e.g. CorruptFileError for a file's header).

    Examples
    --------
    >>> check_resolution((240, 180))
    (240, 180)
    >>> check_resolution((0, 0))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: resolution (0, 0): width and height must be whole numbers in 1..2048 ...
    """
    try:
        width, height = resolution
        ok = all(float(v) == int(v) and not isinstance(v, bool) for v in (width, height))
    except (TypeError, ValueError, OverflowError):
        ok = False
    if ok:
        width, height = int(width), int(height)
        ok = 1 <= width <= MAX_RESOLUTION[0] and 1 <= height <= MAX_RESOLUTION[1]
    if not ok:
        shown = resolution if isinstance(resolution, tuple | list) else repr(resolution)
        raise error(
            f"{source} {_short(shown)}: width and height must be whole numbers in 1..{MAX_RESOLUTION[0]} and "
            f"1..{MAX_RESOLUTION[1]} (the largest supported sensor is {MAX_RESOLUTION[0]}x{MAX_RESOLUTION[1]})."
        )
    return width, height


def _short(value, limit: int = 60) -> str:
    text = str(tuple(value) if isinstance(value, list) else value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


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
              index_offset: int = 0) -> np.ndarray:
    """Convert and validate an event array.

    Accepts a structured array with the fields ``t, x, y, p`` under any widths and order (tonic's
    ``x, y, t, p`` included), ``p`` as bool, 1/0 or +1/-1. Returns a new array of :data:`EVENT_DTYPE`.

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

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE

    Raises
    ------
    EventFormatError
        Missing fields, non-integer fields, polarity other than 0/1/-1, negative or out-of-range
        coordinates, timestamps going backwards. The message names the source, field and first index.
    """
    arr = np.asarray(data)
    names = arr.dtype.names
    if names is None:
        raise EventFormatError(
            f"{source}: expected a structured array with fields t, x, y, p; got dtype {arr.dtype}. "
            "Build one with cvstereo.events.make_events(t, x, y, p)."
        )
    missing = [f for f in _FIELDS if f not in names]
    if missing:
        raise EventFormatError(
            f"{source}: missing field(s) {', '.join(missing)}; an event array needs t, x, y, p "
            f"(it has {', '.join(names)})."
        )
    if arr.ndim != 1:
        raise EventFormatError(f"{source}: expected a 1-D event array, got shape {arr.shape}.")
    for f in _FIELDS:
        kind = arr.dtype[f].kind
        if kind not in "iub" or (kind == "b" and f != "p"):
            raise EventFormatError(
                f"{source}: field '{f}' has dtype {arr.dtype[f]}; it must be an integer type "
                f"(cast it, e.g. events['{f}'].astype('int64'))."
            )
    p = arr["p"]
    if p.dtype.kind == "b":
        p = p.astype(np.int8)
    else:
        bad = np.flatnonzero((p != 0) & (p != 1) & (p != -1))
        if bad.size:
            i = int(bad[0])
            raise EventFormatError(
                f"{source}: field 'p' at index {i + index_offset} is {int(p[i])}; polarity must be 1/0 or +1/-1."
            )
    out = np.empty(arr.shape[0], dtype=EVENT_DTYPE)
    out["t"] = arr["t"]
    out["x"] = _checked_int16(arr["x"], "x", source, index_offset)
    out["y"] = _checked_int16(arr["y"], "y", source, index_offset)
    out["p"] = p > 0
    validate_events(out, resolution=resolution, source=source, index_offset=index_offset)
    return out


def _checked_int16(values: np.ndarray, field: str, source: str, index_offset: int) -> np.ndarray:
    bad = np.flatnonzero((values < -32768) | (values > 32767)) if values.dtype.itemsize > 2 else ()
    if len(bad):
        i = int(bad[0])
        raise EventFormatError(
            f"{source}: field '{field}' at index {i + index_offset} is {int(values[i])}, beyond int16."
        )
    return values


def validate_events(events: np.ndarray, *, resolution: tuple[int, int] | None = DEFAULT_RESOLUTION,
                    source: str = "events", index_offset: int = 0, t_floor: int | None = None) -> None:
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
    _check_coordinates(events, resolution, source, index_offset)
    t = events["t"]
    if t_floor is not None and t[0] < t_floor:
        raise EventFormatError(
            f"{source}: field 't' at index {index_offset} is {int(t[0])}, earlier than the preceding event "
            f"({t_floor}); timestamps must not go backwards."
        )
    back = t[1:] < t[:-1]
    if back.any():
        i = int(np.argmax(back)) + 1
        raise EventFormatError(
            f"{source}: field 't' at index {i + index_offset} is {int(t[i])}, earlier than index "
            f"{i - 1 + index_offset} ({int(t[i - 1])}); timestamps must not go backwards "
            "(sort with np.sort(events, order='t', kind='stable') if the order is known to be wrong)."
        )


def _check_coordinates(events: np.ndarray, resolution, source: str, index_offset: int) -> None:
    """Raise naming the first event (and of it, x before y) whose coordinate is negative or off the sensor."""
    firsts = []
    for k, field in enumerate(("x", "y")):
        column = events[field]
        # Read as unsigned, a negative int16 is >= 32768, beyond any sensor: one comparison tests both bounds
        # (this runs on every packet a matcher is fed, so it is kept to one pass per coordinate).
        bad = column < 0 if resolution is None else column.view(np.uint16) >= resolution[k]
        if bad.any():
            firsts.append((int(np.argmax(bad)), k, field))
    if not firsts:
        return
    i, k, field = min(firsts)
    value = int(events[field][i])
    if value < 0:
        raise EventFormatError(
            f"{source}: field '{field}' at index {i + index_offset} is {value}; "
            "coordinates must be >= 0 (one-based files need the one-based option)."
        )
    raise EventFormatError(
        f"{source}: field '{field}' at index {i + index_offset} is {value}, outside "
        f"the {resolution[0]}x{resolution[1]} sensor (valid 0..{resolution[k] - 1}); "
        "give the right resolution, or the one-based option if the file counts from 1."
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
