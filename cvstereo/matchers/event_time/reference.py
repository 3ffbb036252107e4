"""Reference event-time matcher (docs/algorithms.md section 2, thesis Algorithm 1)."""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.reference import sign
from cvstereo.matchers._shared.reference_border import border_rule_of
from cvstereo.matchers._shared.reference_frames import DynamicFrames, dynamic_unit
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers.event_time.params import EventTimeParams
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.matches import empty_matches, make_matches

__all__ = ["event_time_reference"]


def _neighbour_intervals(events: np.ndarray, cap: int) -> list[float]:
    """Per event, the time back to the last earlier event (strictly earlier) of its polarity in its 3x3
    neighbourhood; NaN when there is none within ``cap`` us."""
    times: dict[tuple[int, int, int], list[int]] = {}  # (p, x, y) -> distinct event times so far
    out = []
    for e in events:
        t, x, y, p = int(e["t"]), int(e["x"]), int(e["y"]), int(e["p"])
        # Times only grow: the latest earlier time of a pixel is one of its last two distinct times.
        earlier = [u for dx in (-1, 0, 1) for dy in (-1, 0, 1) for u in times.get((p, x + dx, y + dy), [])[-2:]
                   if u < t]
        out.append(t - max(earlier) if earlier and t - max(earlier) <= cap else np.nan)
        seen = times.setdefault((p, x, y), [])
        if not seen or seen[-1] != t:
            seen.append(t)
    return out


