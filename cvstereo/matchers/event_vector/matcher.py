"""Event-vector matcher (thesis 3.6, Algorithm 4): compare each event's distances to the neighbouring event
accumulations in its row with those of candidate pixels in the other camera's row.

For an event at (x, y) whose own dynamic frame has ``|D(x, y)| >= threshold`` before its update: the pixels
of row y with ``|D| >= threshold`` form runs ("event accumulations"); x lies in one of them. Its vector is
(a, b): a = distance from x to the nearest above-threshold pixel left of x's own run, b = the same to the
right, each signed by the sign of D at that pixel; 0 where there is none **[choice]**. Candidates x2 lie in
the same row of the other camera's frame (as it stands at the event's time), at disparities
0 .. ``max_disparity`` on the geometrically possible side (right-camera events look towards larger x, left
towards smaller); with ``require_candidate_threshold`` (default) only pixels with ``|D2| >= threshold`` and
the sign of D(x, y) count **[choice]**, without it every x2 does, as Algorithm 4 literally does (a pixel below
the threshold has an empty run of its own: its vector points to the nearest above-threshold pixels). Cost
``|a1 - a2| + |b1 - b2|``; the least cost below ``max_cost`` wins, ties to the smallest disparity.

Beyond the thesis (each a field of :class:`~cvstereo.matchers.event_vector.params.EventVectorParams` whose default
switches it off): ``run_ends`` extends each vector by how many pixels of the pixel's own run lie left and right of it,
so that the cost also places a candidate within its run; ``cost_slack`` and ``cost_ratio`` bound the least cost by a
slack plus a multiple of the event vector's length; ``tie_break="centre"`` reports the middle of the disparities of
equal least cost (possibly half a pixel) instead of the smallest. The ``adaptive`` set (:mod:`cvstereo.matchers.sets`)
turns all of them on, with separate OFF and ON frames and a wider splat (5x5, sigma 1.5 px): the runs are only as
contiguous as the frame is smooth, and a 3x3 splat of a sparse stream leaves holes in an edge's run wherever no event
fell within a pixel.

Search **[implementation, same result]**: rows are read as 64-pixel bit masks of the above-threshold pixels (and, for
candidates, of those of the event's sign), built without a branch per pixel and skipping 16-column blocks whose
magnitude bound says that they hold none (:mod:`cvstereo.frames.dynamic`); runs, their ends and the pixels beyond them
are then found with bit operations (an edge's runs and gaps alternate every few pixels, and a test per pixel
mispredicted at every change). The event's own vector comes from a mask of the 64 pixels around it; with
``require_candidate_threshold`` the other row's mask covers the candidate range, and only runs holding a candidate are
visited (a run's pixels share the ends of their vectors; the least cost of a run's candidates is one branch-free loop).
Where a run or gap reaches beyond a mask, a walk in the frame goes on, skipping blocks
(:func:`cvstereo.matchers._shared.frame_bounds.skip_below`).

Both cameras' events are processed in one merged order (by time, left first at equal times), see
:mod:`cvstereo.matchers._shared.merge_order` and :mod:`cvstereo.matchers._shared.event_common`. The reference
implementation is :func:`cvstereo.matchers.event_vector.reference.event_vector_reference`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.matchers._shared.signal_level`): the threshold (0.8),
which decides both which events are matched and which pixels form the accumulations, becomes ``threshold_scale`` times
each camera's signal level (the 0.9 quantile of the |D| its events read at their pixels over the last second): the
event's own row uses its camera's, the candidate row the other camera's, since D grows with the events per edge. The
cost is a distance in pixels and ``max_cost`` (1000) Algorithm 4's "no match yet" start value: both stay absolute, as do
the disparity range (geometry) and the decay (time).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros

from cvstereo.frames.accumulate import polarity_sign
from cvstereo.frames.dynamic import NEXT_TICK, TOUCHED, tick_due
from cvstereo.matchers._shared.event_common import MergedEventMatcher, emit_match
from cvstereo.matchers._shared.frame_bounds import (
    BOUND_SHIFT,
    advance_due_bounded,
    block_bounds,
    skip_below,
    splat_bounded,
)
from cvstereo.matchers._shared.merge_order import stream_event
from cvstereo.matchers.event_vector.params import EventVectorParams

__all__ = ["EventVectorMatcher"]


@njit(cache=True, inline="always")
def _sign(v):
    return 1 if v > 0 else (-1 if v < 0 else 0)


@njit(cache=True, inline="always")
def _above(stored, cam, slot, y, k, c, threshold):
    return abs(stored[cam, slot, y, k] * c) >= threshold


@njit(cache=True, inline="always")
def _word_masks(stored, bound, cam, slot, y, base, n, c, threshold, sign):
    """Bit masks of the n <= 64 pixels base.. of a row (bit i: pixel base + i; base a multiple of the bounds'
    block): the above-threshold ones, and those of them of sign ``sign`` (+-1.0: ``v * sign >= threshold``, as
    the threshold is positive). A block whose bound says that it holds no above-threshold pixel is not read
    (sparse rows of large sensors); the others with no branch per pixel: an edge's runs and gaps alternate every
    few pixels, and a test per pixel mispredicted at each change."""
    ma = mc = np.uint64(0)
    for blk in range(0, n, 1 << BOUND_SHIFT):
        if bound[cam, slot, y, (base + blk) >> BOUND_SHIFT] * c >= threshold:
            for i in range(blk, min(blk + (1 << BOUND_SHIFT), n)):
                v = stored[cam, slot, y, base + i] * c
                ma |= np.uint64(abs(v) >= threshold) << np.uint64(i)
                mc |= np.uint64(v * sign >= threshold) << np.uint64(i)
    return ma, mc


@njit(cache=True, inline="always")
def _low_bits(k):
    """A word with its k lowest bits set (0 <= k <= 64)."""
    return np.uint64(0xFFFFFFFFFFFFFFFF) if k >= 64 else (np.uint64(1) << np.uint64(k)) - np.uint64(1)


@njit(cache=True)
def _own_vector(stored, bound, cam, slot, y, x, c, threshold):
    """The event's vector (a, b) and the pixels of its run left and right of x (l, r).

    From a bit mask of the above-threshold pixels of the 64 around x (:func:`_word_masks`): the ends of x's run
    and the next above-threshold pixels beyond them are its bits' neighbours; where a run or gap reaches the
    window's end, a walk in the frame goes on from there. A function of its own, not inlined: inlined, its
    walks kept the atomic reference counting of ``stored`` and ``bound`` around them on every matched event; a
    call passes them borrowed."""
    width = stored.shape[3]
    base = (max(0, x - 32) >> BOUND_SHIFT) << BOUND_SHIFT  # a block's start (_word_masks), 32..47 px left of x
    n = min(64, width - base)
    m, _ = _word_masks(stored, bound, cam, slot, y, base, n, c, threshold, 1.0)
    i = x - base  # x is above the threshold (the kernel asks only then)
    # Left: the first pixel below the threshold left of x, then the first one above it beyond that.
    gap = ~m & _low_bits(i)
    if gap != 0:
        j = 63 - leading_zeros(gap)
        left = i - j - 1
        more = m & _low_bits(j)
        if more != 0:
            k = base + 63 - leading_zeros(more)
        else:
            k = skip_below(stored, bound, cam, slot, y, base - 1, -1, -1, c, threshold)
    else:  # x's run reaches the window's left end: walk on in the frame
        k = base - 1
        while k >= 0 and _above(stored, cam, slot, y, k, c, threshold):
            k -= 1
        left = x - k - 1
        k = skip_below(stored, bound, cam, slot, y, max(k - 1, -1), -1, -1, c, threshold)
    a = _sign(stored[cam, slot, y, k] * c) * (x - k) if k >= 0 else 0
    # Right, the same.
    gap = ~m & _low_bits(n) & ~_low_bits(i + 1)
    if gap != 0:
        j = trailing_zeros(gap)
        right = j - i - 1
        more = m & ~_low_bits(j + 1)
        if more != 0:
            k = base + trailing_zeros(more)
        else:
            k = skip_below(stored, bound, cam, slot, y, base + n, 1, width, c, threshold)
    else:
        k = base + n
        while k < width and _above(stored, cam, slot, y, k, c, threshold):
            k += 1
        right = k - x - 1
        k = skip_below(stored, bound, cam, slot, y, min(k + 1, width), 1, width, c, threshold)
    b = _sign(stored[cam, slot, y, k] * c) * (k - x) if k < width else 0
    return a, b, left, right


@njit(cache=True, inline="always")
def _row_masks(stored, bound, other, slot, y, lo, hi, c, threshold, s1, above, cand):
    """:func:`_word_masks` of the pixels lo..hi of the other row, 64 to a word (bit i of word w: pixel
    lo + 64 w + i): ``above`` the above-threshold ones, ``cand`` those of them of sign ``s1`` (the
    candidates)."""
    sign = np.float64(s1)
    for w in range((hi - lo) // 64 + 1):
        base = lo + 64 * w
        above[w], cand[w] = _word_masks(stored, bound, other, slot, y, base, min(64, hi - base + 1), c, threshold, sign)


@njit(cache=True, inline="always")
def _next_bit(words, lo, k, hi, want):
    """The first pixel in k..hi whose bit in ``words`` (:func:`_row_masks`, from ``lo``) is ``want`` (1 or 0), or
    hi + 1 if none."""
    while k <= hi:
        w = (k - lo) >> 6
        word = words[w] if want else ~words[w]
        word >>= np.uint64((k - lo) & 63)
        if word != 0:
            return min(k + trailing_zeros(word), hi + 1)
        k = lo + ((w + 1) << 6)
    return hi + 1


@njit(cache=True, inline="always")
def _prev_bit(words, lo, k, want):
    """The last pixel in lo..k whose bit in ``words`` (:func:`_row_masks`, from ``lo``) is ``want`` (1 or 0), or
    lo - 1 if none."""
    while k >= lo:
        w = (k - lo) >> 6
        word = words[w] if want else ~words[w]
        word <<= np.uint64(63 - ((k - lo) & 63))  # pixel k to the top bit, those beyond it out
        if word != 0:
            return k - leading_zeros(word)
        k = lo + (w << 6) - 1
    return lo - 1


@njit(cache=True, inline="always")
def _left_of(stored, bound, other, slot, y, lo, c, threshold):
    """What a scan of the other row from pixel 0 holds on reaching lo: ``last`` = the last above-threshold pixel
    before lo, and if that is lo - 1 (lo's run began left of it) ``start`` = where that run began and ``prev`` =
    the last above-threshold pixel before it (-1 for none; ``s_*`` their signs), found by walking out of lo's
    run and gap to the left. Returns (last, s_last, prev, s_prev, start)."""
    prev, s_prev, last, s_last, start = -1, 0, -1, 0, -1
    k = lo - 1
    if k >= 0 and _above(stored, other, slot, y, k, c, threshold):
        last, s_last = k, _sign(stored[other, slot, y, k] * c)
        k -= 1
        while k >= 0 and _above(stored, other, slot, y, k, c, threshold):
            k -= 1
        start = k + 1
        k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c, threshold)
        if k >= 0:
            prev, s_prev = k, _sign(stored[other, slot, y, k] * c)
    else:  # k is below the threshold or -1: the skip starts beyond it
        k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c, threshold)
        if k >= 0:
            last, s_last = k, _sign(stored[other, slot, y, k] * c)
    return last, s_last, prev, s_prev, start


@njit(cache=True, inline="always")
def _search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c, threshold, s1, a1, b1, l1, r1, run_ends, above,
                 cand):
    """Candidates = the above-threshold pixels of D's sign in lo..hi of the other row, found from bit masks of
    the row from lo's block to hi (:func:`_row_masks`): from each stretch of candidates to its run (the
    above-threshold pixels around it) and the run's neighbours, so that runs without a candidate are never
    visited. A run's pixels share their vector's ends: the last above-threshold pixel before the run and the
    first one after it; a run, or a gap, that goes on beyond the masks is followed in the frame (skipping
    blocks; :func:`_left_of`, only when needed). Returns the least cost and the smallest and largest disparity of
    that cost (:func:`_keep_least`, :func:`_least_on_run`)."""
    width = stored.shape[3]
    org = (lo >> BOUND_SHIFT) << BOUND_SHIFT  # the masks' first pixel: lo's block (_word_masks)
    _row_masks(stored, bound, other, slot, y, org, hi, c, threshold, s1, above, cand)
    cand[0] &= ~_low_bits(lo - org)  # no candidates left of lo
    best, d_lo, d_hi = np.inf, -1, -1
    known = False  # whether the scan state left of org (_left_of) is computed
    last, s_last, l_prev, l_s_prev, l_start = -1, 0, -1, 0, -1
    u = _next_bit(cand, org, lo, hi, 1)
    while u <= hi:
        start = _prev_bit(above, org, u, 0) + 1  # the run of u: start..end
        prev = _prev_bit(above, org, start - 1, 1) if start > org else org - 1  # and the run before it
        if prev >= org:
            s_prev = _sign(stored[other, slot, y, prev] * c)
        else:
            if not known:
                last, s_last, l_prev, l_s_prev, l_start = _left_of(stored, bound, other, slot, y, org, c, threshold)
                known = True
            if start == org and last == org - 1 and org > 0:  # the run began left of org
                start, prev, s_prev = l_start, l_prev, l_s_prev
            else:
                prev, s_prev = last, s_last
        end = _next_bit(above, org, u, hi, 0) - 1
        if end == hi:  # the run may go on beyond hi
            while end + 1 < width and _above(stored, other, slot, y, end + 1, c, threshold):
                end += 1
        nxt = _next_bit(above, org, end + 2, hi, 1) if end + 2 <= hi else hi + 1  # end + 1 is below
        if nxt > hi:
            nxt = skip_below(stored, bound, other, slot, y, min(max(end + 2, hi + 1), width), 1, width, c, threshold)
        s_nxt = _sign(stored[other, slot, y, nxt] * c) if nxt < width else 0
        top = min(end, hi)
        while u <= top:  # each stretch u..v of candidates in the run
            v = _next_bit(cand, org, u, top, 0) - 1
            cost, p, q = _least_on_run(u, v, a1, b1, l1, r1, run_ends, prev, s_prev, nxt, s_nxt, width, start, end)
            best, d_lo, d_hi = _keep_least(best, d_lo, d_hi, cost, x - q if cam == 0 else p - x)
            best, d_lo, d_hi = _keep_least(best, d_lo, d_hi, cost, x - p if cam == 0 else q - x)
            u = _next_bit(cand, org, v + 1, top, 1)
        u = _next_bit(cand, org, top + 1, hi, 1)
    return best, d_lo, d_hi


@njit(cache=True, inline="always")
def _least_on_run(u, v, a1, b1, l1, r1, run_ends, prev, s_prev, nxt, s_nxt, width, start, end):
    """The least cost over the candidates u..v of the run start..end whose vector ends at prev (sign s_prev; -1:
    none) and nxt (s_nxt; the width: none), and the first and last x2 of that cost.

    Each term of the cost is linear in x2 inside an absolute value (``a1 - a2 = (a1 + s_prev prev) - s_prev x2``
    and so on), so the loop over x2 is a few integer operations with no branch to mispredict."""
    ca = s_prev if prev >= 0 else 0
    cb = s_nxt if nxt < width else 0
    ka = a1 + ca * prev
    kb = b1 - cb * nxt
    re = 1 if run_ends else 0
    kl = l1 + start
    kr = r1 - end
    best = abs(ka - ca * u) + abs(kb + cb * u) + re * (abs(kl - u) + abs(kr + u))
    p = q = u
    for x2 in range(u + 1, v + 1):
        cost = abs(ka - ca * x2) + abs(kb + cb * x2) + re * (abs(kl - x2) + abs(kr + x2))
        if cost < best:
            p = x2
        best = min(best, cost)
        if cost == best:
            q = x2
    return best, p, q


@njit(cache=True)
def _search_all(stored, bound, other, slot, y, x, cam, lo, hi, c, threshold, a1, b1, l1, r1, run_ends, last,
                s_last, prev, s_prev, start, row, vec_a, vec_b, vec_l, vec_r):
    """Candidates = every pixel of lo..hi of the other row (Algorithm 4 literally): its vectors in two passes
    (the same numbers as walking from each), left to right from the scan state at lo, then right to left from
    the mirror state. Returns the least cost and the smallest and largest disparity of that cost."""
    width = stored.shape[3]
    for xx in range(max(0, lo - 1), min(width - 1, hi + 1) + 1):
        row[xx] = stored[other, slot, y, xx] * c
    for xx in range(lo, hi + 1):
        if abs(row[xx]) >= threshold:
            if xx == 0 or abs(row[xx - 1]) < threshold:
                prev, s_prev, start = last, s_last, xx
            vec_a[xx] = s_prev * (xx - prev) if prev >= 0 else 0
            vec_l[xx] = xx - start
            last, s_last = xx, _sign(row[xx])
        else:
            vec_a[xx] = s_last * (xx - last) if last >= 0 else 0
            vec_l[xx] = 0
    # The mirror state at hi: walk out of hi + 1's run and gap to the right (``start``: where the current run
    # began, seen from the right).
    prev, s_prev, last, s_last, start = width, 0, width, 0, width
    k = hi + 1
    if k < width and abs(row[k]) >= threshold:
        last, s_last = k, _sign(row[k])
        while k < width and _above(stored, other, slot, y, k, c, threshold):
            k += 1
        start = k - 1
        k = skip_below(stored, bound, other, slot, y, k, 1, width, c, threshold)
        if k < width:
            prev, s_prev = k, _sign(stored[other, slot, y, k] * c)
    else:
        k = skip_below(stored, bound, other, slot, y, k, 1, width, c, threshold)
        if k < width:
            last, s_last = k, _sign(stored[other, slot, y, k] * c)
    for xx in range(hi, lo - 1, -1):
        if abs(row[xx]) >= threshold:
            if xx == width - 1 or abs(row[xx + 1]) < threshold:
                prev, s_prev, start = last, s_last, xx
            vec_b[xx] = s_prev * (prev - xx) if prev < width else 0
            vec_r[xx] = start - xx
            last, s_last = xx, _sign(row[xx])
        else:
            vec_b[xx] = s_last * (last - xx) if last < width else 0
            vec_r[xx] = 0
    best, d_lo, d_hi = np.inf, -1, -1
    for x2 in range(lo, hi + 1):
        cost = abs(a1 - vec_a[x2]) + abs(b1 - vec_b[x2])
        if run_ends:
            cost += abs(l1 - vec_l[x2]) + abs(r1 - vec_r[x2])
        best, d_lo, d_hi = _keep_least(best, d_lo, d_hi, cost, x - x2 if cam == 0 else x2 - x)
    return best, d_lo, d_hi


@njit(cache=True, inline="always")
def _keep_least(best, d_lo, d_hi, cost, d):
    """The least cost so far and the smallest and largest disparity of that cost, after candidate ``d``."""
    if cost < best:
        return cost, d, d
    if cost == best:
        return best, min(d_lo, d), max(d_hi, d)
    return best, d_lo, d_hi


@njit(cache=True, inline="always")
def _choose(best, d_lo, d_hi, max_cost, limit, centre):
    """The disparity of the least cost ``best`` if below ``max_cost`` and at most ``limit`` (if >= 0): the
    smallest one of that cost ``d_lo``, or with ``centre`` the middle of it and the largest ``d_hi``; -1 for
    none."""
    if not best < max_cost or (limit >= 0 and best > limit):
        return -1.0
    return 0.5 * (d_lo + d_hi) if centre else float(d_lo)


# error_model="numpy": no zero check of the splat's division by the (positive) scale, whose exception path kept
# numba's reference counting of the frame arrays around every splat.
@njit(cache=True, error_model="numpy")
def _event_vector_kernel(stream, stored, scale, clock, bound, kernel, decay, period, thresholds, require, max_d,
                         max_cost, run_ends, cost_ratio, cost_slack, centre, out_cam, out_index, out_disparity,
                         values, right_start):
    """Process the merged stream (:func:`cvstereo.matchers._shared.merge_order.merged_stream`); one output row per
    matched event; returns the count. ``values``, ``right_start``: as for the event-area kernel."""
    width = stored.shape[3]
    row = np.empty(width)
    vec_a, vec_b = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    vec_l, vec_r = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    above = np.empty(max_d // 64 + 2, dtype=np.uint64)  # masks of a candidate range (_search_runs)
    cand = np.empty(max_d // 64 + 2, dtype=np.uint64)
    n = 0
    for j in range(stream.shape[1]):
        cam, i, t, x, y, p, slot = stream_event(stream, j)
        other = 1 - cam
        # The test here, advance_due_bounded only when due: an inlined helper holding both bound the four arrays
        # to new variables and numba kept their atomic reference counting on every event (8 atomics).
        for cc in (cam, other):
            if tick_due(clock[cc, NEXT_TICK], clock[cc, TOUCHED], t, period):
                advance_due_bounded(stored, scale, clock, bound, cc, t, decay, period)
        c1 = scale[cam]
        value = stored[cam, slot, y, x] * c1
        values[cam * right_start + i] = abs(value)
        if abs(value) >= thresholds[cam]:
            a1, b1, l1, r1 = _own_vector(stored, bound, cam, slot, y, x, c1, thresholds[cam])
            lo = x if cam == 1 else max(0, x - max_d)  # the candidate pixels lo..hi of the other row
            hi = min(width - 1, x + max_d) if cam == 1 else x
            c2 = scale[other]
            threshold = thresholds[other]  # the other camera's accumulations, by its own threshold
            if require:
                best, d_lo, d_hi = _search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold,
                                                _sign(value), a1, b1, l1, r1, run_ends, above, cand)
            else:
                last, s_last, prev, s_prev, start = _left_of(stored, bound, other, slot, y, lo, c2, threshold)
                best, d_lo, d_hi = _search_all(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold, a1, b1,
                                               l1, r1, run_ends, last, s_last, prev, s_prev, start, row, vec_a,
                                               vec_b, vec_l, vec_r)
            length = abs(a1) + abs(b1) + (l1 + r1 if run_ends else 0)
            limit = cost_slack + cost_ratio * length if cost_ratio > 0 else -1.0
            disparity = _choose(best, d_lo, d_hi, max_cost, limit, centre)
            n = emit_match(out_cam, out_index, out_disparity, n, cam, i, disparity)
        splat_bounded(stored, scale, clock, bound, cam, slot, x, y, polarity_sign(p), kernel)
    return n


class EventVectorMatcher(MergedEventMatcher):
    """Event-vector matcher (thesis Algorithm 4): each event's distances to the neighbouring accumulations of its
    row, compared with those of candidate pixels in the other camera's row.

    Streaming (``feed`` / ``flush``), for events of either camera; its reference is
    :func:`cvstereo.matchers.event_vector.reference.event_vector_reference`.

    Parameters
    ----------
    params : EventVectorParams, optional
        Default: the thesis' (its only variant).
    resolution : (width, height), keyword-only
    """

    method = "event-vector"
    anchor = "event"
    Params = EventVectorParams
    variants: ClassVar[dict[str, dict]] = {"default": {}}

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._bound = block_bounds(self._bank.stored)  # kept by the kernel (frame_bounds.splat_bounded)

    def _run_kernel(self, stream, thresholds, out_cam, out_index, out_disparity, out_values) -> int:
        prm, bank = self.params, self._bank
        return int(_event_vector_kernel(stream, bank.stored, bank.scale, bank.clock, self._bound,
                                        bank.kernel, *bank.decay_args, thresholds,
                                        bool(prm.require_candidate_threshold), int(prm.max_disparity),
                                        float(prm.max_cost), bool(prm.run_ends), float(prm.cost_ratio),
                                        float(prm.cost_slack), prm.tie_break == "centre", out_cam, out_index,
                                        out_disparity, *out_values))
