"""The cost and the semi-global passes of the fused matcher (:func:`cvstereo.matchers.fused._kernels.match_features`
runs them).

Three ways (:data:`FUSED`, :data:`DIRECTIONS`, :data:`SPLIT`) through the same sums, float32 added in the same
order, ``(left + above) + (right + below)``, so that they are bit-identical:

* *directions* (one or two threads): :func:`_row_pass` steps the row and the column path of each pixel in one loop
  over the disparities (the fused order). The forward pass (top to bottom, left to right) writes ``left + above``
  into the sums, the backward pass (bottom to top, right to left) ``right + below`` into a plane of its own; the
  pass that finishes a row second adds them and answers the row. On two threads both passes run at once, on one
  the backward pass follows the forward one (and answers every row). Each pass computes the costs it steps, into a
  ring of :data:`COST_RUN` pixels: computing them again costs less than storing them and reading them back from a
  plane that outgrows the caches.
* *fused* (one thread, planes that fit the caches): the same two passes, but the forward pass stores the costs
  and the backward pass reads them back and adds ``right + below`` to the sums in place.
* *split* (more threads): row paths depend only on their row and column paths only on their column, so
  :func:`_column_run` first runs the column paths, columns in parallel, writing ``above`` into the sums and
  ``below`` into a plane of its own, then :func:`_row_pass` the row paths, rows in parallel: ``above + left``
  (float addition is commutative, so this is ``left + above`` bit for bit), then ``+ (right + below)``.

Costs are computed for a run of a row's pixels at a time (:func:`_costs_of`, at most :data:`COST_RUN` of them, just
before their steps, while they are in the cache).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import cgutils
from numba.extending import intrinsic

from cvstereo.matchers.fused._constants import TEMPORAL_CAP_PX

#: Pixels whose costs :func:`_row_pass` computes in one call of :func:`_costs_of`: a call per pixel costs its
#: arrays' reference counts, a whole row's costs no longer fit the first-level cache. A power of two: the
#: direction passes keep their costs in a ring of this many rows (pixel ``k`` at ``k % COST_RUN``).
COST_RUN = 16

#: The ways through the passes (module docstring): one thread and small planes, one or two threads, more.
FUSED, DIRECTIONS, SPLIT = 0, 1, 2


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
def min_of(v, i, lo, hi):
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


@njit(cache=True, nogil=True)
def _costs_of(fl, right_rev, prior, ax, yy, k0, k1, prm, costs, ring):
    """The costs of row ``yy``'s active pixels ``k0 .. k1 - 1`` (``k0 < k1``) into ``costs[k]``, or with ``ring``
    into ``costs[k % COST_RUN]`` (at most :data:`COST_RUN` pixels).

    ``right_rev[y, c, j]`` is the right feature at column W - 1 - j (zero for j >= W, beyond the left edge), so that
    disparities 0, 1, ... read it forwards from j = W - 1 - x: contiguous loops without branches, which vectorise.
    The least over the tolerated rows is exact in any order, so this equals the reference's np.minimum over rows.
    """
    h = right_rev.shape[0]
    nd = costs.shape[1]
    inf = np.float32(np.inf)
    for k in range(k0, k1):
        xx = ax[k]
        at = k % COST_RUN if ring else k
        l0, l1 = np.float32(fl[0, yy, xx]), np.float32(fl[1, yy, xx])
        j0 = right_rev.shape[2] - nd - 1 - xx
        for d in range(nd):
            costs[at, d] = inf
        for y2 in range(max(yy - prm.row_tol, 0), min(yy + prm.row_tol + 1, h)):
            for d in range(nd):
                # An unsigned index: numba wraps negative indices around, and the test of a signed one kept
                # this loop from vectorising.
                j = np.uint64(j0 + d)
                costs[at, d] = min(costs[at, d], abs(l0 - right_rev[y2, 0, j]) + abs(l1 - right_rev[y2, 1, j]))
        pr = prior[yy, xx]
        if prm.temporal_weight > 0.0 and not np.isnan(pr):
            for d in range(nd):
                costs[at, d] = costs[at, d] + np.float32(prm.temporal_weight * min(abs(d - pr), TEMPORAL_CAP_PX))


@njit(cache=True, nogil=True, inline="always")
def _row_pass(fl, right_rev, prior, index, ax, yy, k_first, k_stop, step, prm, way, total, costs, below, vecs,
              cols, cols_min, cur):
    """One row of one semi-global pass: ``step`` 1 is the forward pass (left to right; with the column path: from
    above), -1 the backward one (right to left; from below). ``way``: :data:`FUSED`, :data:`DIRECTIONS` or
    :data:`SPLIT` (module docstring).

    Costs: the direction passes each compute theirs into the ring ``costs`` (:data:`COST_RUN` rows); the fused and
    split forward passes compute them into ``costs[k]`` (split with 4 paths: :func:`_column_run` did) and the
    backward pass reads them back. The row path runs in ``vecs[0:2]`` (current and previous, taking turns), the
    column path (fused and direction passes) in ``cols[cur * W + x]`` with the previous row's in
    ``cols[(1 - cur) * W + x]``; disparity d is at column d + 1 of them, between columns of inf. A path without a
    predecessor starts at the cost: it steps from the zero row (``vecs[2]``, ``cols[2 * W]``) with minimum 0, which
    adds exactly 0 (``p1, p2 >= 0``).
    Sums: the forward pass writes ``total[k] = left (+ above)`` (split with 4 paths: adds ``left`` to the ``above``
    there); the direction backward pass writes ``right (+ below)`` into ``total[n - 1 - k]`` of a plane of its own,
    the fused one adds it to ``total[k]``, the split one adds ``right + below[k]``. With 0 paths ``total[k]`` is the
    cost.

    Inlined, and every per-pixel loop written out here rather than in helpers that take arrays: each such call
    bound its arrays to new variables, and numba's two atomic reference-count updates per binding cost more than
    the arithmetic.
    """
    h, w = index.shape
    nd = total.shape[1]  # at least 2 (FusedParams: max_disparity >= 1)
    p1, p2, paths = prm.p1, prm.p2, prm.paths
    split4 = way == SPLIT and paths == 4
    columns = paths == 4 and way != SPLIT  # the column path in this pass
    ring = way == DIRECTIONS
    own_costs = ring or (step > 0 and not split4)  # this pass computes the costs it steps
    # The sums start from total[k] (1) or zero (0).
    sums_from = 1 if (way == SPLIT and (step < 0 or split4)) or (way == FUSED and step < 0) else 0
    add_below = step < 0 and split4
    # The direction passes' backward sums are stored mirrored (pixel k at n - 1 - k), so that the pass, which
    # meets the pixels in descending order, writes its plane in ascending order of memory, which the hardware's
    # prefetch serves better than a descending stream of stores.
    mirror = ring and step < 0
    n_all = total.shape[0]
    inf = np.float32(np.inf)
    zero = np.float32(0.0)
    r = 0
    r_min = zero
    y_from = yy - step  # the row the column path comes from
    for k in range(k_first, k_stop, step):
        if own_costs and (k - k_first) % COST_RUN == 0:
            if step > 0:
                _costs_of(fl, right_rev, prior, ax, yy, k, min(k + COST_RUN, k_stop), prm, costs, ring)
            else:
                _costs_of(fl, right_rev, prior, ax, yy, max(k - COST_RUN, k_stop) + 1, k + 1, prm, costs, ring)
        at = k % COST_RUN if ring else k  # this pixel's costs
        o = n_all - 1 - k if mirror else k  # and sums
        if paths == 0:
            for d in range(nd):
                total[o, d] = costs[at, d]
            continue
        xx = ax[k]
        x_from = xx - step
        if 0 <= x_from < w and index[yy, x_from] >= 0:
            rp, rmn = 1 - r, r_min
        else:
            rp, rmn = 2, zero
        rj = rmn + p2
        # The path vectors hold disparity d at column d + 1, between two columns of inf that are never written:
        # the step reads prev[d - 1] and prev[d + 1] at both ends without a case of its own, so that one loop per
        # pixel steps the paths, adds them to the sums and takes their minima (vectorised reductions, _least).
        # Sums that start from zero rather than the (unwritten) total: 0 + v == v, as v >= +0.
        r_min = inf
        if not columns:
            for d in range(nd):
                v = _step(costs[at, d], vecs[rp, d], vecs[rp, d + 1], vecs[rp, d + 2], rj, p1, rmn)
                vecs[r, d + 1] = v
                total[o, d] = (total[o, d] if sums_from else zero) + ((v + below[k, d]) if add_below else v)
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
                v = _step(costs[at, d], vecs[rp, d], vecs[rp, d + 1], vecs[rp, d + 2], rj, p1, rmn)
                c = _step(costs[at, d], cols[cp, d], cols[cp, d + 1], cols[cp, d + 2], cj, p1, cmn)
                vecs[r, d + 1] = v
                cols[cv, d + 1] = c
                total[o, d] = (total[o, d] if sums_from else zero) + (v + c)
                r_min = _least(r_min, v)
                c_min = _least(c_min, c)
            cols_min[cur, xx] = c_min
        r = 1 - r


@njit(cache=True, nogil=True)
def _column_run(fl, right_rev, prior, index, ax, yy, x0, x1, step, prm, out, costs, cols, cols_min, cur):
    """The column paths of row ``yy``'s active pixels in columns ``x0 .. x1 - 1`` (split passes): ``step`` 1 steps
    them from the row above and computes their costs first, -1 from the row below. Each path's value goes to
    ``out[k]``; the path runs in ``cols`` and ``cols_min`` as in :func:`_row_pass` (this chunk's columns only)."""
    h, w = index.shape
    nd = out.shape[1]
    k0 = -1
    k1 = -1
    for xx in range(x0, x1):  # the row's active pixels in these columns: a run of k
        if index[yy, xx] >= 0:
            k1 = index[yy, xx] + 1
            if k0 < 0:
                k0 = index[yy, xx]
    if k0 < 0:
        return
    if step > 0:
        _costs_of(fl, right_rev, prior, ax, yy, k0, k1, prm, costs, False)
    p1, p2 = prm.p1, prm.p2
    inf = np.float32(np.inf)
    y_from = yy - step
    for k in range(k0, k1):
        xx = ax[k]
        cv = cur * w + xx
        if 0 <= y_from < h and index[y_from, xx] >= 0:
            cp, cmn = (1 - cur) * w + xx, cols_min[1 - cur, xx]
        else:
            cp, cmn = 2 * w, np.float32(0.0)
        cj = cmn + p2
        c_min = inf
        for d in range(nd):
            c = _step(costs[k, d], cols[cp, d], cols[cp, d + 1], cols[cp, d + 2], cj, p1, cmn)
            cols[cv, d + 1] = c
            out[k, d] = c
            c_min = _least(c_min, c)
        cols_min[cur, xx] = c_min
