"""A first-in first-out history of sorted runs of values, with exact quantiles by a selection over the runs.

:class:`cvstereo.matchers._shared.signal_level.SignalLevel` needs, once per 40 ms window, the 0.9 quantile of the last
second's values (up to a few hundred thousand at 640x480). ``np.quantile`` over their concatenation costs a full
partition each time; here each window's values are kept as one run of a flat buffer and sorted once (by the
first quantile after they arrived; a long run by a radix sort of the values' float64 bit patterns, which order
non-negative floats as the floats), and an order statistic is found by a selection over the runs that drops a
quarter or more of the candidates at each step (:func:`_neighbours`). The quantile is then numpy's ``linear``
method (its default) from the two order statistics around the quantile's position, with numpy's own arithmetic,
so that it equals ``np.quantile`` of the concatenated values bit for bit. A quantile may also be of some of the
runs (every ``every``-th from ``first``): the signal level keeps one run per part of a camera's values and window.

>>> runs = SortedRuns()
>>> runs.append(np.array([1.0, 2.0, 3.0, 4.0, 5.0]))
>>> runs.quantile(0.9), float(np.quantile([1.0, 2.0, 3.0, 4.0, 5.0], 0.9))
(4.6, 4.6)
"""

from __future__ import annotations

import math

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
        # End of each run, oldest first (buffer positions): self._stops[self._first:self._last].
        self._stops = np.empty(64, np.int64)
        self._first = 0
        self._last = 0
        self._unsorted = 0  # the newest this many runs are not sorted yet
        self._spare = np.empty(0, np.int64)  # the radix sort's second buffer
        self.size = 0

    def __len__(self) -> int:
        return self._last - self._first

    def append(self, values: np.ndarray) -> None:
        """Add a run: ``values`` (non-negative, no NaN, any order; sorted when a quantile needs it)."""
        n = values.size
        if self._hi + n > self._buf.size:
            live = self._hi - self._lo
            # Move the live runs to the front, into a larger buffer (with room for growth: a fresh buffer's pages
            # cost a fault each) when they would fill more than half of it.
            buf = self._buf if 2 * (live + n) <= self._buf.size else np.empty(4 * (live + n), np.float64)
            buf[:live] = self._buf[self._lo: self._hi]
            self._stops[self._first: self._last] -= self._lo
            self._buf, self._lo, self._hi = buf, 0, live
        if self._last == self._stops.size:
            runs = len(self)
            stops = self._stops if 2 * runs <= self._stops.size else np.empty(4 * runs, np.int64)
            stops[:runs] = self._stops[self._first: self._last]
            self._stops, self._first, self._last = stops, 0, runs
        self._buf[self._hi: self._hi + n] = values
        self._hi += n
        self._stops[self._last] = self._hi
        self._last += 1
        self._unsorted += 1
        if n >= RADIX_MIN and self._spare.size < n:
            self._spare = np.empty(2 * n, np.int64)
        self.size += n

    def first_size(self, runs: int = 1) -> int:
        """Number of values in the oldest ``runs`` runs."""
        return int(self._stops[self._first + runs - 1]) - self._lo

    def popleft(self, runs: int = 1) -> None:
        """Drop the oldest ``runs`` runs."""
        stop = int(self._stops[self._first + runs - 1])
        self._first += runs
        self.size -= stop - self._lo
        self._lo = stop
        self._unsorted = min(self._unsorted, len(self))

    def quantile(self, q: float) -> float:
        """``float(np.quantile(all values, q))`` (method ``linear``) without concatenating or partitioning."""
        if self.size == 0:
            raise ValueError("SortedRuns.quantile: no values (append a run first).")
        return float(self.part_quantiles(q, 1, 1)[0])

    def part_quantiles(self, q: float, parts: int, min_size: int) -> np.ndarray:
        """(parts,) float64: for each part ``i``, :meth:`quantile` of the values of the runs ``i``, ``i + parts``,
        ``i + 2 * parts``, ... (a history that appends one run per part at each step), NaN where they are fewer
        than ``min_size`` (>= 1)."""
        stops = self._stops[self._first: self._last]
        for r in range(stops.size - self._unsorted, stops.size):
            start = self._lo if r == 0 else stops[r - 1]
            if stops[r] - start < RADIX_MIN:
                self._buf[start: stops[r]].sort()  # numpy's sort: faster than a compiled one on short runs
            else:
                _sort_patterns(self._buf[start: stops[r]].view(np.int64), self._spare)
        self._unsorted = 0
        return _part_quantiles(self._buf, self._lo, stops, int(parts), float(q), int(min_size))


