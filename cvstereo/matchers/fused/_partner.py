"""Fused's partner test (design part 10 of :mod:`cvstereo.matchers.fused.matcher`): which answers lie where their
true partner is outside the right image.

An answer at ``x`` whose row band's disparity ``D`` exceeds ``x`` would have its partner at ``x - D < 0``, left of
the right camera's image: what it found there is something else. ``D`` is the median disparity of the band's
consistent answers (rows ``y - border_rows .. y + border_rows``), exact as a sort of the band's values gives it.
Each row's values are sorted once, and a band's median is walked to through its rows' sorted runs (a merge of at
most ``2 * border_rows + 1`` runs up to the middle), where a sort of every band's values would sort each row's
values ``2 * border_rows + 1`` times.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from cvstereo.matchers.fused._constants import CONSISTENT_MAX_UNCERTAINTY
from cvstereo.matchers.fused._parallel import chunk_count, serial_and_parallel
from cvstereo.matchers.fused.params import BORDER_MIN_ANSWERS

__all__ = ["unpartnered", "unpartnered_parallel"]


def _unpartnered(x, y, disparity, uncertainty, rows, chunks):  # pragma: no cover - compiled
    """The partner test: which answers lie where their true partner is outside the right image.

    Parameters
    ----------
    x, y, disparity, uncertainty
        The answers in raster order (row, then column), as for
        :func:`cvstereo.matchers.fused.matcher.occluded`.
    rows : int
        ``border_rows``: the band of rows ``y - rows .. y + rows`` whose answers give a row's disparity.
    chunks : int
        The rows are split into this many chunks (in parallel in the parallel build; the result does not depend
        on it).

    Returns
    -------
    (M,) bool ndarray
        True for an answer left of its band's disparity: ``x < D``, D the median disparity of the answers of
        uncertainty at most 0.5 in the band, where the band has at least :data:`BORDER_MIN_ANSWERS` of them.
    """
    m = x.size
    out = np.zeros(m, np.bool_)
    if m == 0:
        return out
    h = y[m - 1] + 1
    start = np.zeros(h + 1, np.int64)  # row yy's answers: start[yy] .. start[yy + 1]
    runs = np.zeros(h + 1, np.int64)  # row yy's consistent disparities, sorted: values[runs[yy] .. runs[yy + 1]]
    for i in range(m):
        start[y[i] + 1] += 1
        if uncertainty[i] <= CONSISTENT_MAX_UNCERTAINTY:
            runs[y[i] + 1] += 1
    for yy in range(h):
        start[yy + 1] += start[yy]
        runs[yy + 1] += runs[yy]
    values = np.empty(runs[h])
    n_chunks = chunk_count(h, chunks)
    for ch in prange(n_chunks):  # every n_chunks-th row: a share of the busy rows for each chunk
        for yy in range(ch, h, n_chunks):
            c = runs[yy]
            for i in range(start[yy], start[yy + 1]):
                if uncertainty[i] <= CONSISTENT_MAX_UNCERTAINTY:
                    values[c] = disparity[i]
                    c += 1
            values[runs[yy]:runs[yy + 1]].sort()
    for ch in prange(n_chunks):
        heads = np.empty(2 * rows + 1, np.int64)
        for yy in range(ch, h, n_chunks):
            if start[yy] == start[yy + 1]:
                continue
            lo, hi = max(yy - rows, 0), min(yy + rows + 1, h)
            if runs[hi] - runs[lo] < BORDER_MIN_ANSWERS:
                continue
            d = _band_median(values, runs, lo, hi, heads)
            for i in range(start[yy], start[yy + 1]):
                out[i] = x[i] < d
    return out


@njit(cache=True, nogil=True, inline="always")
def _before(a, b):  # pragma: no cover - compiled
    """``a`` comes before ``b`` in a sort's order (NaN last)."""
    return a < b or (b != b and a == a)


@njit(cache=True, nogil=True)
def _band_median(values, runs, lo, hi, heads):  # pragma: no cover - compiled
    """The median of the sorted runs of rows ``lo .. hi - 1`` (``values[runs[r]:runs[r + 1]]``), as
    ``np.sort`` of their union gives it: the middle value, or the mean of the two middle values."""
    c = runs[hi] - runs[lo]
    for r in range(lo, hi):
        heads[r - lo] = runs[r]
    previous = np.nan
    current = np.nan
    for _ in range(c // 2 + 1):  # the values of ranks 0 .. c // 2, smallest first
        best = -1
        for r in range(lo, hi):
            k = heads[r - lo]
            if k < runs[r + 1] and (best < 0 or _before(values[k], values[heads[best - lo]])):
                best = r
        previous, current = current, values[heads[best - lo]]
        heads[best - lo] += 1
    return current if c % 2 else (previous + current) / 2.0


#: :func:`_unpartnered`, serial and parallel.
unpartnered, unpartnered_parallel = serial_and_parallel(_unpartnered)