def _consensus(last: dict, x: int, y: int, t: int, prm: EventTimeParams) -> int | None:
    """The disparity the recent matches around (x, y) agree on (None: no consensus).

    ``last`` maps a pixel (x, y) to the time and disparity of its last match. The pixels within
    ``consensus_radius`` (own pixel included) whose last match is at most ``consensus_window_us`` old count;
    their lower median m is the consensus if at least ``consensus_min`` of them, and more than half, lie within
    1 px of m.
    """
    r = prm.consensus_radius
    around = (last.get((x + dx, y + dy)) for dx in range(-r, r + 1) for dy in range(-r, r + 1))
    recent = sorted(d for tt, d in filter(None, around) if t - tt <= prm.consensus_window_us)
    if not recent:
        return None
    m = recent[(len(recent) - 1) // 2]
    agree = sum(abs(d - m) <= 1 for d in recent)
    return m if agree >= prm.consensus_min and 2 * agree > len(recent) else None


def _choose(disparities: list[int], consensus: int | None) -> int | None:
    """Algorithm 1's smallest distance; where it lies more than 1 px from the neighbourhood's consensus, the
    candidate nearest the consensus (the smaller on a tie) if within 1 px of it, else None."""
    best = min(disparities)
    if consensus is None or abs(best - consensus) <= 1:
        return best
    near = min(disparities, key=lambda d: (abs(d - consensus), d))
    return near if abs(near - consensus) <= 1 else None


def _in_force_by_window(prm: EventTimeParams, events, values) -> tuple[dict, dict, dict]:
    """Window -> thresholds (per camera), value tolerance, time window and D2's gain (``value_units``) in force,
    from the windows before.

    ``events`` and ``values`` are the reference camera's first, the other's second (D1, D2 after).
    """
    w = prm.level_window_us
    ref = prm.reference_camera
    level = SignalLevel(prm, absolute=prm.threshold, unit=dynamic_unit(prm))
    pace = SignalLevel(prm.pace_params(), absolute=prm.time_window_us, unit=1.0)
    # Only the other camera's pace is used: the reference camera's events give no intervals.
    intervals = ([np.nan] * events[0].size,
                 _neighbour_intervals(events[1], w) if prm.paced else [np.nan] * events[1].size)
    windows = sorted({int(t) // w for ev in events for t in ev["t"]})
    threshold, tolerance, window, gain = {}, {}, {}, {}
    for k in windows:
        threshold[k] = level.thresholds(k)
        gain[k] = prm.value_gain(level.levels(k)) if prm.scales_values else 1.0
        tolerance[k] = level.relative(k, absolute=prm.value_tolerance, scale=prm.value_tolerance_scale)[ref]
        # The other camera's pace: its events are the candidates.
        window[k] = int(pace.relative(k, absolute=prm.time_window_us, scale=prm.time_window_scale,
                                      floor=prm.time_window_us)[1 - ref]) if prm.paced else int(prm.time_window_us)
        for cam, ev, vals, ivl in ((ref, events[0], values[0], intervals[0]),
                                   (1 - ref, events[1], values[1], intervals[1])):
            in_k = [int(t) // w == k for t in ev["t"]]
            level.add(k, cam, np.array([np.nan if v is None else v for v, here in zip(vals, in_k, strict=True)
                                        if here]))
            pace.add(k, cam, np.array([v for v, here in zip(ivl, in_k, strict=True) if here]))
    return threshold, tolerance, window, gain


def event_time_reference(left: np.ndarray, right: np.ndarray, params: EventTimeParams | None = None, *,
                         resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the event-time algorithm, one event at a time.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        One row per matched reference event, time-ordered.

    See Also
    --------
    cvstereo.matchers._shared.reference : the arguments, the same for every reference function.
    """
    prm = params if params is not None else EventTimeParams()
    ref = prm.reference_camera
    events = (left, right)
    ev1, ev2 = events[ref], events[1 - ref]
    fp = prm.frame_params()
    # D1 is read before e1 updates its frame (or just after, reference_read); D2 as the frame stood just after
    # e2's own update.
    d1 = DynamicFrames(fp, resolution=resolution).process(ev1, after=prm.reference_read == "after")
    d2 = DynamicFrames(fp, resolution=resolution).process(ev2, after=True)
    threshold, tolerance, window, gain = _in_force_by_window(prm, (ev1, ev2), (d1, d2))
    t2_all = ev2["t"]
    rows = []
    last = {}  # consensus_radius: (x, y) -> (time, disparity) of the pixel's last match
    for i, e1 in enumerate(ev1):
        t, x, y = int(e1["t"]), int(e1["x"]), int(e1["y"])
        s = 1 if e1["p"] else -1
        k = t // prm.level_window_us
        if d1[i] is None or not abs(d1[i]) >= threshold[k][ref]:
            continue
        disparities = []
        lo = int(np.searchsorted(t2_all, t - window[k], side="left"))
        hi = int(np.searchsorted(t2_all, t + window[k], side="right"))
        for j in range(lo, hi):  # events e2 with |t2 - t| <= the window in force
            e2 = ev2[j]
            v2 = d2[j]
            s2 = 1 if e2["p"] else -1
            if v2 is None:
                continue
            k2 = int(e2["t"]) // prm.level_window_us
            if not (abs(v2) >= threshold[k2][1 - ref] and sign(v2) == s and s2 == s
                    and abs(d1[i] - v2 * gain[k2]) <= tolerance[k]):
                continue
            x2, y2 = int(e2["x"]), int(e2["y"])
            if abs(y2 - y) > prm.row_tolerance:
                continue
            if prm.restrict_side and (x2 < x if ref == 1 else x2 > x):
                continue
            if abs(x2 - x) > prm.max_disparity:
                continue
            disparities.append(abs(x2 - x))
        if not disparities:
            continue
        consensus = _consensus(last, x, y, t, prm) if prm.consensus_radius > 0 else None
        chosen = _choose(disparities, consensus)
        if chosen is not None:
            last[(x, y)] = (t, chosen)
            rows.append((t, x, y, int(e1["p"]), ref, float(chosen)))
    if not rows:
        return empty_matches()
    # The border rule (adaptive set) decides on the whole output, in its order.
    return border_rule_of(make_matches(*zip(*rows, strict=True)), prm, resolution)