@numba.njit(cache=True, nogil=True)
def _part_quantiles(buf, lo, stops, parts, q, min_size):  # pragma: no cover - compiled
    """:meth:`SortedRuns.part_quantiles` of the sorted runs that end at ``stops``, the first starting at ``lo``."""
    starts = np.empty_like(stops)
    if stops.size:
        starts[0] = lo
        starts[1:] = stops[:-1]
    bits = buf.view(np.int64)
    out = np.full(parts, np.nan)
    for part in range(parts):
        n = 0
        for r in range(part, stops.size, parts):
            n += stops[r] - starts[r]
        if n >= min_size:
            virtual = (n - 1) * q
            a, b = _neighbours(buf, bits, starts[part::parts], stops[part::parts], n, virtual)
            out[part] = _lerp(a, b, virtual)
    return out


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


@numba.njit(cache=True, nogil=True)
def _lerp(a, b, virtual):  # pragma: no cover - compiled
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
    when virtual >= n - 1 (as numpy).

    A selection over the runs: each run keeps an active range that holds the wanted order statistic's place in
    it; the pivot is the weighted median of the active ranges' middle values (weights: the ranges' lengths), so
    at least a quarter of the active values lie on each side of it and every step drops a quarter or more. A
    bisection over the bit patterns took one step per bit (some 60); this takes about log(n) / log(4/3) at
    most, each one two searches per run in ranges that shrink."""
    rank = n - 1 if virtual >= n - 1 else int(np.floor(virtual))
    lo = starts.copy()
    hi = stops.copy()
    n_runs = starts.size
    mids = np.empty(n_runs, np.int64)
    weights = np.empty(n_runs, np.int64)
    below = np.empty(n_runs, np.int64)
    upto = np.empty(n_runs, np.int64)
    k = rank  # the wanted value's rank among the active values
    while True:
        # The active ranges' middles in the order of their values (an insertion sort: a few dozen runs).
        total = 0
        m = 0
        for r in range(n_runs):
            if hi[r] > lo[r]:
                mid = (lo[r] + hi[r]) // 2
                j = m
                while j > 0 and bits[mids[j - 1]] > bits[mid]:
                    mids[j] = mids[j - 1]
                    weights[j] = weights[j - 1]
                    j -= 1
                mids[j] = mid
                weights[j] = hi[r] - lo[r]
                total += hi[r] - lo[r]
                m += 1
        pivot = mids[m - 1]
        half = 0
        for j in range(m):
            half += weights[j]
            if 2 * half >= total:
                pivot = mids[j]
                break
        p = bits[pivot]
        less = 0
        equal = 0
        for r in range(n_runs):
            below[r] = lo[r] + np.searchsorted(bits[lo[r]: hi[r]], p)
            upto[r] = lo[r] + np.searchsorted(bits[lo[r]: hi[r]], p, side="right")
            less += below[r] - lo[r]
            equal += upto[r] - below[r]
        if k < less:
            hi[:] = below
        elif k >= less + equal:
            lo[:] = upto
            k -= less + equal
        else:
            break
    a = values[pivot]
    if rank == n - 1 or k + 1 < less + equal:  # the last value, or a tie: the next value equals this one
        return a, a
    # The next value is the least one above p: in every run it sits at upto (what lies beyond the active range
    # was dropped for being above a pivot that is above p).
    nxt = -1
    for r in range(n_runs):
        if upto[r] < stops[r] and (nxt < 0 or bits[upto[r]] < bits[nxt]):
            nxt = upto[r]
    return a, values[nxt]

