"""Event-time matcher: moving edges, the time and row limits, streaming lag."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges

from cvstereo.matchers.event_time.matcher import EventTimeMatcher, EventTimeParams
from cvstereo.matchers.registry import create_matcher
from cvstereo.model.events import make_events
from cvstereo.model.matches import concat_matches, validate_matches


@pytest.mark.parametrize("variant", ["shared", "separate", "on", "off"])
@pytest.mark.parametrize("reference_camera", [0, 1])
def test_moving_edges_give_the_shift(variant, reference_camera):
    left, right = moving_edges(shift=6, delay_us=50)
    m = create_matcher("event-time", variant, reference_camera=reference_camera)
    matches = feed_cut(m, left, right, range(0, 40_000, 777))
    assert matches.size > 0.2 * (left.size if reference_camera == 0 else right.size)
    assert np.all(matches["camera"] == reference_camera)
    assert np.mean(matches["disparity"] == 6) >= 0.95


def _probe(*, dt: int, dy: int):
    """One right-camera event at (50, 40, t=1000) whose frame already holds 1.18, and one left candidate at
    (55, 40 + dy, 1000 + dt) whose frame reads 1.2 after its update; earlier events build up the values and
    are themselves too far away in time to be candidates."""
    right = make_events([0, 5, 10, 1000], [50] * 4, [40] * 4, [1] * 4)
    lt = sorted([0, 10, 1000 + dt])
    left = make_events(lt, [55] * 3, [40 + dy] * 3, [1] * 3)
    # the left frame's value after the probe: two earlier events, decayed, plus its own centre weight
    matcher = EventTimeMatcher()
    matches = concat_matches([matcher.feed(left, right), matcher.flush()])
    return matches[matches["t"] == 1000]


@pytest.mark.parametrize(("dt", "dy", "found"), [
    (300, 0, True), (-300, 0, True), (301, 0, False), (-301, 0, False),
    (0, 1, True), (0, -1, True), (0, 2, False), (0, -2, False), (300, 1, True), (301, 1, False),
])
def test_candidates_only_within_300us_and_one_row(dt, dy, found):
    probe = _probe(dt=dt, dy=dy)
    assert probe.size == (1 if found else 0)
    if found:
        assert probe["disparity"][0] == 5.0 and probe["camera"][0] == 1


def test_wrong_side_and_polarity_are_not_candidates():
    right = make_events([0, 5, 10, 1000], [50] * 4, [40] * 4, [1] * 4)
    for x2, p2 in ((45, 1), (55, 0)):
        left = make_events([0, 10, 1000], [x2] * 3, [40] * 3, [p2] * 3)
        m = EventTimeMatcher()
        matches = concat_matches([m.feed(left, right), m.flush()])
        assert not np.any(matches["t"] == 1000)
    # without the side restriction Algorithm 1 takes the left-side candidate, reporting |x2 - x|
    left = make_events([0, 10, 1000], [45] * 3, [40] * 3, [1] * 3)
    m = EventTimeMatcher(EventTimeParams(restrict_side=False))
    matches = concat_matches([m.feed(left, right), m.flush()])
    assert matches[matches["t"] == 1000]["disparity"].tolist() == [5.0]


def test_output_lags_by_the_window_and_stays_time_ordered():
    right = make_events([0, 5, 10, 1000], [50] * 4, [40] * 4, [1] * 4)
    left = make_events([0, 10, 1200], [55] * 3, [40] * 3, [1] * 3)
    m = EventTimeMatcher()
    early = m.feed(left, right, until=1300)  # watermark 1300 = t + window: a candidate at 1300 may still come
    assert not np.any(early["t"] == 1000)
    late = m.feed(left[:0], right[:0], until=1301)
    assert late["t"].tolist() == [1000]
    everything = concat_matches([early, late, m.flush()])
    validate_matches(everything)


def test_describe_and_anchor_camera():
    m = create_matcher("event-time", "separate", reference_camera=0)
    meta = m.describe()
    assert meta["method"] == "event-time" and meta["variant"] == "separate"
    assert meta["anchor_cameras"] == [0] and meta["params"]["threshold"] == 0.8
    with pytest.raises(ValueError, match="reference_camera"):
        EventTimeParams(reference_camera=2)




def test_neighbour_intervals_by_hand():
    """Time back to the last earlier same-polarity event in the 3x3 neighbourhood, fast kernel and reference."""
    from cvstereo.matchers.event_time.matcher import NO_TIME, _neighbour_intervals
    from cvstereo.matchers.event_time.reference import _neighbour_intervals as reference_intervals

    # Times 1 ms earlier than the comment says: time stamps may be negative, and "no event yet" is not -1.
    events = make_events(np.array([0, 100, 100, 250, 400, 700, 50_000]) - 1000, [5, 6, 6, 20, 5, 7, 6],
                         [5, 5, 5, 5, 5, 6, 6], [1, 1, 1, 1, 0, 1, 1])
    # 100: (5, 5) at 0; 100 again: the duplicate finds the same earlier event, not itself; 250: nobody near;
    # 400: no earlier OFF event; 700: (6, 5) at 100; 50 000: 49 300 us after (7, 6), beyond the 40 ms cap.
    expected = [np.nan, 100, 100, np.nan, np.nan, 600, np.nan]
    cols = [events[name].astype(np.int64) for name in ("t", "x", "y", "p")]
    for cut in range(events.size + 1):  # the writes held back at a call's end (time 100) reach the next call
        last, deferred = np.full((2, 10, 24), NO_TIME, np.int64), np.empty(events.size, np.int64)
        state = np.array([0, NO_TIME])
        fast = np.empty(events.size)
        _neighbour_intervals(*(c[:cut] for c in cols), last, deferred, state, 40_000, fast[:cut])
        _neighbour_intervals(*(c[cut:] for c in cols), last, deferred, state, 40_000, fast[cut:])
        np.testing.assert_array_equal(fast, expected)
    np.testing.assert_array_equal(reference_intervals(events, 40_000), expected)


@pytest.mark.parametrize(("read", "found"), [("before", False), ("after", True)])
def test_reading_d1_after_its_update_pairs_lone_events(read, found):
    """Two first events at their pixels, at the same time: D2 just after its update is one centre weight (0.41);
    D1 is 0 before its update (|0 - 0.41| > 0.3: no match) and 0.41 after (a match at 5 px)."""
    right = make_events([1000], [50], [40], [1])
    left = make_events([1000], [55], [40], [1])
    m = EventTimeMatcher(EventTimeParams(threshold=0.0, reference_read=read))
    matches = concat_matches([m.feed(left, right), m.flush()])
    assert matches["disparity"].tolist() == ([5.0] if found else [])


def _paced_pair(offset_us: int, period_us: int = 2000, until_us: int = 100_000):
    """One pixel per camera firing every ``period_us``, the right camera ``offset_us`` after the left, 5 px apart."""
    t = np.arange(0, until_us, period_us)
    left = make_events(t, np.full(t.size, 55), np.full(t.size, 40), np.ones(t.size, int))
    right = make_events(t + offset_us, np.full(t.size, 50), np.full(t.size, 40), np.ones(t.size, int))
    return left, right


@pytest.mark.parametrize(("scale", "found"), [(0.0, False), (0.5, True)])
def test_the_time_window_follows_the_pace(scale, found):
    """Partners 900 us apart: outside the fixed 300 us; inside 0.5 x the 2 ms pace once it is known."""
    from cvstereo.matchers.event_time.reference import event_time_reference

    left, right = _paced_pair(900)
    prm = EventTimeParams(threshold_mode="relative", level_window_us=5_000, level_warmup=20, level_windows=3,
                          threshold_scale=0.65, value_tolerance_scale=0.4, time_window_scale=scale)
    matches = feed_cut(EventTimeMatcher(prm, resolution=(64, 48)), left, right, range(0, 100_000, 3_001))
    np.testing.assert_array_equal(matches, event_time_reference(left, right, prm, resolution=(64, 48)))
    if found:
        # Warm-up: the pace is known after 20 intervals (40 ms), the fixed window in force before.
        assert matches.size > 20 and set(matches["disparity"].tolist()) == {5.0}
        assert matches["t"].min() >= 40_000
    else:
        assert matches.size == 0


def test_windows_that_shrink_and_grow_keep_fast_equal_to_reference():
    """A pace that changes (periods 2 ms, 0.5 ms, 3 ms, 0.5 ms; 100 ms each) gives long time windows, then the
    300 us floor, then long ones again. Where a window grows, a pending event (B, 50 us into a 5 ms level
    window) reaches back to its partner 0.8 or 1.2 ms before it, further back than the shorter window of the
    pending event just before it in its row (A, 100 us earlier, no partner): each row's scan start must move
    back. fast == reference at any packet cut (and with the partners at negative times at the start, which the
    fast path's intervals once took for "no event yet")."""
    from cvstereo.matchers._shared.reference_frames import DynamicFrames
    from cvstereo.matchers.event_time.reference import _in_force_by_window, event_time_reference

    left, right = [], []
    for i, (period, lag) in enumerate(((2000, 800), (500, 100), (3000, 1200), (500, 100))):
        # B: 50 us after a multiple of 1 ms, so 50 us after every 5 ms level window's start (2 and 3 ms periods
        # step through all multiples of 1 ms modulo 5 ms); its partner lag us earlier (the first ones at
        # negative times).
        b = 102_000 * i + np.arange(50, 100_000, period)
        left.append(make_events(b - lag, np.full(b.size, 30), np.full(b.size, 20), np.ones(b.size, int)))
        right.append(make_events(b - 100, np.full(b.size, 40), np.full(b.size, 20), np.ones(b.size, int)))  # A
        right.append(make_events(b, np.full(b.size, 25), np.full(b.size, 20), np.ones(b.size, int)))  # B
    left, right = (np.sort(np.concatenate(ev), order="t", kind="stable") for ev in (left, right))
    prm = EventTimeParams(threshold_mode="relative", level_window_us=5_000, level_warmup=20, level_windows=3,
                          threshold_scale=0.65, value_tolerance_scale=0.4, time_window_scale=0.5)
    expected = event_time_reference(left, right, prm, resolution=(64, 48))
    # The windows in force (reference camera first, D read after the update as adaptive reads them).
    d = [DynamicFrames(prm.frame_params(), resolution=(64, 48)).process(ev, after=True) for ev in (right, left)]
    steps = np.diff(list(_in_force_by_window(prm, (right, left), d)[2].values()))
    assert (steps > 0).any() and (steps < 0).any() and expected.size > 100
    for step in (410_000, 2_999, 7_001, 40_000):
        got = feed_cut(EventTimeMatcher(prm, resolution=(64, 48)), left, right, range(0, 410_000, step))
        np.testing.assert_array_equal(got, expected)


def _veto_scene(probe_partners, neighbour_disparities=(5, 5)):
    """Right-camera events at (49, 40) t=1000 and (51, 40) t=2000 whose only partners lie
    ``neighbour_disparities`` px to their right, then a probe at (50, 40) t=3000 with left candidates at
    ``50 + d`` for d in ``probe_partners`` (all at t=3000; every other pair is more than 300 us apart)."""
    right = make_events([1000, 2000, 3000], [49, 51, 50], [40] * 3, [1] * 3)
    lx = [49 + neighbour_disparities[0], 51 + neighbour_disparities[1], *(50 + d for d in probe_partners)]
    lt = [1000, 2000, *([3000] * len(probe_partners))]
    return make_events(lt, lx, [40] * len(lx), [1] * len(lx)), right


@pytest.mark.parametrize(("partners", "neighbours", "overrides", "expected"), [
    ((2, 5), (5, 5), {}, 5),  # the neighbours agree on 5: the look-alike at 2 gives way to the candidate at 5
    ((2,), (5, 5), {}, None),  # ... and with no candidate near 5 the probe is not matched
    ((2, 5), (5, 5), {"consensus_radius": 0}, 2),  # off (the thesis): the smallest distance
    ((2, 5), (5, 5), {"consensus_window_us": 1500}, 2),  # the match at t=1000 is too old: one neighbour is no consensus
    ((2, 5), (5, 9), {}, 2),  # neighbours that disagree (5 and 9) veto nothing
    ((2, 5), (5, 5), {"consensus_window_us": 1500, "consensus_min": 1}, 5),  # ... unless one suffices
    ((4, 5), (5, 5), {}, 4),  # within 1 px of the consensus: no veto
    ((2, 4, 6), (5, 5), {}, 4),  # none at 5, two 1 px from it: the smaller
    ((2, 6), (5, 5), {}, 6),  # none at 5 or 4: the one 1 px above
    ((5,), (2, 2), {}, None),  # a consensus below the smallest distance: no candidate can be near it
])
def test_the_neighbours_consensus_vetoes_a_look_alike(partners, neighbours, overrides, expected):
    """By hand: the neighbour matches (d = 5 each unless said otherwise) and the probe's candidates; fast at
    every packet cut and reference give the expected disparity of the probe (None: not matched)."""
    from cvstereo.matchers.event_time.reference import event_time_reference

    left, right = _veto_scene(partners, neighbours)
    prm = EventTimeParams(threshold=0.0, value_tolerance=10.0, **{"consensus_radius": 1, **overrides})
    expected_rows = event_time_reference(left, right, prm, resolution=(64, 48))
    assert expected_rows["disparity"][:2].tolist() == list(map(float, neighbours))
    probe = expected_rows[expected_rows["t"] == 3000]["disparity"].tolist()
    assert probe == ([] if expected is None else [float(expected)])
    for cut in (0, 1000, 1500, 2000, 2500, 3000):
        got = feed_cut(EventTimeMatcher(prm, resolution=(64, 48)), left, right, [cut])
        np.testing.assert_array_equal(got, expected_rows)
