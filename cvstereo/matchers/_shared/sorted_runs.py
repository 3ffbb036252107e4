"""A first-in first-out history of sorted runs of values, with exact quantiles in O(runs * log(size)).

:class:`cvstereo.matchers._shared.signal_level.SignalLevel` needs, once per 40 ms window, the 0.9 quantile of the last
second's values (up to a few hundred thousand at 640x480). ``np.quantile`` over their concatenation costs a full
partition each time; here each window's values are kept as one run of a flat buffer and sorted once (by the
first quantile after they arrived; a long run by a radix sort of the values' float64 bit patterns, which order
non-negative floats as the floats), and an order statistic is found by a binary search over those bit patterns
that counts, in each run, the values below it. The quantile is then numpy's ``linear`` method (its default)
from the two order statistics around the quantile's position, with
numpy's own arithmetic, so that it equals ``np.quantile`` of the concatenated values bit for bit.

>>> runs = SortedRuns()
>>> runs.append(np.array([1.0, 2.0, 3.0, 4.0, 5.0]))
>>> runs.quantile(0.9), float(np.quantile([1.0, 2.0, 3.0, 4.0, 5.0], 0.9))
(4.6, 4.6)
"""

from __future__ import annotations

import math
from collections import deque

import numba
import numpy as np

#: Runs of at least this many values are sorted by :func:`_sort_patterns`, shorter ones by numpy's sort (the radix
#: sort's fixed passes cost more than a comparison sort of a short run; both give the same order).
RADIX_MIN = 1024


class SortedRuns:
    """Runs of non-negative, non-NaN float64 values: append a run at the end, drop the oldest; quantiles.

    The runs live one after another in one buffer; dropping a run only moves the start, and the live part is
    moved to the front (or to a larger buffer) when an appended run does not fit. A run is sorted by the first
    :meth:`quantile` after it arrived, not on :meth:`append`: a history whose quantile nobody asks for (the
    signal level in absolute mode, which keeps only its size) never pays for the sorts.
    """

    def __init__(self):
        self._buf = np.empty(1024, np.float64)
        self._lo = 0  # start of the oldest run in the buffer
        self._hi = 0  # end of the newest run
        self._stops: deque[int] = deque()  # end of each run, oldest first (buffer positions)
        self._unsorted = 0  # the newest this many runs are not sorted yet
        self._spare = np.empty(0, np.int64)  # the radix sort's second buffer
        self.size = 0

    def __len__(self) -> int:
        return len(self._stops)

    def append(self, values: np.ndarray) -> None:
        """Add a run: ``values`` (non-negative, no NaN, any order; sorted when a quantile needs it)."""
        n = values.size
        if self._hi + n > self._buf.size:
            live = self._hi - self._lo
            # Move the live runs to the front, into a larger buffer (with room for growth: a fresh buffer's pages
            # cost a fault each) when they would fill more than half of it.
            buf = self._buf if 2 * (live + n) <= self._buf.size else np.empty(4 * (live + n), np.float64)
            buf[:live] = self._buf[self._lo: self._hi]
            self._stops = deque(s - self._lo for s in self._stops)
            self._buf, self._lo, self._hi = buf, 0, live
        self._buf[self._hi: self._hi + n] = values
        self._hi += n
        self._stops.append(self._hi)
        self._unsorted += 1
        self.size += n

    def first_size(self) -> int:
        """Number of values in the oldest run."""
        return self._stops[0] - self._lo

    def popleft(self) -> None:
        """Drop the oldest run."""
        stop = self._stops.popleft()
        self.size -= stop - self._lo
        self._lo = stop
        self._unsorted = min(self._unsorted, len(self._stops))

    def quantile(self, q: float) -> float:
        """``float(np.quantile(all values, q))`` (method ``linear``) without concatenating or partitioning."""
        n = self.size
        if n == 0:
            raise ValueError("SortedRuns.quantile: no values (append a run first).")
        stops = np.fromiter(self._stops, np.int64, len(self._stops))
        starts = np.concatenate(([self._lo], stops[:-1]))
        for r in range(len(stops) - self._unsorted, len(stops)):
            run = self._buf[starts[r]: stops[r]]
            if run.size < RADIX_MIN:
                run.sort()
                continue
            if self._spare.size < run.size:
                self._spare = np.empty(2 * run.size, np.int64)
            _sort_patterns(run.view(np.int64), self._spare)
        self._unsorted = 0
        virtual = (n - 1) * float(q)
        a, b = _neighbours(self._buf, self._buf.view(np.int64), starts, stops, n, virtual)
        return _lerp(a, b, virtual)


