"""Event-vector's row scans: an event's own vector and the least cost over a candidate range of the other row.

The search of :mod:`cvstereo.matchers.event_vector.matcher` (see its module doc, "Search"): rows read as 64-pixel bit
masks of the above-threshold pixels, runs and the pixels beyond them found with bit operations, walks in the frame
skipping blocks where a run or gap reaches beyond a mask. Each function reads one row ``y`` of one camera's frame and
its block bounds (:mod:`cvstereo.matchers._shared.frame_bounds`), so that row bands need no rows beyond an event's own
(:mod:`cvstereo.matchers._shared.row_bands`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros

from cvstereo.matchers._shared.frame_bounds import BOUND_SHIFT, skip_below

__all__ = ["choose", "left_of", "own_vector", "search_all", "search_runs", "sign_of"]


@njit(cache=True, inline="always")
def sign_of(v):
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
def own_vector(stored, bound, cam, slot, y, x, c, threshold):
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
    a = sign_of(stored[cam, slot, y, k] * c) * (x - k) if k >= 0 else 0
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
    b = sign_of(stored[cam, slot, y, k] * c) * (k - x) if k < width else 0
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
def left_of(stored, bound, other, slot, y, lo, c, threshold):
    """What a scan of the other row from pixel 0 holds on reaching lo: ``last`` = the last above-threshold pixel
    before lo, and if that is lo - 1 (lo's run began left of it) ``start`` = where that run began and ``prev`` =
    the last above-threshold pixel before it (-1 for none; ``s_*`` their signs), found by walking out of lo's
    run and gap to the left. Returns (last, s_last, prev, s_prev, start)."""
    prev, s_prev, last, s_last, start = -1, 0, -1, 0, -1
    k = lo - 1
    if k >= 0 and _above(stored, other, slot, y, k, c, threshold):
        last, s_last = k, sign_of(stored[other, slot, y, k] * c)
        k -= 1
        while k >= 0 and _above(stored, other, slot, y, k, c, threshold):
            k -= 1
        start = k + 1
        k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c, threshold)
        if k >= 0:
            prev, s_prev = k, sign_of(stored[other, slot, y, k] * c)
    else:  # k is below the threshold or -1: the skip starts beyond it
        k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c, threshold)
        if k >= 0:
            last, s_last = k, sign_of(stored[other, slot, y, k] * c)
    return last, s_last, prev, s_prev, start


@njit(cache=True, inline="always")
def search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c, threshold, s1, a1, b1, l1, r1, run_ends, above,
                 cand):
    """Candidates = the above-threshold pixels of D's sign in lo..hi of the other row, found from bit masks of
    the row from lo's block to hi (:func:`_row_masks`): from each stretch of candidates to its run (the
    above-threshold pixels around it) and the run's neighbours, so that runs without a candidate are never
    visited. A run's pixels share their vector's ends: the last above-threshold pixel before the run and the
    first one after it; a run, or a gap, that goes on beyond the masks is followed in the frame (skipping
    blocks; :func:`left_of`, only when needed). Returns the least cost and the smallest and largest disparity of
    that cost (:func:`_keep_least`, :func:`_least_on_run`)."""
    width = stored.shape[3]
    org = (lo >> BOUND_SHIFT) << BOUND_SHIFT  # the masks' first pixel: lo's block (_word_masks)
    _row_masks(stored, bound, other, slot, y, org, hi, c, threshold, s1, above, cand)
    cand[0] &= ~_low_bits(lo - org)  # no candidates left of lo
    best, d_lo, d_hi = np.inf, -1, -1
    known = False  # whether the scan state left of org (left_of) is computed
    last, s_last, l_prev, l_s_prev, l_start = -1, 0, -1, 0, -1
    u = _next_bit(cand, org, lo, hi, 1)
    while u <= hi:
        start = _prev_bit(above, org, u, 0) + 1  # the run of u: start..end
        prev = _prev_bit(above, org, start - 1, 1) if start > org else org - 1  # and the run before it
        if prev >= org:
            s_prev = sign_of(stored[other, slot, y, prev] * c)
        else:
            if not known:
                last, s_last, l_prev, l_s_prev, l_start = left_of(stored, bound, other, slot, y, org, c, threshold)
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
        s_nxt = sign_of(stored[other, slot, y, nxt] * c) if nxt < width else 0
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
def search_all(stored, bound, other, slot, y, x, cam, lo, hi, c, threshold, a1, b1, l1, r1, run_ends, last,
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
            last, s_last = xx, sign_of(row[xx])
        else:
            vec_a[xx] = s_last * (xx - last) if last >= 0 else 0
            vec_l[xx] = 0
    # The mirror state at hi: walk out of hi + 1's run and gap to the right (``start``: where the current run
    # began, seen from the right).
    prev, s_prev, last, s_last, start = width, 0, width, 0, width
    k = hi + 1
    if k < width and abs(row[k]) >= threshold:
        last, s_last = k, sign_of(row[k])
        while k < width and _above(stored, other, slot, y, k, c, threshold):
            k += 1
        start = k - 1
        k = skip_below(stored, bound, other, slot, y, k, 1, width, c, threshold)
        if k < width:
            prev, s_prev = k, sign_of(stored[other, slot, y, k] * c)
    else:
        k = skip_below(stored, bound, other, slot, y, k, 1, width, c, threshold)
        if k < width:
            last, s_last = k, sign_of(stored[other, slot, y, k] * c)
    for xx in range(hi, lo - 1, -1):
        if abs(row[xx]) >= threshold:
            if xx == width - 1 or abs(row[xx + 1]) < threshold:
                prev, s_prev, start = last, s_last, xx
            vec_b[xx] = s_prev * (prev - xx) if prev < width else 0
            vec_r[xx] = start - xx
            last, s_last = xx, sign_of(row[xx])
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
def choose(best, d_lo, d_hi, max_cost, limit, centre):
    """The disparity of the least cost ``best`` if below ``max_cost`` and at most ``limit`` (if >= 0): the
    smallest one of that cost ``d_lo``, or with ``centre`` the middle of it and the largest ``d_hi``; -1 for
    none."""
    if not best < max_cost or (limit >= 0 and best > limit):
        return -1.0
    return 0.5 * (d_lo + d_hi) if centre else float(d_lo)
