"""The numba kernels that turn one window's events into the fused matcher's inputs.

:func:`window_masks` (the left camera's event counts, the active pixels, the noise filter's recent pixels),
:func:`surface_features` (time surfaces of one camera, summed over the support square), and the pieces the
signal level needs (:mod:`cvstereo.matchers.fused.signal`: :func:`nonzero_values` gathers the values,
:func:`percentile` is numpy's, compiled with the same floating-point steps, :func:`divide` applies the level).
The cost and its aggregation are in :mod:`cvstereo.matchers.fused._kernels`. Every floating-point expression is
evaluated in the same order as in :mod:`cvstereo.matchers.fused.reference` (bit-identical matches).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from cvstereo.matchers.fused._parallel import COLUMN_BLOCK, serial_and_parallel

#: "Never saw an event" in the last-event-time arrays.
NEVER = np.int64(-(2**62))


def _window_masks(x, y, p, last_left, t_recent, path_radius, counts, active, recent):
    """The left camera's per-pixel inputs of a window, written into caller-owned arrays.

    Parameters
    ----------
    x, y, p : (N,) arrays
        The left camera's events of the window.
    last_left : (2, H, W) int64 ndarray
        The left camera's last event times, already updated with the window.
    t_recent : int
        Pixels whose last event is at or after this time are *recent* (noise filter).
    path_radius : int
        Active pixels: within this Chebyshev distance of an event of the window.
    counts : (2, H, W) int64 ndarray
        Out: event counts per polarity.
    active, recent : (H, W) bool ndarrays
        Out.

    Returns
    -------
    int
        The number of active pixels.
    """
    _, h, w = last_left.shape
    counts[:] = 0
    for i in range(x.size):
        counts[p[i], y[i], x[i]] += 1
    # Dilation of the event pixels by a (2r+1)^2 square, separably: a row pass (rows in parallel), then a column
    # pass over it (column blocks in parallel).
    rows = np.zeros((h, w), np.bool_)
    for yy in prange(h):
        reach = -1  # the last column the most recent event pixel of this row reaches
        for xx in range(min(path_radius, w)):
            if counts[0, yy, xx] + counts[1, yy, xx] > 0:
                reach = xx + path_radius
        # Selects, not branches (whether a pixel saw an event is hard to predict).
        for xx in range(max(w - path_radius, 0)):
            ahead = xx + path_radius
            reach = ahead + path_radius if counts[0, yy, ahead] + counts[1, yy, ahead] > 0 else reach
            rows[yy, xx] = reach >= xx
        for xx in range(max(w - path_radius, 0), w):
            rows[yy, xx] = reach >= xx
        for xx in range(w):
            recent[yy, xx] = (last_left[0, yy, xx] >= t_recent) | (last_left[1, yy, xx] >= t_recent)
    # The column pass row by row, every column's reach at once (contiguous selects that vectorise; a walk down
    # each column in turn was a strided, branchy loop).
    n_active = 0
    for b in prange((w + COLUMN_BLOCK - 1) // COLUMN_BLOCK):
        x0, x1 = b * COLUMN_BLOCK, min((b + 1) * COLUMN_BLOCK, w)
        reach_col = np.full(x1 - x0, -1, np.int64)  # per column: the last row its latest row-pass pixel reaches
        for yy in range(min(path_radius, h)):
            for xx in range(x0, x1):
                reach_col[xx - x0] = yy + path_radius if rows[yy, xx] else reach_col[xx - x0]
        n_block = 0
        for yy in range(h):
            ahead = yy + path_radius
            if ahead < h:
                for xx in range(x0, x1):
                    reach_col[xx - x0] = ahead + path_radius if rows[ahead, xx] else reach_col[xx - x0]
            for xx in range(x0, x1):
                active[yy, xx] = reach_col[xx - x0] >= yy
                n_block += reach_col[xx - x0] >= yy
        n_active += n_block
    return n_active


window_masks, window_masks_parallel = serial_and_parallel(_window_masks)


@njit(cache=True, nogil=True, inline="always")
def _add_to(acc, v):
    """``acc += v`` (1-D, contiguous)."""
    for i in range(acc.size):
        acc[i] += v[i]


@njit(cache=True, nogil=True, inline="always")
def _copy_to(acc, v):
    """``acc[:] = v`` (1-D, contiguous)."""
    for i in range(acc.size):
        acc[i] = v[i]


@njit(cache=True, nogil=True, inline="always")
def _gather_add(src, dst, radius):
    """``dst[x] = sum of src[x - radius .. x + radius]`` within the row, terms added in ascending order (from 0 in
    the reference: the same sums, as the values are at least +0 and ``0 + v == v``, so the first term is copied
    rather than added to zeros: one pass over the row fewer)."""
    n = src.size
    lo = min(radius, n)
    dst[:lo] = 0.0  # no term at x - radius
    _copy_to(dst[lo:], src[:n - lo])
    for dx in range(-radius + 1, radius + 1):
        lo, hi = max(-dx, 0), min(n - dx, n)
        _add_to(dst[lo:hi], src[lo + dx:hi + dx])


@njit(cache=True, nogil=True)
def surface_features(t, x, y, p, last, t_end, tau, radius, ts, rows, out):
    """Update a camera's last-event times with a window's events; write its support-summed time surfaces.

    Serial, releasing the GIL: a matcher on several threads computes the two cameras' features at once, one on
    each thread (:meth:`cvstereo.matchers.fused.matcher.FusedMatcher.match_window`).

    Parameters
    ----------
    t, x, y, p : (N,) arrays
        The camera's events of the window.
    last : (2, H, W) int64 ndarray
        Last event time per polarity and pixel (:data:`NEVER` if none), updated in place.
    t_end, tau, radius : int
        Window end, decay time (us) and support half side (px).
    ts, rows : (2, H, W) float64 ndarrays
        Scratch.
    out : (2, H, W) float64 ndarray
        Out: ``sum over the (2r+1)^2 square of max(0, 1 - (t_end - last) / tau)``, per polarity.
    """
    for i in range(t.size):
        pi, yi, xi = p[i], y[i], x[i]
        if t[i] > last[pi, yi, xi]:
            last[pi, yi, xi] = t[i]
    _, h, w = last.shape
    surf = out if radius == 0 else ts
    # Row by row, both polarities: a row's surface and its sums along the row, while the row is in the cache.
    for yy in range(h):
        for c in range(2):
            for xx in range(w):
                age = t_end - last[c, yy, xx]
                v = 1.0 - float(age) / float(tau)
                surf[c, yy, xx] = v if age < tau else 0.0  # both sides computed: the loop vectorises
            if radius > 0:
                # Separable: sums along the row first, then of those along the column (the reference's order),
                # each gathered with its terms in ascending order as the reference adds them: contiguous loops
                # that vectorise.
                _gather_add(ts[c, yy], rows[c, yy], radius)
    if radius == 0:
        return
    for yy in range(h):
        y_lo = max(yy - radius, 0)
        for c in range(2):
            acc = out[c, yy]
            _copy_to(acc, rows[c, y_lo])  # the first term (see _gather_add)
            for y2 in range(y_lo + 1, min(yy + radius + 1, h)):
                _add_to(acc, rows[c, y2])


@njit(cache=True, nogil=True)
def nonzero_values(features, buf, at):
    """Copy the positive values of ``features`` into ``buf`` and their flat indices into ``at`` (raster order);
    return how many there are."""
    flat = features.ravel()
    n = 0
    for i in range(flat.size):
        v = flat[i]
        buf[n] = v  # written always (n <= i), kept only if positive: no branch to mispredict
        at[n] = np.int32(i)
        n += v > 0.0
    return n


@njit(cache=True, nogil=True)
def select(vals, c, k):
    """The k-th least of ``vals[:c]`` (0-based), reordering ``vals[:c]`` so that nothing before position ``k`` is
    larger and nothing after it smaller.

    Hoare's selection (Wirth's form) in place: O(c) and no allocation (NumPy's partition copies). Used by the
    signal level's percentile and by the fill's median (:mod:`cvstereo.matchers.fused._kernels`).
    """
    lo, hi = 0, c - 1
    while lo < hi:
        pivot = vals[(lo + hi) // 2]
        i, j = lo, hi
        while i <= j:
            while vals[i] < pivot:
                i += 1
            while vals[j] > pivot:
                j -= 1
            if i <= j:
                vals[i], vals[j] = vals[j], vals[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break  # vals[j + 1:i] all equal the pivot, k among them
    return vals[k]


@njit(cache=True, nogil=True, inline="always")
def _bin(v, per_unit, nb):
    """The bin of value ``v`` among ``nb`` bins of width ``1 / per_unit`` from 0, the first and last taking whatever
    lies beyond them: monotone in ``v``."""
    return max(0, min(int(v * per_unit), nb - 1))


@njit(cache=True, nogil=True)
def order_stats(vals, c, k, pair, per_unit, hist, picked):
    """The k-th least of ``vals[:c]`` (0-based) and, with ``pair``, the (k+1)-th (``k + 1 < c``; else the k-th
    twice); ``vals`` is left as it is.

    The values are counted first in bins of ``1 / per_unit`` (``hist``: zeros, left so), which names the bin that
    holds the k-th; only that bin's values (copied to ``picked``, at least ``c`` long) are selected among
    (:func:`select`): two simple passes over the values instead of a selection among all of them, whose
    comparisons the processor mispredicts. The bins are monotone in the value, and order statistics are the same
    values however they are found, so this equals a sort. The (k+1)-th is the least after the k-th in its bin, or
    else the least of the next non-empty bin.
    """
    nb = hist.size
    lo_b, hi_b = nb, -1
    for i in range(c):
        b = _bin(vals[i], per_unit, nb)
        hist[b] += 1
        lo_b = min(lo_b, b)
        hi_b = max(hi_b, b)
    below = 0  # values in the bins before bin b
    b = lo_b
    while below + hist[b] <= k:
        below += hist[b]
        b += 1
    m = 0
    for i in range(c):
        if _bin(vals[i], per_unit, nb) == b:
            picked[m] = vals[i]
            m += 1
    j = k - below
    first = select(picked, m, j)
    second = first
    if pair:
        if j + 1 < m:
            second = picked[j + 1]  # after the selection nothing after j is smaller
            for q in range(j + 2, m):
                second = min(second, picked[q])
        else:
            b += 1
            while hist[b] == 0:
                b += 1
            second = np.inf
            for i in range(c):
                if _bin(vals[i], per_unit, nb) == b:
                    second = min(second, vals[i])
    for q in range(lo_b, hi_b + 1):
        hist[q] = 0
    return first, second


#: Bins per unit of feature value in which :func:`percentile` counts (1024 of them: 0..16, beyond shares the last).
PERCENTILE_BINS_PER_UNIT = 64


@njit(cache=True, nogil=True)
def percentile(values, q):
    """``np.percentile(values, q)`` (method "linear") of a non-empty float64 vector, bit for bit.

    NumPy's steps, in its floating-point order: virtual index ``(n - 1) * (q / 100)``, the two order
    statistics around it (found by :func:`order_stats`, O(n) instead of a full sort), and its interpolation
    between them from the nearer end (``b - (b - a) * (1 - g)`` when ``g >= 0.5``). Called per camera and
    window, where NumPy's own call costs more than the kernels around it.
    """
    n = values.size
    virtual = (n - 1) * (q / 100.0)
    if virtual >= n - 1:
        return values.max()
    below = int(np.floor(virtual))
    a, b = order_stats(values, n, below, True, PERCENTILE_BINS_PER_UNIT, np.zeros(1024, np.int64),
                       np.empty(n))
    g = virtual - float(below)
    diff = b - a
    if g >= 0.5:
        return b - diff * (1.0 - g)
    return a + diff * g


@njit(cache=True, nogil=True)
def divide(features, values, at, n, level):
    """``features /= level`` in place, given its ``n`` non-zero ``values`` and their flat indices ``at`` (from
    :func:`nonzero_values`): zeros stay zero, so only those are divided. Most of the values are zero, so visiting
    only the recorded indices is cheaper than a pass over all values that skips the zeros, and recording them is
    cheap for :func:`nonzero_values`."""
    flat = features.ravel()
    for j in range(n):
        flat[at[j]] = values[j] / level
