"""The pruned searches of event-area and event-vector (block bounds, column-sum bounds, runs) find what the
full searches of their references find, on wide sparse rows where most blocks are skipped.

The scenes are sparse clusters of events far apart along rows 200 px wide, seen by the other camera shifted
by up to 90 px, with noise; a fast decay renormalises the lazy scale (the bounds are rebuilt)
and a long gap clears the frames.
"""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut

from cvstereo.frames.dynamic import FORGET_TICKS
from cvstereo.matchers._shared.frame_bounds import BOUND_SHIFT, skip_below
from cvstereo.matchers.event_area.reference import event_area_reference
from cvstereo.matchers.event_vector.reference import event_vector_reference
from cvstereo.matchers.registry import matcher_class
from cvstereo.model.events import make_events

WIDTH, HEIGHT = 200, 8


def sparse_pair(seed: int, n_clusters: int = 8, per_cluster: int = 60):
    """Clusters of events at random columns, the right camera's shifted left by 0..90 px, plus noise."""
    rng = np.random.default_rng(seed)
    cams = [[], []]
    for k in range(n_clusters):
        shift = int(rng.integers(0, 91))
        x0, y0 = int(rng.integers(shift + 3, WIDTH - 6)), int(rng.integers(2, HEIGHT - 3))
        t = np.sort(rng.integers(k * 16_000, k * 16_000 + 1_500, per_cluster))
        x = x0 + rng.integers(0, 3, per_cluster)
        y = y0 + rng.integers(0, 2, per_cluster)
        p = np.full(per_cluster, int(rng.integers(0, 2)))
        cams[0].append((t, x, y, p))
        cams[1].append((t, x - shift, y, p))
    if seed % 2:  # a gap beyond FORGET_TICKS: the frames (and their bounds) start afresh
        for cam in cams:
            t, x, y, p = cam[-1]
            cam[-1] = (t + (FORGET_TICKS + 5) * 250, x, y, p)
    for cam in cams:
        n = 40
        cam.append((rng.integers(0, n_clusters * 16_000, n), rng.integers(0, WIDTH, n), rng.integers(0, HEIGHT, n),
                    rng.integers(0, 2, n)))
    out = []
    for cam in cams:
        t, x, y, p = (np.concatenate(c) for c in zip(*cam, strict=True))
        order = np.argsort(t, kind="stable")
        out.append(make_events(t[order], x[order], y[order], p[order]))
    return out[0], out[1]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("method", "reference", "extra"), [
    ("event-area", event_area_reference, {}),
    ("event-area", event_area_reference, {"threshold_mode": "relative", "level_window_us": 5_000,
                                          "level_warmup": 20, "level_windows": 3}),
    ("event-vector", event_vector_reference, {"require_candidate_threshold": True}),
    ("event-vector", event_vector_reference, {"require_candidate_threshold": False}),
    ("event-vector", event_vector_reference, {"run_ends": True, "tie_break": "centre", "cost_ratio": 0.3,
                                              "cost_slack": 2.0}),
    ("event-vector", event_vector_reference, {"require_candidate_threshold": False, "run_ends": True}),
])
def test_pruned_search_equals_reference_on_sparse_wide_rows(method, reference, extra, seed):
    cls = matcher_class(method)
    # decay 0.95 every 25 us renormalises the lazy scale (below 1e-100) every ~112 ms: the bounds are rebuilt
    # within the 128 ms stream.
    params = cls.make_params(None, max_disparity=120, decay=0.95, decay_period_us=25, **extra)
    left, right = sparse_pair(seed)
    expected = reference(left, right, params, resolution=(WIDTH, HEIGHT))
    got = feed_cut(cls(params, resolution=(WIDTH, HEIGHT)), left, right, [40_000, 90_001])
    assert expected.size > 20  # the clusters do match
    np.testing.assert_array_equal(got, expected)


