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

from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit, prange

from cvstereo.frames.accumulate import polarity_sign
from cvstereo.frames.dynamic import NEXT_TICK, TOUCHED, tick_due
from cvstereo.matchers._shared.event_common import MergedEventMatcher
from cvstereo.matchers._shared.frame_bounds import BoundedFrames, advance_due_bounded, block_bounds, splat_bounded
from cvstereo.matchers._shared.merge_order import stream_event
from cvstereo.matchers._shared.row_bands import BandedState, band_rows, compile_twice, emit_at, splat_rows
from cvstereo.matchers.event_vector.params import EventVectorParams
from cvstereo.matchers.event_vector.rows import choose, left_of, own_vector, search_all, search_runs, sign_of

__all__ = ["EventVectorMatcher"]


class VectorSearch(NamedTuple):
    """The event-vector kernel's parameters for one level window (:meth:`EventVectorMatcher._search`)."""

    kernel: np.ndarray  #: the update kernel (:func:`cvstereo.frames.dynamic.update_kernel`)
    decay: float
    period: int
    thresholds: np.ndarray  #: (2,) each camera's threshold in force
    require: bool  #: ``require_candidate_threshold``
    max_d: int
    max_cost: float
    run_ends: bool
    cost_ratio: float
    cost_slack: float
    centre: bool  #: ``tie_break="centre"``


# error_model="numpy": no zero check of the splat's division by the (positive) scale, whose exception path kept
# numba's reference counting of the frame arrays around every splat.
@njit(cache=True, error_model="numpy")
def _event_vector_band(stream, bands, cuts, band, search, out_pos, out_disparity, values, right_start):
    """Process the merged stream (:func:`cvstereo.matchers._shared.merge_order.merged_stream`) in row band ``band``
    of the cut ``cuts`` (:mod:`cvstereo.matchers._shared.row_bands`); one output row per matched event of the band;
    returns the count. ``bands``: each band's frames and block bounds
    (:class:`cvstereo.matchers._shared.frame_bounds.BoundedFrames`, a leading axis of bands). ``values``,
    ``right_start``: as for the event-area kernel."""
    stored, scale, clock, bound = bands.stored[band], bands.scale[band], bands.clock[band], bands.bound[band]
    kernel, decay, period, thresholds, require, max_d, max_cost, run_ends, cost_ratio, cost_slack, centre = search
    # The band's own rows (the events it searches) and the rows it keeps exact: an event reads its own row only.
    first_row, end_row, keep_lo, keep_hi = band_rows(cuts, band, stored.shape[2], 0)
    r = kernel.shape[0] // 2
    width = stored.shape[3]
    row = np.empty(width)
    vec_a, vec_b = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    vec_l, vec_r = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    above = np.empty(max_d // 64 + 2, dtype=np.uint64)  # masks of a candidate range (search_runs)
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
        if y + r < keep_lo or y - r >= keep_hi:
            # Another band's event whose splat misses the rows this band keeps: what the splat would do here
            # (splat_bounded with no rows), the frames marked touched, and no more.
            clock[cam, TOUCHED] = 1
            continue
        c1 = scale[cam]
        own_event = first_row <= y < end_row  # the band's own event: its value and its search
        # Another band's event is not read: its pixel lies on rows this band does not keep (a cache miss each).
        value = stored[cam, slot, y, x] * c1 if own_event else 0.0
        if own_event:
            values[cam * right_start + i] = abs(value)
        if own_event and abs(value) >= thresholds[cam]:
            a1, b1, l1, r1 = own_vector(stored, bound, cam, slot, y, x, c1, thresholds[cam])
            lo = x if cam == 1 else max(0, x - max_d)  # the candidate pixels lo..hi of the other row
            hi = min(width - 1, x + max_d) if cam == 1 else x
            c2 = scale[other]
            threshold = thresholds[other]  # the other camera's accumulations, by its own threshold
            if require:
                best, d_lo, d_hi = search_runs(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold,
                                                sign_of(value), a1, b1, l1, r1, run_ends, above, cand)
            else:
                last, s_last, prev, s_prev, start = left_of(stored, bound, other, slot, y, lo, c2, threshold)
                best, d_lo, d_hi = search_all(stored, bound, other, slot, y, x, cam, lo, hi, c2, threshold, a1, b1,
                                               l1, r1, run_ends, last, s_last, prev, s_prev, start, row, vec_a,
                                               vec_b, vec_l, vec_r)
            length = abs(a1) + abs(b1) + (l1 + r1 if run_ends else 0)
            limit = cost_slack + cost_ratio * length if cost_ratio > 0 else -1.0
            disparity = choose(best, d_lo, d_hi, max_cost, limit, centre)
            n = emit_at(out_pos, out_disparity, n, j, disparity)
        splat_bounded(stored, scale, clock, bound, cam, slot, x, y, polarity_sign(p), kernel,
                      splat_rows(y, r, keep_lo, keep_hi))
    return n


def _event_vector_bands(stream, bands, cuts, search, out_pos, out_disparity, counts, values, right_start):
    """:func:`_event_vector_band` for every band (``counts``: one per band, set to its count of matches;
    ``values``: one buffer per band), in parallel in the parallel compile."""
    for band in prange(counts.shape[0]):
        counts[band] = _event_vector_band(stream, bands, cuts, band, search, out_pos[band], out_disparity[band],
                                          values[band], right_start)


#: :func:`_event_vector_bands`, serial (one thread) and parallel (several).
_EVENT_VECTOR_KERNELS = compile_twice(_event_vector_bands)


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

    kernels = _EVENT_VECTOR_KERNELS

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._bound = block_bounds(self._bank.stored)  # kept by the kernel (frame_bounds.splat_bounded)
        self._bands = BandedState(BoundedFrames(self._bank.stored, self._bank.scale, self._bank.clock, self._bound),
                                  row_fields=("stored", "bound"), halo=0)

    def _search(self, thresholds, gains) -> VectorSearch:
        prm, bank = self.params, self._bank
        return VectorSearch(bank.kernel, *bank.decay_args, thresholds, bool(prm.require_candidate_threshold),
                            int(prm.max_disparity), float(prm.max_cost), bool(prm.run_ends), float(prm.cost_ratio),
                            float(prm.cost_slack), prm.tie_break == "centre")
