"""Synthetic event streams for the event-matcher tests: random streams and moving vertical edges."""

from __future__ import annotations

import numpy as np

from cvstereo.model.events import make_events
from cvstereo.model.matches import concat_matches


def random_stream(rng: np.random.Generator, n: int, duration_us: int, *, width: int, height: int) -> np.ndarray:
    """``n`` uniformly random events on a small sensor (small, so that frame values build up), time-ordered.

    Timestamps repeat on purpose (ties within and across cameras).
    """
    t = np.sort(rng.integers(0, duration_us, n))
    return make_events(t, rng.integers(0, width, n), rng.integers(0, height, n), rng.integers(0, 2, n))


def random_pair(seed: int, n: int = 600, duration_us: int = 60_000, *, width: int = 32, height: int = 8):
    """Two independent random streams, and the resolution they live on."""
    rng = np.random.default_rng(seed)
    return (random_stream(rng, n, duration_us, width=width, height=height),
            random_stream(rng, n, duration_us, width=width, height=height), (width, height))


def feed_cut(matcher, left: np.ndarray, right: np.ndarray, cut_times) -> np.ndarray:
    """Stream a pair through ``matcher`` in packets cut at ``cut_times``, then flush; all matches.

    At each cut time the left camera's events at exactly that time go into the earlier packet and the
    right camera's into the later one, which is a legal cut (packets are time slices) that splits a tie.
    """
    parts = []
    il = ir = 0
    for c in sorted(cut_times):
        jl = int(np.searchsorted(left["t"], c, side="right"))
        jr = int(np.searchsorted(right["t"], c, side="left"))
        parts.append(matcher.feed(left[il:jl], right[ir:jr]))
        il, ir = jl, jr
    parts.append(matcher.feed(left[il:], right[ir:]))
    parts.append(matcher.flush())
    return concat_matches(parts)


def feed_slices(matcher, left: np.ndarray, right: np.ndarray, cut_times) -> np.ndarray:
    """Stream a pair through ``matcher`` in time slices ``[start, stop)`` between the cut times, each fed with
    ``until=stop`` (so that a matcher may close windows while a camera is silent), then flush; all matches."""
    out, start = [], 0
    for stop in sorted(cut_times):
        out.append(matcher.feed(left[(left["t"] >= start) & (left["t"] < stop)],
                                right[(right["t"] >= start) & (right["t"] < stop)], until=stop))
        start = stop
    out.append(matcher.feed(left[left["t"] >= start], right[right["t"] >= start]))
    out.append(matcher.flush())
    return concat_matches(out)


#: (start column, polarity) of the edges: three bars, 2, 3 and 4 px wide (ON leading edge, OFF trailing edge),
#: at irregular spacing; edges of one polarity lie at least 20 px apart.
EDGES = ((10, 1), (12, 0), (30, 1), (33, 0), (51, 1), (55, 0))


def moving_edges(*, shift: int = 6, delay_us: int = 50, edges=EDGES, us_per_px: int = 1000,
                 duration_us: int = 40_000, rows: tuple[int, int] = (20, 100), events_per_pixel: int = 6,
                 width: int = 128, seed: int = 0):
    """Vertical edges moving right at one pixel per ``us_per_px``, seen by both cameras.

    While an edge crosses a pixel (``us_per_px``), the pixel fires ``events_per_pixel`` events of the edge's
    polarity, one in each equal part of the crossing at a random time. The right camera sees the left
    camera's events ``shift`` px to the left and ``delay_us`` later, so the true disparity of every event is
    ``shift``.

    Returns
    -------
    left, right : ndarray of EVENT_DTYPE
    """
    rng = np.random.default_rng(seed)
    t, x, y, p = [], [], [], []
    ys = np.arange(rows[0], rows[1])
    for x0, pol in edges:
        for k in range(duration_us // us_per_px):
            col = x0 + k
            if col >= width:
                break
            for i in range(events_per_pixel):
                phase = (i + rng.random(ys.size)) / events_per_pixel
                t.append(k * us_per_px + (phase * us_per_px).astype(np.int64))
                x.append(np.full(ys.size, col))
                y.append(ys)
                p.append(np.full(ys.size, pol))
    t, x, y, p = (np.concatenate(a) for a in (t, x, y, p))
    order = np.argsort(t, kind="stable")
    left = make_events(t[order], x[order], y[order], p[order])
    keep = left["x"] >= shift
    right = make_events(left["t"][keep] + delay_us, left["x"][keep] - shift, left["y"][keep], left["p"][keep])
    return left, right


def simulated_clip(t_stop_us: int = 100_000):
    """The first ``t_stop_us`` of the simulator's ``2arms-50cm`` preset (left, right, resolution); skips the
    test when the simulator is not available."""
    import pytest

    try:
        from cvstereo.io.npz import read_recording_npz
        from cvstereo.simulate import cached_preset
    except ImportError as exc:
        pytest.skip(f"simulator not available: {exc}")
    rec = read_recording_npz(cached_preset("2arms-50cm", seconds=0.3))
    left = rec.left[rec.left["t"] < t_stop_us]
    right = rec.right[rec.right["t"] < t_stop_us]
    return left, right, rec.resolution
