"""A first-in first-out history of sorted runs of values, with exact quantiles in O(runs * log(size)).

:class:`cvstereo.signal_level.SignalLevel` needs, once per 40 ms window, the 0.9 quantile of the last second's
values (up to a few hundred thousand at 640x480). ``np.quantile`` over their concatenation costs a full
partition each time; here each window's values are sorted once when they arrive, kept as one run of a flat
buffer, and an order statistic is found by a binary search over the values (their float64 bit patterns, which
order non-negative floats as the floats) that counts, in each run, the values below it. The quantile is then
numpy's ``linear`` method (its default) from the two order statistics around the quantile's position, with
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


class SortedRuns:
    """Runs of non-negative, non-NaN float64 values: append a run at the end, drop the oldest; quantiles.

    The runs live one after another in one buffer; dropping a run only moves the start, and the live part is
    moved to the front (or to a larger buffer) when an appended run does not fit.
    """

    def __init__(self):
        self._buf = np.empty(1024, np.float64)
        self._lo = 0  # start of the oldest run in the buffer
        self._hi = 0  # end of the newest run
        self._stops: deque[int] = deque()  # end of each run, oldest first (buffer positions)
        self.size = 0

    def __len__(self) -> int:
        return len(self._stops)

    def append(self, values: np.ndarray) -> None:
        """Add a run: ``values`` (non-negative, no NaN, any order; sorted here)."""
        n = values.size
        if self._hi + n > self._buf.size:
            live = self._hi - self._lo
            # Move the live runs to the front, into a larger buffer when they would fill more than half of it.
            buf = self._buf if 2 * (live + n) <= self._buf.size else np.empty(2 * (live + n), np.float64)
            buf[:live] = self._buf[self._lo: self._hi]
            self._stops = deque(s - self._lo for s in self._stops)
            self._buf, self._lo, self._hi = buf, 0, live
        self._buf[self._hi: self._hi + n] = values
        self._buf[self._hi: self._hi + n].sort()
        self._hi += n
        self._stops.append(self._hi)
        self.size += n

    def first_size(self) -> int:
        """Number of values in the oldest run."""
        return self._stops[0] - self._lo

    def popleft(self) -> None:
        """Drop the oldest run."""
        stop = self._stops.popleft()
        self.size -= stop - self._lo
        self._lo = stop

    def quantile(self, q: float) -> float:
        """``float(np.quantile(all values, q))`` (method ``linear``) without concatenating or partitioning."""
        n = self.size
        if n == 0:
            raise ValueError("SortedRuns.quantile: no values (append a run first).")
        stops = np.fromiter(self._stops, np.int64, len(self._stops))
        starts = np.concatenate(([self._lo], stops[:-1]))
        return _linear_quantile(self._buf.view(np.int64), starts, stops, n, q)


def _linear_quantile(bits: np.ndarray, starts: np.ndarray, stops: np.ndarray, n: int, q: float) -> float:
    """numpy's ``linear`` quantile (numpy.lib._function_base_impl._quantile with a scalar q), step by step."""
    virtual = (n - 1) * float(q)
    if virtual >= n - 1:  # numpy takes the last value (both neighbours are index -1)
        a = b = _from_bits(_order_statistic(bits, starts, stops, n - 1))
        gamma = virtual + 1.0  # virtual - (-1): numpy's gamma there; a == b makes it irrelevant but for 0 * inf
    else:
        previous = math.floor(virtual)
        a_bits = _order_statistic(bits, starts, stops, previous)
        b_bits = _next_order_statistic(bits, starts, stops, previous, a_bits)
        a, b = _from_bits(a_bits), _from_bits(b_bits)
        gamma = virtual - previous
    # numpy's _lerp: a + (b - a) * t, and b - (b - a) * (1 - t) where t >= 0.5.
    diff = b - a
    return b - diff * (1.0 - gamma) if gamma >= 0.5 else a + diff * gamma


def _from_bits(b: int) -> float:
    return float(np.array([b], np.int64).view(np.float64)[0])


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
