"""Event-area matcher (thesis 3.5.2, Algorithm 3): block matching (SAD) on the dynamic frames, per event.

For each event of either camera whose own dynamic frame has ``|D(x, y)| >= threshold`` before the event
updates it: the ``block`` x ``block`` patch around (x, y) in its own frame is compared by the sum of absolute
differences with the patches along the same row of the other camera's frame (as it stands at the event's
time), over disparities 0 .. ``max_disparity`` on the geometrically possible side: an event of the right
camera searches towards larger x in the left frame, an event of the left camera towards smaller x. The least
SAD wins (strict ``<``, scanning disparities upwards: ties go to the smaller disparity); a SAD must be below
``max_cost`` (Algorithm 3's initial minimum, 1000) to count. Patches that would leave the sensor are not used:
events within ``block // 2`` of the border are not matched, and candidates whose patch leaves the sensor end
the search **[choice, as for frame-area]**. Variant ``no-gaussian``: single-pixel frame updates (eq. 4.1)
with the threshold raised to 4.

Search **[implementation, same result]**: the SAD of the patches' column sums bounds every candidate's SAD from
below (triangle inequality; 5 terms instead of 25, computed for all candidates at once); the exact SAD is
computed where that bound is least, then only for candidates whose bound does not exceed the best SAD so far
(times ``1 + uniqueness``; with a margin beyond float rounding; none at all when the least bound of the others
already does, as for most events), so that the winner, its tie rule and the uniqueness check are the full
search's. The other camera's column sums are not summed per event but kept with
every splat (:func:`cvstereo.matchers._shared.frame_bounds.splat_summed`: one row of sums read instead of ``block``
rows of
the frame); they drift from the frames' by float rounding, which the margin covers ten times over
(:func:`cvstereo.matchers._shared.frame_bounds.sum_drift`).

Both cameras' events are processed in one merged order (by time, left first at equal times), see
:mod:`cvstereo.matchers._shared.merge_order` and :mod:`cvstereo.matchers._shared.event_common`. The reference
implementation is
:func:`cvstereo.matchers.event_area.reference.event_area_reference`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.matchers._shared.signal_level`): the event threshold
(1.2;
4 for single-pixel updates) becomes ``threshold_scale`` times the signal level of the event's camera (the 0.9
quantile of the |D| its events read at their pixels over the last second), since D grows with the events per
edge. The SAD needs no threshold: candidates are compared with each other (least SAD wins), and ``max_cost``
(1000) is Algorithm 3's "no match yet" start value, which no 5x5 SAD reaches; with ``cost_scale`` > 0 (not the
thesis') the SAD must also stay below ``cost_scale * block**2`` (per frame compared) times the threshold in
force, a bound relative to the signal level like the threshold itself; block and disparity range are geometry;
decay and its period are time.

Checks the thesis does not make (each off at its default; :mod:`cvstereo.matchers.sets` turns them on under
``adaptive``):

* ``sad_frames="all"`` with ``polarity="separate"``: the SAD sums over the OFF and the ON frame. In one shared
  frame ON and OFF events cancel where both fall in a patch (a fan's blades); the event's own polarity frame
  alone leaves a bar's leading edge ambiguous against the next bar's, which the trailing edge of the other
  polarity tells apart.
* ``own_ratio`` > 0: the SAD must also stay below ``own_ratio`` times the sum of |D| over the own patch (over
  the frames compared), which is the SAD of an empty candidate: a match must explain part of the patch, not
  only be the least bad, whatever the signal level.
* ``uniqueness`` > 0: a match is dropped when a candidate more than 1 px away has a SAD within the factor
  ``1 + uniqueness`` of the best (ambiguous: a repeating texture, or too little content to tell), as OpenCV's
  StereoBM ``uniquenessRatio``. The search then also computes the exact SAD of every candidate whose bound
  lies within that factor of the best.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit, prange

from cvstereo.frames.accumulate import polarity_sign
from cvstereo.frames.dynamic import NEXT_TICK, TOUCHED, tick_due
from cvstereo.matchers._shared.event_common import MergedEventMatcher
from cvstereo.matchers._shared.frame_bounds import (
    SUM_REBUILD,
    SummedFrames,
    advance_due_summed,
    column_sums,
    splat_summed,
    sum_drift,
)
from cvstereo.matchers._shared.merge_order import stream_event
from cvstereo.matchers._shared.row_bands import BandedState, band_rows, compile_twice, emit_at, splat_rows
from cvstereo.matchers._shared.uniqueness import ambiguous
from cvstereo.matchers.event_area.params import EventAreaParams

__all__ = ["EventAreaMatcher"]


class AreaSearch(NamedTuple):
    """The event-area kernel's parameters for one level window (:meth:`EventAreaMatcher._run_kernel`)."""

    kernel: np.ndarray  #: the update kernel (:func:`cvstereo.frames.dynamic.update_kernel`)
    decay: float
    period: int
    thresholds: np.ndarray  #: (2,) each camera's event threshold in force
    half: int  #: block // 2
    max_d: int
    max_cost: np.ndarray  #: (2,) the SAD each camera's match must stay below
    all_frames: bool  #: the SAD sums over all of a camera's frames (``sad_frames="all"``), else the event's own
    own_ratio: float
    uniqueness: float
    #: (2, frames) the factor on the other camera's values of each frame in the SAD of each camera's events
    #: (``value_units``; :class:`cvstereo.matchers._shared.frame_gains.FrameGains`)
    other_gains: np.ndarray
    #: the bound of the column sums' drift per unit of mass of all the entries one lower bound sums
    #: (:func:`cvstereo.matchers._shared.frame_bounds.sum_drift`)
    drift: float


