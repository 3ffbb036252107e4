"""Event-time matcher: fast == reference, moving edges, the time and row limits, streaming lag."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges, random_pair, simulated_clip
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration_free.event_time import EventTimeMatcher, EventTimeParams
from calibration_free.reference.event_time import event_time_reference
from cvstereo.events import make_events
from cvstereo.matches import concat_matches, validate_matches
from cvstereo.registry import create_matcher


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), polarity=st.sampled_from(["shared", "separate", "on", "off"]),
       reference_camera=st.sampled_from([0, 1]), restrict_side=st.booleans(),
       n_cuts=st.integers(0, 30))
def test_fast_equals_reference_across_packet_cuts(seed, polarity, reference_camera, restrict_side, n_cuts):
    left, right, resolution = random_pair(seed, n=1500, width=24, height=6)
    params = EventTimeParams(polarity=polarity, reference_camera=reference_camera, restrict_side=restrict_side,
                             max_disparity=12)
    expected = event_time_reference(left, right, params, resolution=resolution)
    cuts = np.random.default_rng(seed).choice(np.concatenate([left["t"], right["t"]]), n_cuts)
    got = feed_cut(EventTimeMatcher(params, resolution=resolution), left, right, cuts)
    assert expected.size > 0 or polarity == "shared"
    np.testing.assert_array_equal(got, expected)
    validate_matches(got)


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


def test_fast_equals_reference_on_a_simulated_clip():
    left, right, resolution = simulated_clip(100_000)
    expected = event_time_reference(left, right, EventTimeParams(), resolution=resolution)
    got = feed_cut(EventTimeMatcher(EventTimeParams(), resolution=resolution), left, right, range(0, 100_000, 3_333))
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
