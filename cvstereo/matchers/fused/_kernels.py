"""The matching kernel of the fused matcher (:mod:`cvstereo.matchers.fused.matcher` describes the method).

Per window, on the features of :mod:`cvstereo.matchers.fused._features`: :func:`match_features` (cost,
semi-global aggregation, winner, left-right check, sub-pixel, uncertainty). Every floating-point expression
is evaluated in the same order as in :mod:`cvstereo.matchers.fused.reference`, so that both give bit-identical
matches (tests/test_fused.py).

Why the kernels are shaped as they are (the figures that led here are in bench/results/docstring-figures.md).
Typical windows: 2arms-50cm, 128x128, 64 disparities, about 6000 active pixels; a 346x260 recording at a
million events a second, about 26000 active pixels and 171 disparities.

* Memory traffic, not arithmetic, set the pace when the cost and the four paths were stored as (active
  pixels x disparities) arrays of several MB. Now a window keeps two such arrays, in float32 (half the
  bytes, twice the vector lanes): the cost and the sum of its paths. Each pass (:func:`_row_pass`) keeps its
  row path in a vector and its column path in two sensor rows; the forward pass computes the cost, stores it
  and writes left + above, the backward pass reads the cost back and adds right and below.
  Cost, paths and sums are float32 in the reference too, in the same order. Keeping the paths out of memory
  pays most where the arrays outgrow the caches (the 346x260 windows); storing the cost saves computing it
  again in the backward pass.
* Each pixel's semi-global step is one plain loop over the disparities, which the compiler vectorises: it steps
  the row and the column path, adds them to the sums and takes their minima (a reduction the compiler vectorises
  too, :func:`_least`: numba's ``min`` kept it scalar, one instruction per value, in a pass of its own). The
  path vectors carry a column of inf at either end, so that the first and last disparity need no case of their
  own outside the loop.
* No array is sliced or passed to an inlined helper inside the per-pixel loops: each such view or binding is a
  new array whose reference count numba updates with two atomic instructions, and with a dozen a pixel those
  dominated the kernel's time (perf: NRT_incref/NRT_decref). The loops are written out in
  :func:`_row_pass` and index rows of 2-D arrays in place; :func:`_step` takes scalars only.
* The left-right check needs the right pixels' winners of a row, each one disparity of many different left
  pixels: they are found in one sweep over the row's sums (contiguous, branch-free, mirrored like the cost)
  as soon as the backward pass has finished the row, while its sums are in the cache, instead of a scattered
  walk per anchor.
* The cost reads the right camera's row backwards (disparity 0, 1, ... is column x, x - 1, ...): a mirrored
  copy of the right features makes those loops contiguous and branch-free, so they vectorise. Its index is
  unsigned: numba wraps negative indices around, and testing a signed one kept the loop scalar.
* The fill's median and the level's percentile select in place (:func:`~cvstereo.matchers.fused._features.select`)
  rather than sort; the median first counts its values in bins and selects within one (:func:`median_of`), and the
  fill reads the consistent answers from per-row runs rather than scanning its square (2arms-50cm: about 200
  filled pixels a window, 25x25 squares).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import cgutils
from numba.extending import intrinsic

from cvstereo.matchers.fused._constants import (
    LR_PENALTY,
    NOISE_RADIUS,
    RATIO_UNCERTAINTY,
    SECOND_BEST_GAP_PX,
    SUBPIXEL_MAX_SHIFT_PX,
    TEMPORAL_CAP_PX,
)
from cvstereo.matchers.fused._features import order_stats


@intrinsic
def _least(typingctx, a, b):
    """``min(a, b)`` of two floats of one type, as LLVM's ``minnum`` with the no-NaN and no-signed-zero flags.

    A loop of these that keeps a running minimum is a reduction LLVM vectorises (packed minima, several lanes at
    once); of numba's ``min`` (a compare and a select without those flags) it cannot, since it may not reorder
    them, and the running minima were scalar instructions, one per value. The flags hold here: the costs and
    paths are never NaN (features are finite, the prior's NaN is tested before use) and never -0 (sums of
    values >= +0, and ``x - x`` is +0), so the result is exactly ``min(a, b)``, and a minimum is the same in any
    order.
    """
    sig = a(a, b)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(args[0].type, [args[0].type, args[1].type])
        name = f"llvm.minnum.f{signature.return_type.bitwidth}"
        return builder.call(cgutils.get_or_insert_function(builder.module, fnty, name), args,
                            fastmath=("nnan", "nsz"))

    return sig, codegen


@njit(cache=True, nogil=True, inline="always")
def _min_of(v, i, lo, hi):
    """``min(v[i, lo:hi])`` (``lo < hi``), vectorised (:func:`_least`)."""
    m = v[i, lo]
    for d in range(lo + 1, hi):
        m = _least(m, v[i, d])
    return m


@njit(cache=True, nogil=True, inline="always")
def _step(c, before, at, after, jump, p1, mn):
    """One disparity of a semi-global step: ``c + min(prev[d], prev[d+-1] + p1, mn + p2) - mn`` (Hirschmüller 2008,
    eq. 13), with ``before, at, after = prev[d - 1], prev[d], prev[d + 1]`` (inf beyond the range) and ``jump = mn +
    p2``. The minima are exact in any order, so this equals the reference. Scalars only: an inlined helper that
    takes an array binds it to a new variable, which numba counts with two atomic instructions per call."""
    return c + (min(min(at, jump), min(before, after) + p1) - mn)


@njit(cache=True, nogil=True, inline="always")
def _row_pass(fl, right_rev, prior, index, ax, yy, k_first, k_stop, step, row_tol, temporal_weight, p1, p2, paths,
              total, costs, vecs, cols, cols_min, cur):
    """One row of one semi-global pass: ``step`` 1 is the forward pass (left to right, the column path comes from
    above), -1 the backward one (right to left, from below).

    The forward pass computes each pixel's cost into ``costs[k]``, the backward pass reads it back. The row path runs
    in ``vecs[0:2]`` (current and previous, taking turns), the column path in ``cols[cur * W + x]`` with the previous
    row's in ``cols[(1 - cur) * W + x]``; disparity d is at column d + 1 of them, between columns of inf. A path
    without a predecessor starts at the cost: it steps from the zero row (``vecs[2]``, ``cols[2 * W]``) with
    minimum 0, which adds exactly 0 (``p1, p2 >= 0``). The forward pass writes
    ``total[k] = left (+ above)``, the backward pass adds ``(+ right) (+ below)`` in that order, as the reference
    sums them; with ``paths`` 0, ``total[k]`` is the cost.

    Every per-pixel loop is written out here rather than in helpers that take arrays: each such call bound its
    arrays to new variables, and numba's two atomic reference-count updates per binding cost more than the
    arithmetic (the module docstring has the figures).
    """
    h, w = index.shape
    nd = total.shape[1]  # at least 2 (FusedParams: max_disparity >= 1)
    inf = np.float32(np.inf)
    zero = np.float32(0.0)
    r = 0
    r_min = zero
    y_from = yy - step  # the row the column path comes from
    for k in range(k_first, k_stop, step):
        xx = ax[k]
        if step > 0:
            # The cost of every disparity: right_rev[y, c, j] is the right feature at column W - 1 - j (zero for
            # j >= W, beyond the left edge), so that disparities 0, 1, ... read it forwards from j = W - 1 - xx:
            # contiguous loops without branches, which vectorise. The least over the tolerated rows is exact in
            # any order, so this equals the reference's np.minimum over rows.
            l0, l1 = np.float32(fl[0, yy, xx]), np.float32(fl[1, yy, xx])
            j0 = right_rev.shape[2] - nd - 1 - xx
            for d in range(nd):
                costs[k, d] = inf
            for y2 in range(max(yy - row_tol, 0), min(yy + row_tol + 1, h)):
                for d in range(nd):
                    # An unsigned index: numba wraps negative indices around, and the test of a signed one kept
                    # this loop from vectorising.
                    j = np.uint64(j0 + d)
                    costs[k, d] = min(costs[k, d], abs(l0 - right_rev[y2, 0, j]) + abs(l1 - right_rev[y2, 1, j]))
            pr = prior[yy, xx]
            if temporal_weight > 0.0 and not np.isnan(pr):
                for d in range(nd):
                    costs[k, d] = costs[k, d] + np.float32(temporal_weight * min(abs(d - pr), TEMPORAL_CAP_PX))
        if paths == 0:
            for d in range(nd):
                total[k, d] = costs[k, d]
            continue
        x_from = xx - step
        if 0 <= x_from < w and index[yy, x_from] >= 0:
            rp, rmn = 1 - r, r_min
        else:
            rp, rmn = 2, zero
        rj = rmn + p2
        # The path vectors hold disparity d at column d + 1, between two columns of inf that are never written:
        # the step reads prev[d - 1] and prev[d + 1] at both ends without a case of its own, so that one loop per
        # pixel steps the paths, adds them to the sums and takes their minima (vectorised reductions, _least).
        # The forward pass starts the sums from zero rather than the (unwritten) total: 0 + v == v, as v >= +0.
        r_min = inf
        if paths == 2:
            for d in range(nd):
                v = _step(costs[k, d], vecs[rp, d], vecs[rp, d + 1], vecs[rp, d + 2], rj, p1, rmn)
                vecs[r, d + 1] = v
                total[k, d] = (zero if step > 0 else total[k, d]) + v
                r_min = _least(r_min, v)
        else:
            cv = cur * w + xx
            if 0 <= y_from < h and index[y_from, xx] >= 0:
                cp, cmn = (1 - cur) * w + xx, cols_min[1 - cur, xx]
            else:
                cp, cmn = 2 * w, zero
            cj = cmn + p2
            c_min = inf
            for d in range(nd):
                v = _step(costs[k, d], vecs[rp, d], vecs[rp, d + 1], vecs[rp, d + 2], rj, p1, rmn)
                c = _step(costs[k, d], cols[cp, d], cols[cp, d + 1], cols[cp, d + 2], cj, p1, cmn)
                vecs[r, d + 1] = v
                cols[cv, d + 1] = c
                total[k, d] = ((zero if step > 0 else total[k, d]) + v) + c
                r_min = _least(r_min, v)
                c_min = _least(c_min, c)
            cols_min[cur, xx] = c_min
        r = 1 - r


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
def match_features(fl, fr, counts, active, recent, prior, max_d, row_tol, p1, p2, paths, temporal_weight, lr_tol,
                   subpixel, min_neighbours, isolated_below, fill_radius, confirm, work, rowbuf, planes):
    """Match one window's normalised features; return the answers at the left camera's event pixels.

    Parameters
    ----------
    fl, fr : (2, H, W) float64 ndarray
        Normalised features of the left and right camera (rounded to float32 where they are compared).
    counts : (2, H, W) int ndarray
        The left camera's event counts of the window per polarity (anchors: pixels with events).
    active : (H, W) bool ndarray
        The left pixels the semi-global paths run through (anchors must be among them).
    recent : (H, W) bool ndarray
        Left pixels with an event in the last two windows (the noise filter's neighbours).
    prior : (H, W) float64 ndarray
        Disparity of the previous window per pixel, NaN where none (temporal coherence).
    max_d, row_tol, p1, p2, paths, temporal_weight, lr_tol, subpixel, min_neighbours, isolated_below, fill_radius,
    confirm
        :class:`~cvstereo.matchers.fused.params.FusedParams` fields (``isolated_below``: its
        ``isolated_max_uncertainty``; ``confirm``: its ``fill_confirms``).
    work : (2, n, max_d + 1) float32 ndarray
        Scratch for at least the n active pixels: the sum of their paths and their cost (kept by the caller:
        fresh pages cost more than the arithmetic).
    rowbuf : tuple of ndarrays
        Scratch ``(cols, vecs)``, (2 W + 1, max_d + 3) and (3, max_d + 3) float32: the column path's current and
        previous sensor row (row ``cur * W + x``), the row path's current and previous vector, each with a last row
        of zeros, and a first and last column of inf, that are never written (see :func:`_row_pass`).
    planes : tuple of ndarrays
        Scratch kept between windows: ``(right_rev, index)``, (H, 2, W + max_d + 1) float32 zeros and (H, W)
        int64.

    Returns
    -------
    x, y, pol : (M,) int ndarrays; disparity, uncertainty : (M,) float64 ndarrays
        Every answer, in raster order (row, then column): uncertainty is at most 1, and the caller keeps those
        within ``max_uncertainty`` after the occlusion test (:func:`cvstereo.matchers.fused.matcher.finish_window`).
    """
    _, h, w = fl.shape
    nd = max_d + 1
    # Compact storage of the active pixels, raster order; each row's pixels are a contiguous range.
    right_rev, index = planes
    row_start = np.empty(h + 1, np.int64)
    slot_start = np.empty(h + 1, np.int64)  # output slots: the anchors, raster order
    n = 0
    n_anchor = 0
    for yy in range(h):
        row_start[yy] = n
        slot_start[yy] = n_anchor
        for xx in range(w):
            if active[yy, xx]:
                index[yy, xx] = n
                n += 1
                if counts[0, yy, xx] + counts[1, yy, xx] > 0:
                    n_anchor += 1
            else:
                index[yy, xx] = -1
    row_start[h] = n
    slot_start[h] = n_anchor
    if n_anchor == 0:
        none = np.empty(0, np.int64)
        return none, none.copy(), none.copy(), np.empty(0), np.empty(0)
    ax = np.empty(n, np.int64)
    for yy in range(h):
        for xx in range(w):
            if index[yy, xx] >= 0:
                ax[index[yy, xx]] = xx
    # The right features mirrored along the row, zero beyond the left edge (see _row_pass; the zeros were
    # written when the array was made).
    for yy in range(h):
        for c in range(2):
            for xx in range(w):
                right_rev[yy, c, w - 1 - xx] = fr[c, yy, xx]
    p1, p2 = np.float32(p1), np.float32(p2)  # float32 steps throughout (see the module docstring)
    total, costs = work[0, :n], work[1, :n]
    cols, vecs = rowbuf
    cols_min = np.empty((2, w), np.float32)
    # Forward pass (top to bottom, left to right): total = row path from the left (+ column path from above).
    cur = 0
    for yy in range(h):
        if row_start[yy] < row_start[yy + 1]:
            _row_pass(fl, right_rev, prior, index, ax, yy, row_start[yy], row_start[yy + 1], 1, row_tol,
                      temporal_weight, p1, p2, paths, total, costs, vecs, cols, cols_min, cur)
            cur = 1 - cur
    # Backward pass (bottom to top, right to left): the row path from the right and the column path from below
    # are added; then the row's answers, while its sums are in the cache.
    right_v = np.empty(w, np.float32)  # the right pixels' least total and its disparity (-1: none), mirrored
    right_d = np.empty(w, np.int32)
    out_x = np.empty(n_anchor, np.int64)
    out_y = np.empty(n_anchor, np.int64)
    out_p = np.empty(n_anchor, np.int64)
    out_d = np.empty(n_anchor)
    out_u = np.empty(n_anchor)
    out_ok = np.empty(n_anchor, np.bool_)
    out_has = np.zeros(n_anchor, np.bool_)
    for yy in range(h - 1, -1, -1):
        k0, k1 = row_start[yy], row_start[yy + 1]
        if k0 == k1:
            continue
        if paths > 0:
            _row_pass(fl, right_rev, prior, index, ax, yy, k1 - 1, k0 - 1, -1, row_tol, temporal_weight, p1, p2,
                      paths, total, costs, vecs, cols, cols_min, cur)
            cur = 1 - cur
        if slot_start[yy] == slot_start[yy + 1]:
            continue
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
        slot = slot_start[yy]
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
            isolated = neighbours < min_neighbours
            if isolated and isolated_below <= 0.0:
                continue  # no isolated pixel can answer: skip the work
            # The first least disparity (argmin's), then the least more than SECOND_BEST_GAP_PX away from it.
            low = _min_of(total, k, 0, nd)
            best = 0
            while total[k, best] != low:
                best += 1
            second = np.inf
            if best > SECOND_BEST_GAP_PX:
                second = _min_of(total, k, 0, best - SECOND_BEST_GAP_PX)
            if best + SECOND_BEST_GAP_PX + 1 < nd:
                second = min(second, _min_of(total, k, best + SECOND_BEST_GAP_PX + 1, nd))
            ratio = 1.0 if second == 0.0 else np.float64(total[k, best]) / second
            consistent = True
            if lr_tol >= 0:
                xr = xx - best
                best_r = right_d[w - 1 - xr] if xr >= 0 else -1
                consistent = best_r >= 0 and abs(best_r - best) <= lr_tol
            u = RATIO_UNCERTAINTY * ratio if consistent else RATIO_UNCERTAINTY * ratio + LR_PENALTY
            if isolated and not u < isolated_below:
                continue
            disp = float(best)
            if subpixel and 0 < best < nd - 1:
                a, b, c = np.float64(total[k, best - 1]), np.float64(total[k, best]), np.float64(total[k, best + 1])
                den = (a - 2.0 * b) + c
                if den > 0.0:
                    delta = (a - c) / (2.0 * den)
                    disp = disp + min(max(delta, -SUBPIXEL_MAX_SHIFT_PX), SUBPIXEL_MAX_SHIFT_PX)
            out_x[i] = xx
            out_y[i] = yy
            out_p[i] = 1 if counts[1, yy, xx] >= counts[0, yy, xx] else 0
            out_d[i] = disp
            out_u[i] = u
            out_ok[i] = consistent
            out_has[i] = True
    out_x, out_y, out_p = out_x[out_has], out_y[out_has], out_p[out_has]
    out_d, out_u, out_ok = out_d[out_has], out_u[out_has], out_ok[out_has]
    m = out_x.size
    # Inconsistent winners take the median of the consistent answers around them (when there are any), or are
    # confirmed by it when they agree with it.
    # The consistent answers, in raster order: row y's are cons_x/cons_d[cons_start[y]:cons_start[y + 1]], sorted
    # by x. A square then reads, per row, only the answers within it (found by bisection), in the order a scan of
    # the square's pixels would meet them: a few hundred pixel reads per filled pixel fewer.
    cons_x = np.empty(m, np.int64)
    cons_d = np.empty(m)
    cons_start = np.zeros(h + 1, np.int64)
    n_cons = 0
    for i in range(m):
        if out_ok[i]:
            cons_x[n_cons] = out_x[i]
            cons_d[n_cons] = out_d[i]
            n_cons += 1
            cons_start[out_y[i] + 1] += 1
    for yy in range(h):
        cons_start[yy + 1] += cons_start[yy]
    vals = np.empty((2 * fill_radius + 1) ** 2)
    picked = np.empty_like(vals)
    hist = np.zeros(MEDIAN_BINS_PER_PX * nd, np.int64)
    for i in range(m):
        if not out_ok[i] and fill_radius > 0:
            c = 0
            x_lo, x_hi = out_x[i] - fill_radius, out_x[i] + fill_radius
            for y2 in range(max(out_y[i] - fill_radius, 0), min(out_y[i] + fill_radius + 1, h)):
                lo, hi = cons_start[y2], cons_start[y2 + 1]
                while lo < hi:  # the row's first answer at or right of x_lo
                    mid = (lo + hi) // 2
                    if cons_x[mid] < x_lo:
                        lo = mid + 1
                    else:
                        hi = mid
                while lo < cons_start[y2 + 1] and cons_x[lo] <= x_hi:
                    vals[c] = cons_d[lo]
                    c += 1
                    lo += 1
            if c > 0:
                med = median_of(vals, c, hist, picked)
                if confirm and abs(out_d[i] - med) <= lr_tol:
                    out_u[i] = out_u[i] - LR_PENALTY  # confirmed by the consistent answers around it
                else:
                    out_d[i] = med
    return out_x, out_y, out_p, out_d, out_u