@numba.njit(cache=True, nogil=True)
def _sort_patterns(bits, spare):  # pragma: no cover - compiled
    """Sort ``bits`` (the float64 bit patterns of non-negative, non-NaN values, which order as the values) in
    place: a least-significant-byte radix sort, one counting pass and one stable scatter per byte, skipping the
    bytes all values share; ``spare`` holds at least as many. Its passes are linear in the values, where a
    comparison sort of a window's thousands of values was most of the signal level's cost (a serial part of
    every run: docs/guide/threads.md)."""
    n = bits.size
    src, dst = bits, spare[:n]
    count = np.empty(256, np.int64)
    in_bits = True
    for shift in range(0, 64, 8):
        count[:] = 0
        for i in range(n):
            count[(src[i] >> shift) & 255] += 1
        if n == 0 or count[(src[0] >> shift) & 255] == n:  # every value has this byte: already in order by it
            continue
        start = 0
        for b in range(256):
            c = count[b]
            count[b] = start
            start += c
        for i in range(n):
            b = (src[i] >> shift) & 255
            dst[count[b]] = src[i]
            count[b] += 1
        src, dst = dst, src
        in_bits = not in_bits
    if not in_bits:
        bits[:] = src


def _lerp(a: float, b: float, virtual: float) -> float:
    """numpy's ``linear`` quantile (numpy.lib._function_base_impl._quantile with a scalar q) from the values
    ``a``, ``b`` at ``floor(virtual)`` and the next index (both the last value when virtual >= n - 1)."""
    # numpy's gamma is virtual - the previous index (-1 at the last value, where a == b makes gamma moot).
    gamma = virtual - math.floor(virtual)
    diff = b - a
    # numpy's _lerp: a + (b - a) * t, and b - (b - a) * (1 - t) where t >= 0.5.
    return b - diff * (1.0 - gamma) if gamma >= 0.5 else a + diff * gamma


@numba.njit(cache=True, nogil=True)
def _neighbours(values, bits, starts, stops, n, virtual):  # pragma: no cover - compiled
    """The values at index floor(virtual) and the next of the sorted union of the runs; the last value twice
    when virtual >= n - 1 (as numpy)."""
    if virtual >= n - 1:
        last = _order_statistic(bits, starts, stops, n - 1)
        v = _value_of(values, bits, starts, stops, last)
        return v, v
    previous = int(np.floor(virtual))
    a_bits = _order_statistic(bits, starts, stops, previous)
    b_bits = _next_order_statistic(bits, starts, stops, previous, a_bits)
    return _value_of(values, bits, starts, stops, a_bits), _value_of(values, bits, starts, stops, b_bits)


@numba.njit(cache=True, nogil=True)
def _value_of(values, bits, starts, stops, pattern):  # pragma: no cover - compiled
    """The value whose bit pattern is ``pattern`` (one of the runs holds it)."""
    for r in range(starts.size):
        k = starts[r] + np.searchsorted(bits[starts[r]: stops[r]], pattern)
        if k < stops[r] and bits[k] == pattern:
            return values[k]
    return np.nan


@numba.njit(cache=True, nogil=True)
def _count_at_most(bits, starts, stops, v):  # pragma: no cover - compiled
    """How many values have bit pattern <= v, over all runs."""
    c = 0
    for r in range(starts.size):
        c += np.searchsorted(bits[starts[r]: stops[r]], v, side="right")
    return c


@numba.njit(cache=True, nogil=True)
def _order_statistic(bits, starts, stops, i):  # pragma: no cover - compiled
    """Bit pattern of the i-th smallest value (0-based) of the sorted runs ``bits[starts[r]:stops[r]]``.

    The least pattern v with at least i + 1 values <= v is a value's own pattern: the count only steps there.
    """
    lo = 0
    hi = 0
    for r in range(starts.size):
        if stops[r] > starts[r] and bits[stops[r] - 1] > hi:
            hi = bits[stops[r] - 1]
    while lo < hi:
        mid = lo + (hi - lo) // 2
        if _count_at_most(bits, starts, stops, mid) >= i + 1:
            hi = mid
        else:
            lo = mid + 1
    return lo


@numba.njit(cache=True, nogil=True)
def _next_order_statistic(bits, starts, stops, i, at_i):  # pragma: no cover - compiled
    """Bit pattern of the (i+1)-th smallest value, given that of the i-th (``at_i``)."""
    if _count_at_most(bits, starts, stops, at_i) >= i + 2:
        return at_i  # a tie: the next value equals this one
    best = np.int64(-1)
    for r in range(starts.size):
        k = starts[r] + np.searchsorted(bits[starts[r]: stops[r]], at_i, side="right")
        if k < stops[r] and (best < 0 or bits[k] < best):
            best = bits[k]
    return best
