"""Event-area and event-vector in row bands (issue 28 item 1): the same matches with any number of threads.

The matches with 1, 2 and 3 threads must be equal as arrays (same rows, same order) on simulated 128x128 and
640x480 clips, for every variant of both matchers and both parameter sets; over random packet cuts, random thread
counts (changing from packet to packet) and tiny sensors (bands of one or two rows, halos reaching across
several bands) they must equal the one-thread run's and the reference's. The bands' rows must be the one-thread
state bit for bit (:class:`cvstereo.matchers._shared.row_bands.BandedState`).
"""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import pytest
from _event_scenes import feed_cut, random_pair, simulated_clip
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.matchers._shared import row_bands
from cvstereo.matchers._shared.row_bands import band_rows, even_cuts
from cvstereo.matchers.event_area.reference import event_area_reference
from cvstereo.matchers.event_vector.reference import event_vector_reference
from cvstereo.matchers.registry import matcher_class, matcher_params
from cvstereo.model.matches import concat_matches

METHODS = ("event-area", "event-vector")
COMBOS = [(m, v) for m in METHODS for v in matcher_class(m).variants]
#: Single-pixel updates reach the variant's threshold (4) rarely in short clips (as test_fast_vs_reference's case).
NO_GAUSSIAN = {"threshold": 2.0}
REFERENCES = {"event-area": event_area_reference, "event-vector": event_vector_reference}


def thread_count(matcher, n: int):
    """``matcher`` on ``n`` threads: its feed and flush set numba's and OpenCV's counts themselves
    (:func:`cvstereo._threads.using_threads`)."""
    matcher.threads = n
    return nullcontext(matcher)


def make(method: str, variant: str, param_set: str, resolution, **extra):
    return matcher_class(method)(matcher_params(method, variant, resolution=resolution, param_set=param_set,
                                                **extra), resolution=resolution)


def assert_same_state(banded, one):
    """The state assembled from ``banded``'s bands is ``one``'s (a one-thread matcher's) bit for bit, but for the
    magnitude bound (event-area's mass), which must bound it."""
    full, expected = banded._bands.full(), one._bands.full()
    for name in full._fields:
        if name == "mass":
            assert np.all(full.mass >= expected.mass)
        else:
            np.testing.assert_array_equal(getattr(full, name), getattr(expected, name), err_msg=name)


def clip_640(seconds: float = 0.05):
    """The first ``seconds`` of the robustness suite's 640x480 recording (simulated, cached)."""
    try:
        from cvstereo.io import read_recording
        from cvstereo.simulate import suite_recordings
    except ImportError as exc:
        pytest.skip(f"simulator not available: {exc}")
    rec = read_recording(dict(suite_recordings("robustness", seconds=seconds, only=["sensor-640x480"]))[
        "sensor-640x480"])
    return rec.left, rec.right, rec.resolution


