"""The fused matcher's answers from the aggregated costs: winner, uncertainty, left-right check, sub-pixel, noise
test (:func:`row_answers`, a row at a time) and the fill of the inconsistent winners (:func:`fill_answers`), for
:func:`cvstereo.matchers.fused._kernels.match_features`. Each row's answers, and each filled answer, depend on
nothing another row or answer computes, so that rows and answers may be taken in any order or in parallel.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cvstereo.matchers.fused._constants import (
    LR_PENALTY,
    NOISE_RADIUS,
    RATIO_UNCERTAINTY,
    SECOND_BEST_GAP_PX,
    SUBPIXEL_MAX_SHIFT_PX,
)
from cvstereo.matchers.fused._features import order_stats
from cvstereo.matchers.fused._sgm import min_of

#: Bins per pixel of disparity in which :func:`median_of` counts the values before it selects.
MEDIAN_BINS_PER_PX = 8


@njit(cache=True, nogil=True)
def median_of(vals, c, hist, picked):
    """The median of ``vals[:c]`` (``c > 0``; the mean of the two middle values when ``c`` is even), as the
    reference's sort gives it.

    By :func:`~cvstereo.matchers.fused._features.order_stats` in bins of 1/:data:`MEDIAN_BINS_PER_PX` px (``hist``:
    zeros, left so; ``picked`` as long as ``vals``): a selection among all the several hundred values of a filled
    pixel's square cost half the fill.
    """
    k = c // 2
    if c % 2:
        return order_stats(vals, c, k, False, MEDIAN_BINS_PER_PX, hist, picked)[0]
    lower, mid = order_stats(vals, c, k - 1, True, MEDIAN_BINS_PER_PX, hist, picked)
    return (lower + mid) / 2.0


@njit(cache=True, nogil=True)
def row_answers(yy, k0, k1, slot, counts, recent, total, ax, prm, right_v, right_d, ints, reals, flags):
    """The answers of row ``yy``, whose active pixels are ``k0 .. k1 - 1`` and whose anchors take the output slots
    from ``slot`` on, once the row's sums ``total[k0:k1]`` are final.

    ``right_v``, ``right_d`` (W,) float32 and int32: scratch. Slot ``i`` gets ``ints[:, i] = x, y, polarity``,
    ``reals[:, i] = disparity, uncertainty`` and ``flags[:, i] = left-right consistent, answered``; an anchor that
    the noise test silences keeps ``flags[1, i]`` False.
    """
    h, w = recent.shape
    nd = total.shape[1]
    lr_tol = prm.lr_tol
    if lr_tol >= 0:
        # The right pixels' own winners from the same sums, for the whole row in one sweep: right pixel xr
        # (at j = W - 1 - xr) takes the least total[k, d] over the active xl = xr + d. Pixels in ascending
        # x meet each xr in ascending d, so a strict < keeps the first least d, as the reference's argmin.
        for j in range(w):
            right_v[j] = np.float32(np.inf)
            right_d[j] = -1
        for k in range(k0, k1):
            j0 = w - 1 - ax[k]
            for d in range(min(nd, ax[k] + 1)):
                j = np.uint64(j0 + d)  # unsigned: no wrap-around test (see the cost loop)
                v = total[k, d]
                better = v < right_v[j]
                right_v[j] = v if better else right_v[j]
                right_d[j] = np.int32(d) if better else right_d[j]
    for k in range(k0, k1):
        xx = ax[k]
        if counts[0, yy, xx] + counts[1, yy, xx] == 0:
            continue
        i = slot
        slot += 1
        neighbours = 0
        for y2 in range(max(yy - NOISE_RADIUS, 0), min(yy + NOISE_RADIUS + 1, h)):
            for x2 in range(max(xx - NOISE_RADIUS, 0), min(xx + NOISE_RADIUS + 1, w)):
                if recent[y2, x2]:
                    neighbours += 1
        isolated = neighbours < prm.min_neighbours
        if isolated and prm.isolated_below <= 0.0:
            continue  # no isolated pixel can answer: skip the work
        # The first least disparity (argmin's), then the least more than SECOND_BEST_GAP_PX away from it.
        low = min_of(total, k, 0, nd)
        best = 0
        while total[k, best] != low:
            best += 1
        second = np.inf
        if best > SECOND_BEST_GAP_PX:
            second = min_of(total, k, 0, best - SECOND_BEST_GAP_PX)
        if best + SECOND_BEST_GAP_PX + 1 < nd:
            second = min(second, min_of(total, k, best + SECOND_BEST_GAP_PX + 1, nd))
        ratio = 1.0 if second == 0.0 else np.float64(total[k, best]) / second
        consistent = True
        if lr_tol >= 0:
            xr = xx - best
            best_r = right_d[w - 1 - xr] if xr >= 0 else -1
            consistent = best_r >= 0 and abs(best_r - best) <= lr_tol
        u = RATIO_UNCERTAINTY * ratio if consistent else RATIO_UNCERTAINTY * ratio + LR_PENALTY
        if isolated and not u < prm.isolated_below:
            continue
        disp = float(best)
        if prm.subpixel and 0 < best < nd - 1:
            a, b, c = np.float64(total[k, best - 1]), np.float64(total[k, best]), np.float64(total[k, best + 1])
            den = (a - 2.0 * b) + c
            if den > 0.0:
                delta = (a - c) / (2.0 * den)
                disp = disp + min(max(delta, -SUBPIXEL_MAX_SHIFT_PX), SUBPIXEL_MAX_SHIFT_PX)
        ints[0, i] = xx
        ints[1, i] = yy
        ints[2, i] = 1 if counts[1, yy, xx] >= counts[0, yy, xx] else 0
        reals[0, i] = disp
        reals[1, i] = u
        flags[0, i] = consistent
        flags[1, i] = True


@njit(cache=True, nogil=True)
def consistent_rows(x, y, ok, h):
    """The consistent answers (``ok``) of answers ``x, y`` in raster order, by row: row y's x are
    ``cons_x[start[y]:start[y + 1]]``, ascending, their indices among the answers ``cons_i[...]``.

    A fill square then reads, per row, only the answers within it (found by bisection), in the order a scan of
    the square's pixels would meet them: a few hundred pixel reads per filled pixel fewer.
    """
    m = x.size
    cons_x = np.empty(m, np.int64)
    cons_i = np.empty(m, np.int64)
    start = np.zeros(h + 1, np.int64)
    n = 0
    for i in range(m):
        if ok[i]:
            cons_x[n] = x[i]
            cons_i[n] = i
            n += 1
            start[y[i] + 1] += 1
    for yy in range(h):
        start[yy + 1] += start[yy]
    return cons_x, cons_i, start


@njit(cache=True, nogil=True)
def fill_answers(first, stride, x, y, ok, disparity, uncertainty, cons, prm, h, nd):
    """The fill of answers ``first, first + stride, ...`` (design part 8): an inconsistent winner takes the median of
    the consistent answers within ``fill_radius`` (when there are any), or is confirmed by it when it agrees with it
    (``confirm``). ``cons``: :func:`consistent_rows` of the answers; it reads only consistent answers, which are
    never filled, so that answers may be filled in any order.
    """
    cons_x, cons_i, cons_start = cons
    radius = prm.fill_radius
    vals = np.empty((2 * radius + 1) ** 2)
    picked = np.empty_like(vals)
    hist = np.zeros(MEDIAN_BINS_PER_PX * nd, np.int64)
    for i in range(first, x.size, stride):
        if ok[i] or radius <= 0:
            continue
        c = 0
        x_lo, x_hi = x[i] - radius, x[i] + radius
        for y2 in range(max(y[i] - radius, 0), min(y[i] + radius + 1, h)):
            lo, hi = cons_start[y2], cons_start[y2 + 1]
            while lo < hi:  # the row's first answer at or right of x_lo
                mid = (lo + hi) // 2
                if cons_x[mid] < x_lo:
                    lo = mid + 1
                else:
                    hi = mid
            while lo < cons_start[y2 + 1] and cons_x[lo] <= x_hi:
                vals[c] = disparity[cons_i[lo]]
                c += 1
                lo += 1
        if c > 0:
            med = median_of(vals, c, hist, picked)
            if prm.confirm and abs(disparity[i] - med) <= prm.lr_tol:
                uncertainty[i] = uncertainty[i] - LR_PENALTY  # confirmed by the consistent answers around it
            else:
                disparity[i] = med
