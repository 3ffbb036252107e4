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

Beyond the thesis (each a field of :class:`~calibration_free.params.EventVectorParams` whose default switches
it off): ``run_ends`` extends each vector by how many pixels of the pixel's own run lie left and right of it,
so that the cost also places a candidate within its run; ``cost_slack`` and ``cost_ratio`` bound the least
cost by a slack plus a multiple of the event vector's length; ``tie_break="centre"`` reports the middle of
the disparities of equal least cost (possibly half a pixel) instead of the smallest. The ``adaptive`` set
(:mod:`cvstereo.param_sets`) turns all of them on, with separate OFF and ON frames and a wider splat (5x5,
sigma 1.5 px): the runs are only as contiguous as the frame is smooth, and a 3x3 splat of a sparse stream
leaves holes in an edge's run wherever no event fell within a pixel.

Search **[implementation, same result]**: the walks through gaps skip 16-column blocks whose magnitude bound
says that they hold no above-threshold pixel (:func:`cvstereo.dynamic_frames.skip_below`); the other row is read
only over the candidate range and the walks out of its ends; with ``require_candidate_threshold`` only its runs
of above-threshold pixels are visited (a run's pixels share the ends of their vectors).

Both cameras' events are processed in one merged order (by time, left first at equal times), see
:mod:`calibration_free.merge_order` and :mod:`calibration_free._event_common`. The reference implementation is
:func:`calibration_free.reference.event_vector.event_vector_reference`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.signal_level`): the threshold (0.8), which
decides both which events are matched and which pixels form the accumulations, becomes ``threshold_scale``
times each camera's signal level (the 0.9 quantile of the |D| its events read at their pixels over the last
second): the event's own row uses its camera's, the candidate row the other camera's, since D grows with the
events per edge. The cost is a distance in pixels and ``max_cost`` (1000) Algorithm 4's "no match yet" start
value: both stay absolute, as do the disparity range (geometry) and the decay (time).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numba import njit

from calibration_free._event_common import MergedEventMatcher, emit_match
from calibration_free.params import EventVectorParams
from cvstereo.dynamic_frames import advance_due_bounded, skip_below, splat_bounded, tick_due


@njit(cache=True, inline="always")
def _sign(v):
    return 1 if v > 0 else (-1 if v < 0 else 0)


@njit(cache=True, inline="always")
def _above(stored, cam, slot, y, k, c, threshold):
    return abs(stored[cam, slot, y, k] * c) >= threshold


@njit(cache=True)
def _own_vector(stored, bound, cam, slot, y, x, c, threshold):
    """The event's vector (a, b) and the pixels of its run left and right of x (l, r).

    A function of its own, not inlined: inlined, its walks kept the atomic reference counting of ``stored`` and
    ``bound`` around them on every matched event; a call passes them borrowed."""
    width = stored.shape[3]
    # Walk out of x's run, then on to the next above-threshold pixel, on each side. x is above the threshold
    # (the kernel asks only then), and a walk ends on a pixel below it or at the border: neither is read twice.
    k = x - 1
    while k >= 0 and _above(stored, cam, slot, y, k, c, threshold):
        k -= 1
    left = x - k - 1
    k = skip_below(stored, bound, cam, slot, y, max(k - 1, -1), -1, -1, c, threshold)
    a = _sign(stored[cam, slot, y, k] * c) * (x - k) if k >= 0 else 0
    k = x + 1
    while k < width and _above(stored, cam, slot, y, k, c, threshold):
        k += 1
    right = k - x - 1
    k = skip_below(stored, bound, cam, slot, y, min(k + 1, width), 1, width, c, threshold)
    b = _sign(stored[cam, slot, y, k] * c) * (k - x) if k < width else 0
    return a, b, left, right


@njit(cache=True, inline="always")
def _search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c, threshold, s1, a1, b1, l1, r1, run_ends, last,
                 s_last, prev, s_prev, start):
    """Candidates = the above-threshold pixels of D's sign in lo..hi of the other row: visit its runs, skipping
    the gaps blockwise. A run's pixels share their vector's ends: the last above-threshold pixel before the run
    and the first one after it (found beyond hi if need be). ``last``/``prev``/``start``: the scan state at lo
    (see the kernel). Returns the least cost and the smallest and largest disparity of that cost
    (:func:`_keep_least`)."""
    width = stored.shape[3]
    best, d_lo, d_hi = np.inf, -1, -1
    xx = skip_below(stored, bound, other, slot, y, lo, 1, hi + 1, c, threshold)
    if not (xx == lo and lo > 0 and _above(stored, other, slot, y, lo - 1, c, threshold)):
        prev, s_prev, start = last, s_last, xx  # lo's run (if any) does not come from the left of lo
    while xx <= hi:
        end = xx
        while end + 1 < width and _above(stored, other, slot, y, end + 1, c, threshold):
            end += 1
        nxt = skip_below(stored, bound, other, slot, y, min(end + 2, width), 1, width, c, threshold)  # end + 1 is below
        s_nxt = _sign(stored[other, slot, y, nxt] * c) if nxt < width else 0
        for x2 in range(xx, min(end, hi) + 1):
            if _sign(stored[other, slot, y, x2] * c) != s1:
                continue
            a2 = s_prev * (x2 - prev) if prev >= 0 else 0
            b2 = s_nxt * (nxt - x2) if nxt < width else 0
            cost = abs(a1 - a2) + abs(b1 - b2)
            if run_ends:
                cost += abs(l1 - (x2 - start)) + abs(r1 - (end - x2))
            best, d_lo, d_hi = _keep_least(best, d_lo, d_hi, cost, x - x2 if cam == 0 else x2 - x)
        prev, s_prev = end, _sign(stored[other, slot, y, end] * c)  # the next run's left end
        xx = nxt
        start = nxt
    return best, d_lo, d_hi


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


# error_model="numpy": the splat's division by the (positive) scale then has no zero check, whose exception
# path kept numba's reference counting of the frame arrays around every splat.
@njit(cache=True, error_model="numpy")
def _event_vector_kernel(stream, stored, scale, clock, bound, kernel, decay, period, thresholds, require, max_d,
                         max_cost, run_ends, cost_ratio, cost_slack, centre, out_cam, out_index, out_disparity,
                         values_l, values_r):
    """Process the merged stream (:func:`calibration_free.merge_order.merged_stream`); one output row per matched
    event; returns the count."""
    width = stored.shape[3]
    row = np.empty(width)
    vec_a = np.empty(width, dtype=np.int64)
    vec_b = np.empty(width, dtype=np.int64)
    vec_l = np.empty(width, dtype=np.int64)
    vec_r = np.empty(width, dtype=np.int64)
    n = 0
    for j in range(stream.shape[1]):
        cam, i, t, x, y, p, slot = stream[0, j], stream[1, j], stream[2, j], stream[3, j], stream[4, j], \
            stream[5, j], stream[6, j]
        other = 1 - cam
        # The test here, advance_due_bounded only when due: an inlined helper holding both bound the four arrays
        # to new variables and numba kept their atomic reference counting on every event (8 atomics, ~30 ns).
        for cc in (cam, other):
            if tick_due(clock[cc, 0], clock[cc, 1], t, period):
                advance_due_bounded(stored, scale, clock, bound, cc, t, decay, period)
        c1 = scale[cam]
        value = stored[cam, slot, y, x] * c1
        if cam == 0:
            values_l[i] = abs(value)
        else:
            values_r[i] = abs(value)
        if abs(value) >= thresholds[cam]:
            a1, b1, l1, r1 = _own_vector(stored, bound, cam, slot, y, x, c1, thresholds[cam])
            lo = x if cam == 1 else max(0, x - max_d)  # the candidate pixels lo..hi of the other row
            hi = min(width - 1, x + max_d) if cam == 1 else x
            c2 = scale[other]
            threshold = thresholds[other]  # the other camera's accumulations, by its own threshold
            # Scanning the other row from left to right, last = the last above-threshold pixel so far and
            # prev = the last one before the current run (s_* their signs), start = where the current run
            # began: what a scan from pixel 0 would hold on reaching lo, found by walking out of lo's run and
            # gap to the left.
            prev, s_prev, last, s_last, start = -1, 0, -1, 0, -1
            k = lo - 1
            if k >= 0 and _above(stored, other, slot, y, k, c2, threshold):
                last, s_last = k, _sign(stored[other, slot, y, k] * c2)
                k -= 1
                while k >= 0 and _above(stored, other, slot, y, k, c2, threshold):
                    k -= 1
                start = k + 1
                k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c2, threshold)
                if k >= 0:
                    prev, s_prev = k, _sign(stored[other, slot, y, k] * c2)
            else:  # k is below the threshold or -1: the skip starts beyond it
                k = skip_below(stored, bound, other, slot, y, max(k - 1, -1), -1, -1, c2, threshold)
                if k >= 0:
                    last, s_last = k, _sign(stored[other, slot, y, k] * c2)
            if require:
                best, d_lo, d_hi = _search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold,
                                                _sign(value), a1, b1, l1, r1, run_ends, last, s_last, prev,
                                                s_prev, start)
            else:
                best, d_lo, d_hi = _search_all(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold, a1, b1,
                                               l1, r1, run_ends, last, s_last, prev, s_prev, start, row, vec_a,
                                               vec_b, vec_l, vec_r)
            length = abs(a1) + abs(b1) + (l1 + r1 if run_ends else 0)
            limit = cost_slack + cost_ratio * length if cost_ratio > 0 else -1.0
            disparity = _choose(best, d_lo, d_hi, max_cost, limit, centre)
            n = emit_match(out_cam, out_index, out_disparity, n, cam, i, disparity)
        splat_bounded(stored, scale, clock, bound, cam, slot, x, y, 1.0 if p > 0 else -1.0, kernel)
    return n


class EventVectorMatcher(MergedEventMatcher):
    """Event-vector matcher (thesis Algorithm 4): each event's distances to the neighbouring accumulations of its
    row, compared with those of candidate pixels in the other camera's row.

    Streaming (``feed`` / ``flush``), for events of either camera; its reference is
    :func:`calibration_free.reference.event_vector.event_vector_reference`.

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

    def _run_kernel(self, stream, thresholds, out_cam, out_index, out_disparity, out_values) -> int:
        prm, bank = self.params, self._bank
        return int(_event_vector_kernel(stream, bank.stored, bank.scale, bank.clock, self._bound,
                                        bank.kernel, *bank.decay_args, thresholds,
                                        bool(prm.require_candidate_threshold), int(prm.max_disparity),
                                        float(prm.max_cost), bool(prm.run_ends), float(prm.cost_ratio),
                                        float(prm.cost_slack), prm.tie_break == "centre", out_cam, out_index,
                                        out_disparity, *out_values))