@njit(cache=True)
def _event_area_band(stream, bands, cuts, band, search, out_pos, out_disparity, values, right_start):
    """Process the merged stream (:func:`cvstereo.matchers._shared.merge_order.merged_stream`) in row band ``band``
    of the cut ``cuts`` (:mod:`cvstereo.matchers._shared.row_bands`); one output row per matched event of the band
    (:func:`~cvstereo.matchers._shared.row_bands.emit_at`); returns the count. ``bands``: each band's frames and
    their column sums of ``block`` rows (:class:`cvstereo.matchers._shared.frame_bounds.SummedFrames`, a leading
    axis of bands). ``values``, ``right_start``: each event's |D| before its update, the right camera's from
    ``right_start`` on (:meth:`cvstereo.matchers._shared.event_common.MergedEventMatcher._run_kernel`)."""
    # Once per call: the loop below indexes the arrays themselves.
    stored, scale, clock = bands.stored[band], bands.scale[band], bands.clock[band]
    sums, mass, pending = bands.sums[band], bands.mass[band], bands.pending[band]
    (kernel, decay, period, thresholds, half, max_d, max_cost, all_frames, own_ratio, uniqueness, other_gains,
     drift) = search
    n_frames = stored.shape[1]
    height = stored.shape[2]
    width = stored.shape[3]
    # The band's own rows (the events it searches) and the rows it keeps exact: a patch reads ``half`` rows
    # beyond its own.
    first_row, end_row, keep_lo, keep_hi = band_rows(cuts, band, height, half)
    r = kernel.shape[0] // 2
    size = 2 * half + 1
    n_planes = n_frames if all_frames else 1
    own = np.empty((n_planes, size, size))
    n_d = min(max_d, width) + 1  # at most this many candidates stay on the sensor
    own_col = np.empty((n_planes, size))
    bound = np.empty(n_d + 1)  # and a scratch entry, where the least bound of the rest is turned into a float
    # The bounds' bit patterns: non-negative float64 values order as their int64 bits, and an integer minimum
    # vectorises where a float one does not (without fast-math).
    bits = bound.view(np.int64)
    inf_bits = np.int64(0x7FF0000000000000)  # +inf
    done_d = np.empty(n_d, np.int64)  # the candidates whose exact SAD was computed in full, and their SADs
    done_sad = np.empty(n_d)
    rival = 1.0 + uniqueness  # a candidate within this factor of the best SAD, > 1 px away, makes it ambiguous
    n = 0
    for j in range(stream.shape[1]):
        cam, i, t, x, y, p, slot = stream_event(stream, j)
        other = 1 - cam
        # The test here, the call below only about once per decay tick: an inlined helper holding both kept
        # atomic reference counting of the six state arrays around every event (12 calls).
        for c in (cam, other):
            if tick_due(clock[c, NEXT_TICK], clock[c, TOUCHED], t, period) or pending[c] >= SUM_REBUILD:
                advance_due_summed(stored, scale, clock, sums, mass, pending, c, t, decay, period, half)
        if y + r < keep_lo or y - r >= keep_hi:
            # Another band's event whose splat misses the rows this band keeps: what the splat would do here
            # (splat_summed with no rows), the count towards the rebuild and the frames marked touched, and no more.
            pending[cam] += 1
            clock[cam, TOUCHED] = 1
            continue
        c1 = scale[cam]
        c2 = scale[other]
        own_event = first_row <= y < end_row  # the band's own event: its value and its search
        # Another band's event is not read: its pixel lies on rows this band does not keep (a cache miss each).
        value = stored[cam, slot, y, x] * c1 if own_event else 0.0
        if own_event:
            values[cam * right_start + i] = abs(value)
        if (own_event and abs(value) >= thresholds[cam] and half <= x < width - half
                and half <= y < height - half):
            # The frames compared: the event's own (plane 0 is frame ``slot``), or all of them in slot order.
            first_slot = 0 if all_frames else slot
            # The candidates d = 0 .. last are those whose patch stays on the sensor (the search ends at the
            # first one that leaves it): towards larger x for right-camera events, smaller x for left-camera
            # ones. Only the columns they cover are read, from ``base`` on, in memory order (contiguous reads
            # that vectorise, where the mirrored order of left-camera events did not): candidate e's patch starts
            # at column e of the band, e = d for right-camera events, e = last - d for left-camera ones.
            if cam == 1:
                last = min(max_d, width - 1 - half - x)
                base = x - half
            else:
                last = min(max_d, x - half)
                base = x - last - half
            # Values are products stored * scale, computed once per pixel: the same numbers as the reference.
            own_abs = 0.0
            for q in range(n_planes):
                s = first_slot + q
                for ii in range(size):
                    own_col[q, ii] = 0.0
                for jj in range(size):
                    for ii in range(size):
                        v = stored[cam, s, y - half + jj, x - half + ii] * c1
                        own[q, jj, ii] = v
                        own_col[q, ii] += v
                        own_abs += abs(v)
            # A lower bound of every candidate's SAD: the SAD of the patches' column sums (triangle
            # inequality), 5 terms per frame instead of 25, for all candidates at once (the loop over e
            # vectorises). The other frames' column sums are the kept ones (one row read instead of ``block``
            # rows of the frame), read in place in their stored units (unsigned indices: numba wraps negative
            # signed ones around, which made LLVM gather the row): the own column sums are divided by the
            # other camera's scale instead, and so is the cut below, which changes the bound's rounding only
            # (~1e-16 relative, far inside the cut's margin). With two frames (a camera has at most two) both
            # terms go in one pass over the bounds per column, half the passes. With ``value_units`` the other
            # camera's values of each frame are multiplied by that frame's gain: its term is in the stored units
            # of its own gain, and the cut is in those of the least gain, which only loosens the bound.
            g0 = other_gains[cam, first_slot]
            g1 = other_gains[cam, first_slot + n_planes - 1]
            for q in range(n_planes):
                inv_q = 1.0 / (c2 * (g0 if q == 0 else g1))
                for ii in range(size):
                    own_col[q, ii] *= inv_q
            inv2 = 1.0 / (c2 * min(g0, g1))
            ubase = np.uint64(base)
            row0 = sums[other, first_slot, y]
            row1 = sums[other, first_slot + n_planes - 1, y]
            for e in range(last + 1):
                bound[e] = 0.0
            for ii in range(size):
                o = own_col[0, ii]
                uii = ubase + np.uint64(ii)
                if n_planes == 1:
                    for e in range(np.uint64(last + 1)):
                        bound[e] += abs(o - row0[uii + e])
                else:
                    o1 = own_col[1, ii]
                    for e in range(np.uint64(last + 1)):
                        bound[e] += abs(o - row0[uii + e]) + abs(o1 - row1[uii + e])
            # The exact SAD first where the bound is least (likely the winner, so that the bound then rules
            # out most others), then of every candidate whose bound does not exceed the best SAD so far (at
            # first the SAD a match must stay below, so that often no exact SAD is needed at all) by more than
            # the column sums' drift (ten times its bound) and the rounding of both sums could explain (a
            # relative 1e-9 of the own patch's magnitude and of the SAD, ~10^6 times the worst case): a
            # candidate skipped has a SAD above the best one, so the winner (least SAD, ties to the smaller
            # disparity, below max_cost) and the uniqueness check are the full search's, whatever the order in
            # which the candidates are visited.
            least = bits[0]
            for e in range(1, last + 1):
                least = min(least, bits[e])
            first = 0
            while bits[first] != least:
                first += 1
            # The least bound of the other candidates: when it exceeds the cut after the first exact SAD (most
            # events), no other candidate needs a look.
            second = inf_bits
            for e in range(first):
                second = min(second, bits[e])
            for e in range(first + 1, last + 1):
                second = min(second, bits[e])
            bits[n_d] = second
            rest = bound[n_d]
            best = -1
            best_sad = max_cost[cam]
            if own_ratio > 0:  # the SAD of an empty candidate patch is own_abs: a match must explain more
                best_sad = min(best_sad, own_ratio * own_abs)
            limit = best_sad * rival
            slack = 10.0 * drift * mass[other] * c2 * max(g0, g1) + 1e-9 * own_abs + 1e-300
            cut = (limit + 1e-9 * limit + slack) * inv2  # a bound above this rules the candidate out (stored units)
            n_done = 0
            e = first if bound[first] <= cut else -1  # else no candidate can match
            k = -1  # the candidates up to k have been visited (or ruled out), besides the first
            while e >= 0:
                d = e if cam == 1 else last - e
                x2 = base + half + e  # the candidate's centre, x + d or x - d
                sad = 0.0
                # Plane by plane, row by row, as the reference sums; a partial sum above the best ends the
                # candidate: partial sums never decrease, it can neither win nor tie.
                for q in range(n_planes):
                    s = first_slot + q
                    g = g0 if q == 0 else g1
                    for jj in range(size):
                        for ii in range(size):
                            sad += abs(own[q, jj, ii] - stored[other, s, y - half + jj, x2 - half + ii] * c2 * g)
                        if sad > limit:
                            break
                    if sad > limit:
                        break
                if sad <= limit:  # a possible rival: kept for the uniqueness check
                    done_d[n_done] = d
                    done_sad[n_done] = sad
                    n_done += 1
                if sad < best_sad or (sad == best_sad and d < best):  # ties keep the smaller disparity
                    best_sad = sad
                    best = d
                    limit = best_sad * rival
                    cut = (limit + 1e-9 * limit + slack) * inv2
                # The next candidate whose bound lies within the cut (a tight loop of its own: in the loop over
                # all candidates the compiler kept its counter in memory).
                k += 1
                if k == 0 and rest > cut:
                    break
                while k <= last and (bound[k] > cut or k == first):
                    k += 1
                e = k if k <= last else -1
            if uniqueness > 0 and best >= 0 and ambiguous(done_d, done_sad, n_done, best, best_sad, rival):
                best = -1
            n = emit_at(out_pos, out_disparity, n, j, best)
        splat_summed(stored, scale, clock, sums, mass, pending, half, cam, slot, x, y, polarity_sign(p), kernel,
                     splat_rows(y, r, keep_lo, keep_hi))
    return n