@pytest.mark.parametrize("param_set", ["thesis", "adaptive"])
@pytest.mark.parametrize(("method", "variant"), COMBOS)
@pytest.mark.parametrize("clip", ["128x128", "640x480"])
def test_threads_give_the_one_thread_matches_on_simulated_clips(clip, method, variant, param_set):
    left, right, res = simulated_clip(60_000) if clip == "128x128" else clip_640()
    cuts = [int(left["t"][left.size // 3]), int(right["t"][2 * right.size // 3])]
    extra = NO_GAUSSIAN if variant == "no-gaussian" else {}
    runs = {}
    for n in (1, 2, 3):
        with thread_count(make(method, variant, param_set, res, **extra), n) as m:
            runs[n] = feed_cut(m, left, right, cuts)
    assert runs[1].size > 100  # a clip that matches, so that equal results say something
    np.testing.assert_array_equal(runs[2], runs[1])
    np.testing.assert_array_equal(runs[3], runs[1])


@pytest.mark.parametrize(("method", "variant"), COMBOS)
def test_bands_keep_the_one_thread_state_bit_for_bit(method, variant):
    # Each band's own rows of the frames, of event-area's column sums and of event-vector's block bounds are the
    # one-thread run's, bit for bit; the assembled magnitude bound (event-area's mass) bounds the whole sensor.
    left, right, res = simulated_clip(60_000)
    one = make(method, variant, "adaptive", res)
    one.feed(left, right)
    with thread_count(make(method, variant, "adaptive", res), 3) as three:
        three.feed(left, right)
        assert three._bands.n_bands == 3
    assert_same_state(three, one)
    assert np.abs(three._bands.full().stored).max() > 0.5  # frames with content


def test_band_rows_keep_the_halo_on_the_sensor():
    cuts = np.array([0, 3, 6, 10])
    assert [band_rows.py_func(cuts, b, 10, 2) for b in range(3)] == [(0, 3, 0, 5), (3, 6, 1, 8), (6, 10, 4, 10)]


def test_cuts_share_the_events_and_give_every_band_a_row():
    assert even_cuts(3, 10).tolist() == [0, 3, 6, 10]  # no events: as many rows each
    rows = np.repeat(np.arange(100), np.where(np.arange(100) >= 80, 40, 1))  # 80 events above row 80, 800 below
    cuts = even_cuts(2, 100, rows)
    assert cuts.tolist() == [0, 89, 100]  # 440 events each: the busy rows are split
    assert even_cuts(4, 6, np.full(50, 5)).tolist() == [0, 3, 4, 5, 6]  # all on one row: one row each at least


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("n_threads", [2, 3])
def test_bands_cut_anew_when_the_events_move_give_the_same_matches(monkeypatch, method, n_threads):
    # Every window may cut anew (no wait between cuts, any imbalance): the events of a scene move from row to row,
    # and each new cut moves the rows that change hands between the bands; the matches stay the one-thread run's
    # and the bands' own rows its state, bit for bit.
    monkeypatch.setattr(row_bands, "REBALANCE_EVENTS", 0)
    monkeypatch.setattr(row_bands, "REBALANCE_SHARE", 1.0)
    left, right, res = simulated_clip(60_000)
    variant = next(iter(matcher_class(method).variants))
    one = make(method, variant, "adaptive", res)
    expected = feed_cut(one, left, right, [20_000, 40_000])
    with thread_count(make(method, variant, "adaptive", res), n_threads) as m:
        cuts_seen = []
        layout = m._bands.layout

        def recording_layout(n, rows):
            out = layout(n, rows)
            cuts_seen.append(tuple(m._bands.cuts))
            return out

        monkeypatch.setattr(m._bands, "layout", recording_layout)
        got = feed_cut(m, left, right, [20_000, 40_000])
    assert len(set(cuts_seen)) >= 3  # it did cut anew, more than once
    np.testing.assert_array_equal(got, expected)
    assert_same_state(m, one)


def test_serial_and_parallel_kernels_are_cached_apart():
    # numba's cache keys a function by name and signature, not by its options: one name for both compiles would
    # load the serial code where the parallel one is asked for.
    for method in METHODS:
        serial, parallel = matcher_class(method).kernels
        assert not serial.targetoptions.get("parallel") and parallel.targetoptions.get("parallel")
        assert serial.py_func.__qualname__ != parallel.py_func.__qualname__
        assert serial.py_func.__code__ is parallel.py_func.__code__  # one source


@st.composite
def banded_case(draw):
    method, variant = draw(st.sampled_from(COMBOS))
    height = draw(st.sampled_from([5, 8]))
    left, right, res = random_pair(draw(st.integers(0, 10_000)), 500, 40_000, width=24, height=height)
    extra = {"max_disparity": 12, "polarity": draw(st.sampled_from(["shared", "separate"]))}
    if method == "event-area":
        extra |= {"block": draw(st.sampled_from([3, 5])), "threshold": 2.0 if variant == "no-gaussian" else 1.2}
    else:
        extra |= {"require_candidate_threshold": draw(st.booleans())}
    cuts = sorted(draw(st.lists(st.integers(0, 40_000), max_size=4)))
    threads = draw(st.lists(st.integers(1, 6), min_size=len(cuts) + 2, max_size=len(cuts) + 2))
    return method, variant, left, right, res, extra, cuts, threads


@settings(max_examples=40, deadline=None)
@given(banded_case())
def test_any_packet_cuts_and_thread_counts_give_the_one_thread_and_reference_matches(case):
    # The thread count changes from packet to packet (the bands are cut anew from the assembled state), up to
    # more bands than the sensor's rows allow (then one band per row).
    method, variant, left, right, res, extra, cuts, threads = case
    one = make(method, variant, "thesis", res, **extra)
    expected = concat_matches([one.feed(left, right), one.flush()])
    np.testing.assert_array_equal(expected, REFERENCES[method](left, right, one.params, resolution=res))
    m = make(method, variant, "thesis", res, **extra)
    bounds = [0, *cuts, 1 << 40]
    parts = []
    for k, n in enumerate(threads[:-1]):
        lo, hi = bounds[k], bounds[k + 1]
        with thread_count(m, n):
            parts.append(m.feed(left[(left["t"] >= lo) & (left["t"] < hi)],
                                right[(right["t"] >= lo) & (right["t"] < hi)]))
    with thread_count(m, threads[-1]):
        parts.append(m.flush())
    np.testing.assert_array_equal(concat_matches(parts), expected)
