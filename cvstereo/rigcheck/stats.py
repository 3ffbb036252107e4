"""Event counts, ON share, rate imbalance and noise of the two cameras: :func:`count_statistics`."""

from __future__ import annotations

import numba
import numpy as np

from cvstereo.rigcheck.peaks import clip01

__all__ = ["BURST_PERCENTILE", "burst_ratio", "count_statistics", "isolated_events"]

#: The percentile of the burst ratio: the report's ``burst_ratio_p95`` is named for it.
BURST_PERCENTILE = 95


def count_statistics(left, right, *, duration_s, resolution, noise_window_us, burst_window_us,
                     burst_min_events) -> dict:
    """Rate ratio, burst ratio, ON share and isolated-event noise, each with its confidence (left camera first).

    Returns
    -------
    dict
        The count fields of :class:`~cvstereo.rigcheck.report.RigReport`, by name (``events`` to
        ``noise_confidence``; their meaning is documented there, once): the report is built from them.
    """
    n_l, n_r = int(left.size), int(right.size)
    rate_conf = clip01(1.0 - np.sqrt(1.0 / n_l + 1.0 / n_r) / 0.1)
    on = (float(left["p"].mean()), float(right["p"].mean()))
    on_conf = clip01(1.0 - max(np.sqrt(f * (1 - f) / n) for f, n in zip(on, (n_l, n_r), strict=True)) / 0.05)
    burst = burst_ratio(left, right, window_us=burst_window_us, min_events=burst_min_events)
    iso = [isolated_events(ev, window_us=noise_window_us, resolution=resolution) for ev in (left, right)]
    return dict(
        events=(n_l, n_r), rate_ratio=float(n_r / n_l), rate_ratio_confidence=rate_conf,
        burst_ratio_p95=burst, on_fraction=on, on_fraction_confidence=on_conf,
        noise_rate_hz=(float(iso[0] / duration_s), float(iso[1] / duration_s)),
        noise_fraction=(float(iso[0] / n_l), float(iso[1] / n_r)),
        noise_confidence=clip01(1.0 - 1.0 / np.sqrt(1.0 + min(iso))),
    )


def burst_ratio(left, right, *, window_us, min_events):
    """:data:`BURST_PERCENTILE` percentile, over windows with at least ``min_events`` events in each camera, of the
    larger count over the smaller; NaN without such a window."""
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    n = (max(int(left["t"][-1]), int(right["t"][-1])) - t0) // window_us + 1
    a = np.bincount((left["t"] - t0) // window_us, minlength=n)
    b = np.bincount((right["t"] - t0) // window_us, minlength=n)
    both = (a >= min_events) & (b >= min_events)
    if not both.any():
        return float("nan")
    r = np.maximum(a[both] / b[both], b[both] / a[both])
    return float(np.percentile(r, BURST_PERCENTILE))


def isolated_events(ev, *, window_us, resolution):
    """Number of events with no event at any of the 8 neighbouring pixels within ``window_us`` either side.

    The own pixel does not count: a hot pixel firing alone is noise too. Two sweeps over the time-ordered events
    with a grid of each pixel's nearest event time: forward, the latest event before (in the array); backward, the
    earliest after; the nearest neighbour event either side is within one of the two. Linear in the events.
    """
    width, height = resolution
    if ev.size == 0:
        return 0
    t = (ev["t"] - int(ev["t"][0])).astype(np.int64)
    return int(_count_isolated(t, ev["x"].astype(np.int64), ev["y"].astype(np.int64), int(width), int(height),
                               int(window_us)))


@numba.njit(cache=True, nogil=True)
def _count_isolated(t, x, y, width, height, window):  # pragma: no cover - compiled
    """:func:`isolated_events` of time-ordered events (times from 0)."""
    n = t.size
    never = -(1 << 62)
    near = np.full((height + 2, width + 2), never, np.int64)  # a one-pixel border: no bounds tests
    has = np.zeros(n, np.bool_)
    for i in range(n):  # forward: the latest event of each neighbour before this one
        cx, cy = x[i] + 1, y[i] + 1
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                if (dx != 0 or dy != 0) and t[i] - near[cy + dy, cx + dx] <= window:
                    has[i] = True
        near[cy, cx] = t[i]
    near[:, :] = -never
    count = 0
    for i in range(n - 1, -1, -1):  # backward: the earliest event of each neighbour after this one
        cx, cy = x[i] + 1, y[i] + 1
        if not has[i]:
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    if (dx != 0 or dy != 0) and near[cy + dy, cx + dx] - t[i] <= window:
                        has[i] = True
        near[cy, cx] = t[i]
        count += not has[i]
    return count