def _event_area_bands(stream, bands, cuts, search, out_pos, out_disparity, counts, values, right_start):
    """:func:`_event_area_band` for every band (``counts``: one per band, set to its count of matches;
    ``values``: one buffer per band), in parallel in the parallel compile."""
    for band in prange(counts.shape[0]):
        counts[band] = _event_area_band(stream, bands, cuts, band, search, out_pos[band], out_disparity[band],
                                        values[band], right_start)


#: :func:`_event_area_bands`, serial (one thread) and parallel (several).
_EVENT_AREA_KERNELS = compile_twice(_event_area_bands)


class EventAreaMatcher(MergedEventMatcher):
    """Event-area matcher (thesis Algorithm 3): the SAD of dynamic-frame patches, for each event of either camera.

    Streaming (``feed`` / ``flush``); its reference is
    :func:`cvstereo.matchers.event_area.reference.event_area_reference`.

    Parameters
    ----------
    params : EventAreaParams, optional
        Default: the thesis' (variant ``gaussian``).
    resolution : (width, height), keyword-only
    """

    Params = EventAreaParams
    variants: ClassVar[dict[str, dict]] = {
        "gaussian": {"gaussian": True, "threshold": 1.2},
        "no-gaussian": {"gaussian": False, "threshold": 4.0},
    }
    anchor = "event"
    method = "event-area"

    kernels = _EVENT_AREA_KERNELS

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        # The column sums of ``block`` rows of the frames, kept by the kernel for its lower bound of the SAD; a
        # patch reads ``block // 2`` rows beyond the event's.
        self._bands = BandedState(SummedFrames(self._bank.stored, self._bank.scale, self._bank.clock,
                                               *column_sums(self._bank.stored)),
                                  row_fields=("stored", "sums"), summed_fields=("mass",),
                                  halo=self.params.block // 2)

    def _value_units(self) -> str:
        return self.params.value_units

    def _search(self, thresholds, gains) -> AreaSearch:
        prm, bank = self.params, self._bank
        drift = sum_drift(1.0, prm.block) * prm.block * prm.compared_frames  # all entries of one lower bound
        return AreaSearch(bank.kernel, *bank.decay_args, thresholds, prm.block // 2, int(prm.max_disparity),
                          prm.max_costs(thresholds), prm.sad_frames == "all", float(prm.own_ratio),
                          float(prm.uniqueness), gains, drift)