def test_skip_below_finds_the_first_column_at_or_above_the_threshold():
    rng = np.random.default_rng(3)
    width = 100
    for _ in range(200):
        stored = np.zeros((1, 1, 1, width))
        hot = rng.random(width) < 0.05
        stored[0, 0, 0] = np.where(hot, rng.normal(0, 2, width), rng.normal(0, 0.01, width))
        bound = np.zeros((1, 1, 1, (width + (1 << BOUND_SHIFT) - 1) >> BOUND_SHIFT))
        for b in range(bound.shape[3]):
            bound[0, 0, 0, b] = np.abs(stored[0, 0, 0, b << BOUND_SHIFT:(b + 1) << BOUND_SHIFT]).max()
        bound *= 1 + rng.random(bound.shape) * (rng.random(bound.shape) < 0.3)  # loose bounds are allowed
        c, threshold = float(rng.uniform(0.5, 2)), float(rng.uniform(0.5, 1.5))
        above = np.abs(stored[0, 0, 0] * c) >= threshold
        start = int(rng.integers(0, width))
        right = [k for k in range(start, width) if above[k]]
        left = [k for k in range(start, -1, -1) if above[k]]
        assert skip_below(stored, bound, 0, 0, 0, start, 1, width, c, threshold) == (right[0] if right else width)
        assert skip_below(stored, bound, 0, 0, 0, start, -1, -1, c, threshold) == (left[0] if left else -1)


def test_block_bounds_stay_above_every_stored_value():
    left, right = sparse_pair(1)
    cls = matcher_class("event-vector")
    matcher = cls(cls.make_params(None, decay=0.95, decay_period_us=25), resolution=(WIDTH, HEIGHT))
    for cut in np.linspace(0, left["t"][-1], 7)[1:]:
        matcher.feed(left[left["t"] < cut], right[right["t"] < cut])
        left, right = left[left["t"] >= cut], right[right["t"] >= cut]
        stored, bound = np.abs(matcher._bank.stored), matcher._bound
        for b in range(bound.shape[3]):
            block = stored[..., b << BOUND_SHIFT:(b + 1) << BOUND_SHIFT].max(axis=-1)
            assert np.all(bound[..., b] >= block)
        assert stored.max() > 0


def dense_pair(seed: int, n_events: int = 2500):
    """Rows 200 px wide crowded with runs of every length (a few px to over 100, across the 64-px words of
    event-vector's bit masks and the edges of its 64-px window around an event), of both polarities side by
    side, the right camera's shifted left by 0..40 px; a few rows empty."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(0, 60_000, n_events))
    y = rng.integers(0, HEIGHT - 2, n_events)  # the last two rows stay empty
    centre = rng.integers(0, WIDTH, n_events // 50)[np.arange(n_events) // 50]  # clusters that drift along rows
    spread = rng.choice([2, 8, 40, 90], n_events // 50)[np.arange(n_events) // 50]
    x = np.clip(centre + rng.integers(-spread, spread + 1), 0, WIDTH - 1)
    p = (x // int(rng.integers(3, 9)) + y) % 2  # stripes of ON and OFF within a run
    shift = rng.integers(0, 41, n_events // 50)[np.arange(n_events) // 50]
    return make_events(t, x, y, p), make_events(t, np.clip(x - shift, 0, WIDTH - 1), y, p)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("extra", [
    {},
    {"run_ends": True, "tie_break": "centre", "cost_ratio": 0.3, "cost_slack": 2.0},
    {"polarity": "separate", "run_ends": True, "kernel_size": 5, "kernel_sigma": 1.5},
])
def test_event_vector_search_equals_reference_on_dense_wide_rows(extra, seed):
    # The other side of the sparse rows above: long runs, runs of both signs, rows that are mostly above the
    # threshold, where the bit masks' words, the window of the event's own vector and the walks beyond them meet.
    cls = matcher_class("event-vector")
    params = cls.make_params(None, max_disparity=120, threshold=0.3, **extra)
    left, right = dense_pair(seed)
    expected = event_vector_reference(left, right, params, resolution=(WIDTH, HEIGHT))
    got = feed_cut(cls(params, resolution=(WIDTH, HEIGHT)), left, right, [20_000, 41_001])
    assert expected.size > 500
    np.testing.assert_array_equal(got, expected)
