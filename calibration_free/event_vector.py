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

Both cameras' events are processed in one merged order (by time, left first at equal times), see
:mod:`calibration_free.merge_order` and :mod:`calibration_free._event_common`. The reference implementation is
:func:`calibration_free.reference.event_vector.event_vector_reference`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numba import njit

from calibration_free._event_common import MergedEventMatcher
from calibration_free.merge_order import left_is_next_jit
from calibration_free.params import EventVectorParams
from cvstereo.dynamic_frames import advance, splat


@njit(cache=True, inline="always")
def _sign(v):
    return 1 if v > 0 else (-1 if v < 0 else 0)


@njit(cache=True)
def _event_vector_kernel(tl, xl, yl, pl, tr, xr, yr, pr, stored, scale, clock, slot_of_p, kernel, decay, period,
                         threshold, require, max_d, max_cost, out_cam, out_index, out_disparity):
    """Process both cameras' events in merged order; one output row per matched event; returns the count."""
    width = stored.shape[3]
    row = np.empty(width)
    vec_a = np.empty(width, dtype=np.int64)
    vec_b = np.empty(width, dtype=np.int64)
    nl = tl.shape[0]
    nr = tr.shape[0]
    il = 0
    ir = 0
    n = 0
    while il < nl or ir < nr:
        if left_is_next_jit(il, nl, ir, nr, tl, tr):
            cam, i, t, x, y, p = 0, il, tl[il], xl[il], yl[il], pl[il]
            il += 1
        else:
            cam, i, t, x, y, p = 1, ir, tr[ir], xr[ir], yr[ir], pr[ir]
            ir += 1
        slot = slot_of_p[1 if p > 0 else 0]
        if slot < 0:
            continue
        other = 1 - cam
        advance(stored, scale, clock, cam, t, decay, period)
        advance(stored, scale, clock, other, t, decay, period)
        c1 = scale[cam]
        value = stored[cam, slot, y, x] * c1
        if abs(value) >= threshold:
            # Own vector: walk out of x's run, then on to the next above-threshold pixel, on each side.
            k = x
            while k >= 0 and abs(stored[cam, slot, y, k] * c1) >= threshold:
                k -= 1
            while k >= 0 and abs(stored[cam, slot, y, k] * c1) < threshold:
                k -= 1
            a1 = _sign(stored[cam, slot, y, k] * c1) * (x - k) if k >= 0 else 0
            k = x
            while k < width and abs(stored[cam, slot, y, k] * c1) >= threshold:
                k += 1
            while k < width and abs(stored[cam, slot, y, k] * c1) < threshold:
                k += 1
            b1 = _sign(stored[cam, slot, y, k] * c1) * (k - x) if k < width else 0
            # The other row's vectors at the candidate pixels lo..hi in two passes (the same numbers as walking
            # from each): left to right up to hi, right to left down to lo.
            step = 1 if cam == 1 else -1  # right-camera events look towards larger x, left towards smaller
            lo = x if cam == 1 else max(0, x - max_d)
            hi = min(width - 1, x + max_d) if cam == 1 else x
            c2 = scale[other]
            for xx in range(width):
                row[xx] = stored[other, slot, y, xx] * c2
            prev = -1  # last above-threshold pixel before the current run
            last = -1  # last above-threshold pixel so far
            for xx in range(hi + 1):
                if abs(row[xx]) >= threshold:
                    if xx == 0 or abs(row[xx - 1]) < threshold:
                        prev = last
                    vec_a[xx] = _sign(row[prev]) * (xx - prev) if prev >= 0 else 0
                    last = xx
                else:
                    vec_a[xx] = _sign(row[last]) * (xx - last) if last >= 0 else 0
            prev = width
            last = width
            for xx in range(width - 1, lo - 1, -1):
                if abs(row[xx]) >= threshold:
                    if xx == width - 1 or abs(row[xx + 1]) < threshold:
                        prev = last
                    vec_b[xx] = _sign(row[prev]) * (prev - xx) if prev < width else 0
                    last = xx
                else:
                    vec_b[xx] = _sign(row[last]) * (last - xx) if last < width else 0
            s1 = _sign(value)
            best = -1
            best_cost = max_cost
            for d in range(max_d + 1):
                x2 = x + step * d
                if x2 < 0 or x2 >= width:
                    break
                if require and not (abs(row[x2]) >= threshold and _sign(row[x2]) == s1):
                    continue
                cost = abs(a1 - vec_a[x2]) + abs(b1 - vec_b[x2])
                if cost < best_cost:
                    best_cost = cost
                    best = d
            if best >= 0:
                out_cam[n] = cam
                out_index[n] = i
                out_disparity[n] = best
                n += 1
        splat(stored, scale, clock, cam, slot, x, y, 1.0 if p > 0 else -1.0, kernel)
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

    def _run_kernel(self, columns, out_cam, out_index, out_disparity) -> int:
        prm, bank = self.params, self._bank
        return int(_event_vector_kernel(*columns, bank.stored, bank.scale, bank.clock, bank.slot_of_p, bank.kernel,
                                        *bank.decay_args, float(prm.threshold),
                                        bool(prm.require_candidate_threshold), int(prm.max_disparity),
                                        float(prm.max_cost), out_cam, out_index, out_disparity))
