"""Event-area matcher: fast == reference, moving edges, search side, borders and ties."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges, random_pair, simulated_clip
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration_free.event_area import EventAreaMatcher, EventAreaParams
from calibration_free.reference.event_area import event_area_reference
from cvstereo.events import make_events
from cvstereo.matches import concat_matches, validate_matches
from cvstereo.registry import create_matcher


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), variant=st.sampled_from(["gaussian", "no-gaussian"]),
       polarity=st.sampled_from(["shared", "separate", "on"]), n_cuts=st.integers(0, 30))
def test_fast_equals_reference_across_packet_cuts(seed, variant, polarity, n_cuts):
    left, right, resolution = random_pair(seed, n=1000, width=32, height=8)
    # no-gaussian needs |D| >= 4, which random streams rarely reach: lower it to exercise the search
    params = EventAreaMatcher.make_params(variant, polarity=polarity, max_disparity=20,
                                          **({"threshold": 2.0} if variant == "no-gaussian" else {}))
    expected = event_area_reference(left, right, params, resolution=resolution)
    cuts = np.random.default_rng(seed).choice(np.concatenate([left["t"], right["t"]]), n_cuts)
    got = feed_cut(EventAreaMatcher(params, resolution=resolution), left, right, cuts)
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    validate_matches(got)


@pytest.mark.parametrize("variant", ["gaussian", "no-gaussian"])
def test_moving_edges_give_the_shift(variant):
    left, right = moving_edges(shift=6, delay_us=50)
    matches = feed_cut(create_matcher("event-area", variant), left, right, range(0, 40_000, 777))
    assert set(np.unique(matches["camera"]).tolist()) == {0, 1}  # both cameras are matched
    assert matches.size > 0.1 * (left.size + right.size)
    assert np.mean(matches["disparity"] == 6) >= 0.95


def _run(left, right, **params):
    m = EventAreaMatcher(EventAreaParams(**params))
    return concat_matches([m.feed(left, right), m.flush()])


def test_each_camera_searches_its_own_side():
    # A blob built up in both frames, the left one 4 px right of the right one: the left camera's probe
    # finds it 4 px to its left, the right camera's probe 4 px to its right.
    t = np.repeat(np.arange(10), 2)
    left = make_events(np.r_[t, 100], np.r_[np.tile([40, 41], 10), 40], [30] * 21, [1] * 21)
    right = make_events(np.r_[t, 100], np.r_[np.tile([36, 37], 10), 36], [30] * 21, [1] * 21)
    matches = _run(left, right)
    probes = matches[matches["t"] == 100]
    assert probes["camera"].tolist() == [0, 1] and probes["disparity"].tolist() == [4.0, 4.0]


def test_events_near_the_border_are_not_matched_and_ties_go_to_the_smaller_disparity():
    t = np.arange(10)
    right = make_events(np.r_[t, 100], [1] * 11, [30] * 11, [1] * 11)  # x = 1: its block leaves the sensor
    assert _run(right[:0], right).size == 0
    # Nothing in the left frame: every candidate block has the same SAD, and disparity 0 wins.
    right = make_events(np.r_[t, 100], [50] * 11, [30] * 11, [1] * 11)
    matches = _run(right[:0], right)
    assert matches.size > 0 and np.all(matches["disparity"] == 0)
    # ... unless max_sad is below that SAD.
    assert _run(right[:0], right, max_sad=1.0).size == 0


def test_variant_parameters():
    assert EventAreaMatcher.make_params("no-gaussian").threshold == 4.0
    assert EventAreaMatcher.make_params("no-gaussian").gaussian is False
    assert EventAreaMatcher.make_params().threshold == 1.2
    with pytest.raises(ValueError, match="block"):
        EventAreaParams(block=4)


def test_fast_equals_reference_on_a_simulated_clip():
    left, right, resolution = simulated_clip(100_000)
    expected = event_area_reference(left, right, EventAreaParams(), resolution=resolution)
    got = feed_cut(EventAreaMatcher(EventAreaParams(), resolution=resolution), left, right, range(0, 100_000, 3_333))
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
