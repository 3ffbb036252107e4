"""Event-time matcher (thesis 3.4, Algorithm 1): pair an event with a near-simultaneous event of the other
camera in the same row band whose dynamic-frame value is alike.

For each event e1 = (x, y, t, s) of the reference camera, before e1 updates its own dynamic frame D1:
skip unless ``|D1(x, y)| >= threshold``; candidates are the other camera's events e2 = (x2, y2, t2, s2) with
``|t2 - t| <= time_window_us``, ``|y2 - y| <= row_tolerance``, ``s2 = s``, ``sign(D2) = s``,
``|D2| >= threshold`` and ``|D1 - D2| <= value_tolerance``, where D2 is the other frame's value at (x2, y2)
just after e2's own update **[choice]**. The smallest ``|x2 - x|`` (at most ``max_disparity``) is the
disparity. With ``restrict_side`` (default) only the geometrically possible side counts (x2 >= x when the
reference is the right camera, x2 <= x when it is the left); without it Algorithm 1 is reproduced exactly,
reporting ``|x2 - x|`` whichever the side.

Candidates up to the time window after e1 are waited for: a match is emitted once the stream is complete
past ``t + window``, so the output lags the input by the window (300 us in the thesis set) and stays
time-ordered.

The reference implementation is :func:`cvstereo.matchers.event_time.reference.event_time_reference`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.matchers._shared.signal_level`): the threshold (0.8)
becomes
``threshold_scale`` times each camera's signal level (the 0.9 quantile of the |D| its events read, as the test
reads them: D1 before, D2 after the update, over the last second), and the value tolerance (0.3) becomes
``value_tolerance_scale`` times the reference camera's level: D grows with the events per edge, and so does the
difference of two Ds of one edge. The row tolerance is geometry and stays absolute, as do the decay and its
period. Two more fields, off in the thesis set and on in ``adaptive``, keep the test fair when an edge gives a
pixel only one or two events:

* ``reference_read="after"``: D1 is read just after e1's own update, as D2 is after e2's. Read before, D1 of
  a corresponding pair lacks one event's centre weight (0.41) that D2 holds, a bias as large as the values
  themselves on a sparse edge (NSTlogo: D1 before 0.13, D2 after 0.54 at the median; no pair agreed).
* ``time_window_scale``: the window is that many times the other camera's pace, the median time from an
  event back to the last earlier event of its polarity in its 3x3 neighbourhood (:func:`_neighbour_intervals`,
  estimated per level window like the signal level), and at least ``time_window_us``. Fewer events per edge
  lie further apart in time, in one camera and between the two: on the density sweep the median gap from an
  event to its true partner grew from 0.9 ms (thresholds x1) to 2.1 ms (x3), and the share of true
  partners within 300 us fell from 20 % to 6 %, while the pace grew alike (1.3 ms to 3.3 ms).

A third field, also off in the thesis set and on in ``adaptive``, keeps look-alike partners out:

* ``consensus_radius``: where the recent matches around the event (the last match of each pixel within the
  radius, at most ``consensus_window_us`` old) agree on a disparity more than 1 px from the smallest distance,
  the candidate nearest that consensus is taken, or none if no candidate lies within 1 px of it
  (:func:`_veto`). On an arm's repeating texture at 50 cm the nearest-x rule took a partner one texture period
  (4-5 px) off in 10-12 % of the matches, and for most of those the true partner was not a candidate at all. A
  full stream's (pixel, 40 ms) cells hold enough matches for their median to outvote these; a thinned stream's
  do not, so with every second event dropped only 88 % of the cells agreed with the full stream's. A veto, not
  a requirement: with no recent neighbour matches a match stands, so sparse and large sensors keep their
  coverage (a requirement of agreeing neighbours left 0.03 of the events matched at 346x260). The matches are
  resolved in time order, so each pixel's last match is that of the stream so far whatever the packets.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numba import njit

from cvstereo.frames.accumulate import polarity_sign
from cvstereo.frames.dynamic import FrameBank, dynamic_unit, event_matrix
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers.event_time.params import EventTimeParams
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import paired_window_segments
from cvstereo.model.matches import empty_matches
from cvstereo.model.polarity import POLARITY_MODES

__all__ = ["NO_TIME", "EventTimeMatcher"]

#: "No event yet" in the tables of event times: below any time stamp (time stamps may be negative).
NO_TIME = np.iinfo(np.int64).min


@njit(cache=True)
def _nearest(row_t, row_x, row_p, row_v, start, first, y0, y1, t_end, p, v, tol, x, side, max_d, seen, stamp):
    """The smallest candidate disparity (Algorithm 1's rule; -1: none) in rows y0 .. y1, each scanned from
    ``first[r]`` up to time ``t_end``; ``seen[d] = stamp`` marks every candidate disparity d on the way, so that
    the candidate nearest another disparity needs no second scan (:func:`_nearest_to`)."""
    best = -1
    for r in range(y0, y1 + 1):
        k = first[r]
        while k < start[r + 1] and row_t[k] <= t_end:
            if row_p[k] == p and abs(v - row_v[k]) <= tol:
                dx = row_x[k] - x
                if not ((side > 0 and dx < 0) or (side < 0 and dx > 0)):
                    d = abs(dx)
                    if d <= max_d:
                        seen[d] = stamp
                        if best < 0 or d < best:
                            best = d
            k += 1
    return best


@njit(cache=True)
def _nearest_to(seen, stamp, target):
    """The candidate disparity marked ``stamp`` in ``seen`` (:func:`_nearest`) within 1 px of ``target``, the
    nearest (ties: the smaller), or -1 if none."""
    if seen[target] == stamp:
        return target
    if target >= 1 and seen[target - 1] == stamp:
        return target - 1
    return target + 1 if seen[target + 1] == stamp else -1


@njit(cache=True)
def _veto(last, x, y, t, best, radius, window, min_agree, hist):
    """The consensus of the recent matches around (x, y) if it lies more than 1 px from ``best``, else -1.

    The last match of each pixel within ``radius`` (own pixel included; ``last[y, x]``: its time and disparity)
    counts if it is at most ``window`` us old; their lower median m is the consensus when at least ``min_agree``
    of them, and more than half, lie within 1 px of it (:func:`_consensus`, whose ``hist`` this is).
    """
    height, width = last.shape[0], last.shape[1]
    y0, y1, x0, x1 = max(0, y - radius), min(height, y + radius + 1), max(0, x - radius), min(width, x + radius + 1)
    since = t - window  # NO_TIME (no match yet) lies before any such time
    # First only count, in a branch-free pass: the lower median, the ((n - 1) // 2)-th of the n recent
    # disparities in ascending order, lies more than 1 px from best only if more than that many lie below
    # best - 1, or at most that many at or below best + 1. Else best stands, with no histogram (2 calls in 5 on
    # the motorcycle, 49 in 50 at 640x480).
    n = below = upto = 0
    for r in range(y0, y1):
        for c in range(x0, x1):
            recent = last[r, c, 0] >= since
            d = last[r, c, 1]
            n += recent
            below += recent & (d < best - 1)
            upto += recent & (d <= best + 1)
    k = (n - 1) // 2
    if n == 0 or n < min_agree or (below <= k < upto):
        return -1
    return _consensus(last, y0, y1, x0, x1, since, n, min_agree, hist)


@njit(cache=True)
def _consensus(last, y0, y1, x0, x1, since, n, min_agree, hist):
    """The lower median m of the ``n`` disparities of ``last[y0:y1, x0:x1]`` at least ``since`` recent if at
    least ``min_agree`` of them, and more than half, lie within 1 px of it, else -1.

    Disparities are small non-negative integers: a histogram over the range they span gives the median and the
    counts near it without a sort (a sort per call cost more than the rest of the matcher on a dense scene).
    ``hist`` (zeros, at least ``max_disparity`` + 3 entries) counts disparity d at ``hist[d + 1]`` and is left
    zeroed again.
    """
    lo, hi = hist.shape[0], -1
    for r in range(y0, y1):
        for c in range(x0, x1):
            recent = last[r, c, 0] >= since
            d = last[r, c, 1] + 1
            hist[d] += recent
            lo, hi = min(lo, d if recent else lo), max(hi, d if recent else hi)
    below, m = 0, lo
    while below + hist[m] <= (n - 1) // 2:
        below += hist[m]
        m += 1
    agree = hist[m - 1] + hist[m] + hist[m + 1]
    hist[lo:hi + 1] = 0
    return m - 1 if agree >= min_agree and 2 * agree > n else -1


@njit(cache=True)
def _resolve(pt, px, py, pp, pv, n, ct, cx, cy, cp, cv, height, window, row_tol, value_tol, side, max_d, last, radius,
             c_window, c_min, out):
    """Disparity of the first ``n`` pending reference events (-1: no candidate, or vetoed).

    Pending events (pt, px, py, pp, pv: time, x, y, p, D1; window and value_tol: each one's time window and
    maximum ``|D1 - D2|``) and candidates (ct, ... cv: the other camera's events that passed the threshold and
    sign tests, D2 just after their update) are both time-ordered. Candidates are bucketed by row (a stable
    counting sort keeps each row time-ordered), so each pending event scans only rows y - row_tol .. y + row_tol,
    from its own ``t - window`` on: a per-row pointer follows ``t - window``, forwards as the pending events'
    times grow and back only where a longer window begins (a paced window may be 300 us in one level window
    and 20 ms in the next). The winner, the smallest distance, does not depend on the scan order. ``side`` is +1
    (x2 >= x), -1 (x2 <= x) or 0 (either side).

    With ``radius`` > 0 (``consensus_radius``), a winner more than 1 px from the consensus of the recent matches
    around it (:func:`_veto`; ``last``: each pixel's last match, time and disparity, updated here in time
    order) gives way to the candidate nearest the consensus if that lies within 1 px of it, else the event
    is not matched.
    """
    nc = ct.shape[0]
    start = np.zeros(height + 1, dtype=np.int64)
    for j in range(nc):
        start[cy[j] + 1] += 1
    for r in range(height):
        start[r + 1] += start[r]
    fill = start[:height].copy()
    order = np.empty(nc, dtype=np.int64)
    for j in range(nc):
        order[fill[cy[j]]] = j
        fill[cy[j]] += 1
    # The candidates in row order, as the scans read them.
    row_t, row_x, row_p, row_v = ct[order], cx[order], cp[order], cv[order]
    first = start[:height].copy()  # per row: the first candidate at or after t - w of the last event that scanned it
    hist = np.zeros(max_d + 3, dtype=np.int64)
    seen = np.full(max_d + 2, -1, dtype=np.int64)  # stamped with the pending event's index i
    for i in range(n):
        t = pt[i]
        w = window[i]
        y0, y1 = max(0, py[i] - row_tol), min(height - 1, py[i] + row_tol)
        for r in range(y0, y1 + 1):
            # t - w only grows while the window stays (one level window): the first candidate moves forward,
            # and back only where a longer window begins.
            k = first[r]
            while k > start[r] and row_t[k - 1] >= t - w:
                k -= 1
            while k < start[r + 1] and row_t[k] < t - w:
                k += 1
            first[r] = k
        best = _nearest(row_t, row_x, row_p, row_v, start, first, y0, y1, t + w, pp[i], pv[i], value_tol[i], px[i],
                        side, max_d, seen, i)
        if best >= 0 and radius > 0:
            cons = _veto(last, px[i], py[i], t, best, radius, c_window, c_min, hist)
            if cons >= 0:
                # A look-alike where the neighbourhood agrees on another disparity: the candidate nearest it, if any.
                best = _nearest_to(seen, i, cons)
            if best >= 0:
                last[py[i], px[i], 0] = t
                last[py[i], px[i], 1] = best
        out[i] = best


@njit(cache=True)
def _neighbour_intervals(t, x, y, p, last, deferred, state, cap, out):
    """Time from each event back to the last earlier event of its polarity in its 3x3 neighbourhood.

    ``last[p, y + 1, x + 1]`` is the latest time of a ``p`` event at (x, y) before the current time ``td``
    (padded by one pixel, :data:`NO_TIME` for none): the events of one time stamp read the table before any of
    them writes it, so that an event sent twice at the same time finds the same earlier event both times and duplicates
    do not fake a fast pace. Their writes wait in ``deferred`` (flat indices into ``last``, the first
    ``state[0]`` in use, of time ``state[1]``) until a later time comes, in this call or the next: one
    table of times per polarity instead of two (the latest and the one before), half the memory that a 640x480
    sensor's neighbourhoods draw through the cache. ``deferred`` holds at least ``state[0] + t.size``
    entries. ``out[i]`` is NaN when there is no earlier event within ``cap`` us.
    """
    flat = last.reshape(-1)
    nd, td = state[0], state[1]
    for i in range(t.shape[0]):
        pol, yy, xx, ti = p[i], y[i] + 1, x[i] + 1, t[i]
        if ti != td:
            for k in range(nd):
                flat[deferred[k]] = td
            nd, td = 0, ti
        newest = NO_TIME
        for r in range(yy - 1, yy + 2):
            for c in range(xx - 1, xx + 2):
                newest = max(newest, last[pol, r, c])
        out[i] = ti - newest if newest != NO_TIME and ti - newest <= cap else np.nan
        deferred[nd] = (pol * last.shape[1] + yy) * last.shape[2] + xx
        nd += 1
    state[0], state[1] = nd, td


@njit(cache=True)
def _passing(value, p, threshold, signed):
    """Indices of the events whose ``|value| >= threshold`` (NaN, a dropped polarity, fails) and, if ``signed``,
    whose value has the event's sign (``2 p - 1``): the threshold and sign tests in one pass."""
    out = np.empty(value.size, dtype=np.int64)
    n = 0
    for i in range(value.size):
        v = value[i]
        if not abs(v) >= threshold:
            continue
        if signed and (v > 0) - (v < 0) != polarity_sign(p[i]):
            continue
        out[n] = i
        n += 1
    return out[:n]


class EventTimeMatcher(StreamMatcher):
    """Event-time matcher (thesis Algorithm 1), fast path; streaming, ``feed`` / ``flush``.

    Parameters
    ----------
    params : EventTimeParams, optional
    resolution : (width, height), keyword-only

    Examples
    --------
    >>> from cvstereo.model.events import make_events
    >>> m = EventTimeMatcher.from_variant("shared")
    >>> left = make_events([0, 100], [20, 20], [5, 5], [1, 1])
    >>> right = make_events([20, 60, 120], [17, 17, 17], [5, 5, 5], [1, 1, 1])
    >>> matches = np.concatenate([m.feed(left, right), m.flush()])
    >>> matches["disparity"].tolist()
    [3.0]
    """

    Params = EventTimeParams
    variants: ClassVar[dict[str, dict]] = {mode: {"polarity": mode} for mode in POLARITY_MODES}
    anchor = "event"
    method = "event-time"

    def __init__(self, params: EventTimeParams | None = None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._bank = FrameBank(2, self.params.frame_params(), resolution=self.resolution)
        # Plain columns rather than structured arrays: numpy is several times faster on them, and at 10 ms
        # packets the per-packet overhead is what limits the speed.
        # Reference events that passed the threshold and await their candidate window: rows t, x, y, p; D1;
        # the value tolerance in force for each.
        self._pending, self._pending_value = np.empty((4, 0), np.int64), np.empty(0)
        self._pending_tol, self._pending_window = np.empty(0), np.empty(0, np.int64)
        # Other-camera events that can be candidates (threshold and sign passed): rows t, x, y, p; D2.
        self._cands, self._cand_value = np.empty((4, 0), np.int64), np.empty(0)
        self._level = SignalLevel(self.params, absolute=self.params.threshold, unit=dynamic_unit(self.params),
                                  value_name="dynamic-frame value")
        # The pace of the other camera's events (time_window_scale), whose events are the candidates: the
        # reference camera's pace is never used, and its intervals cost as much as the other's.
        self._pace = SignalLevel(self.params.pace_params(), absolute=self.params.time_window_us, unit=1.0,
                                 value_name="interval")
        width, height = self.resolution
        # Per polarity, the latest time of the other camera's events at every pixel (padded by one pixel, NO_TIME
        # for none); the writes of its latest time stamp that _neighbour_intervals still holds back, and (their
        # number, their time).
        self._last = np.full((2, height + 2, width + 2), NO_TIME, np.int64) if self.params.paced else None
        self._deferred, self._deferred_state = np.empty(0, np.int64), np.array([0, NO_TIME], np.int64)
        # consensus_radius: per pixel of the reference camera, the time and disparity of its last match.
        # Side by side, as the neighbourhood reads them.
        self._last_match = np.zeros((height, width, 2) if self.params.consensus_radius > 0 else (1, 1, 2), np.int64)
        self._last_match[..., 0] = NO_TIME

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.reference_camera,)

    def _feed(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        prm = self.params
        ref = prm.reference_camera
        packets = (left, right)
        # Each camera's frame depends on its own events only: no merged order is needed here. The level
        # windows are taken in time order, both cameras' part of a window before the next window's thresholds.
        for k, *runs in paired_window_segments(left["t"], right["t"], prm.level_window_us):
            threshold = self._level.thresholds(k)
            tolerance = self._level.relative(k, absolute=prm.value_tolerance, scale=prm.value_tolerance_scale)[ref]
            window = self._window(k)
            # The levels are asked only where D2 is scaled: absolute mode estimates no signal level otherwise.
            gain = prm.value_gain(self._level.levels(k)) if prm.scales_values else 1.0
            for cam in (ref, 1 - ref):
                a, b = runs[cam]
                if b > a:
                    self._take(cam, packets[cam][a:b], k, threshold[cam], tolerance, window, gain)
        if self.watermark is None:
            return empty_matches()
        # Every later event has t >= watermark: a pending event is final once watermark > t + its window; the
        # matches leave in time order, up to the first pending event that is not final yet.
        final = self._pending[0] + self._pending_window < self.watermark
        n = final.size if final.all() else int(np.argmin(final))
        return self._resolve(n)

    def _window(self, k: int) -> int:
        """The time window in force for the reference events of level window ``k``: ``time_window_us``, or
        ``time_window_scale`` times the other camera's pace (whose events are the candidates)."""
        prm = self.params
        if not prm.paced:
            return int(prm.time_window_us)
        other = 1 - prm.reference_camera
        return int(self._pace.relative(k, absolute=prm.time_window_us, scale=prm.time_window_scale,
                                       floor=prm.time_window_us)[other])

    def _take(self, cam: int, events: np.ndarray, k: int, threshold: float, tolerance: float, window: int,
              gain: float) -> None:
        """Run one camera's events of level window ``k`` through its frame; keep the ones that pass (the other
        camera's D2 in the reference camera's units: ``gain``, :meth:`EventTimeParams.value_gain`)."""
        cols = event_matrix(events)
        if cam == self.params.reference_camera:
            v1 = self._bank.process_columns(cam, cols, read=self.params.reference_read)
            keep = _passing(v1, cols[3], float(threshold), False)
            self._pending = np.concatenate([self._pending, cols[:, keep]], axis=1)
            self._pending_value = np.concatenate([self._pending_value, v1[keep]])
            self._pending_tol = np.concatenate([self._pending_tol, np.full(keep.size, tolerance)])
            self._pending_window = np.concatenate([self._pending_window, np.full(keep.size, window, np.int64)])
            self._level.add(k, cam, v1)
        else:
            if self.params.paced:  # the pace of the other camera's events, whose window holds the candidates
                self._pace.add(k, cam, self._intervals(cols))
            v2 = self._bank.process_columns(cam, cols, read="after")
            keep = _passing(v2, cols[3], float(threshold), True)
            self._cands = np.concatenate([self._cands, cols[:, keep]], axis=1)
            self._cand_value = np.concatenate([self._cand_value, v2[keep] * gain])
            self._level.add(k, cam, v2)

    def _intervals(self, cols: np.ndarray) -> np.ndarray:
        """:func:`_neighbour_intervals` of the other camera's events (rows t, x, y, p), after its earlier ones."""
        held = int(self._deferred_state[0])
        if self._deferred.size < held + cols.shape[1]:
            grown = np.empty(max(2 * self._deferred.size, held + cols.shape[1]), np.int64)
            grown[:held] = self._deferred[:held]
            self._deferred = grown
        out = np.empty(cols.shape[1])
        _neighbour_intervals(cols[0], cols[1], cols[2], cols[3], self._last, self._deferred, self._deferred_state,
                             int(self.params.level_window_us), out)
        return out

    def _flush(self) -> np.ndarray:
        return self._resolve(self._pending.shape[1])

    def _resolve(self, n: int) -> np.ndarray:
        prm = self.params
        if n == 0:
            return empty_matches()
        ref = prm.reference_camera
        side = 0 if not prm.restrict_side else (1 if ref == 1 else -1)
        out = np.empty(n, dtype=np.int64)
        pend, cands = self._pending, self._cands
        max_window = prm.max_time_window_us()
        _resolve(pend[0], pend[1], pend[2], pend[3], self._pending_value, n, cands[0], cands[1], cands[2],
                 cands[3], self._cand_value, self.resolution[1], self._pending_window, int(prm.row_tolerance),
                 self._pending_tol, side, int(prm.max_disparity), self._last_match, int(prm.consensus_radius),
                 int(prm.consensus_window_us), int(prm.consensus_min), out)
        found = np.flatnonzero(out >= 0)
        matches = empty_matches(found.size)
        for row, name in enumerate(("t", "x", "y", "p")):
            matches[name] = pend[row, found]
        matches["camera"] = ref
        matches["disparity"] = out[found]
        self._pending, self._pending_value = pend[:, n:], self._pending_value[n:]
        self._pending_tol, self._pending_window = self._pending_tol[n:], self._pending_window[n:]
        # Candidates older than any future use: earlier than the next pending event (or the watermark)
        # minus the window.
        horizon = self.watermark if self.watermark is not None else 0
        if self._pending.shape[1]:
            horizon = min(horizon, int(self._pending[0, 0]))
        drop = int(np.searchsorted(cands[0], horizon - max_window, side="left"))
        self._cands, self._cand_value = cands[:, drop:], self._cand_value[drop:]
        return matches
