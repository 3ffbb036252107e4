"""Event-area matcher: moving edges, search side, borders and ties."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges

from calibration_free.event_area import EventAreaMatcher, EventAreaParams
from cvstereo.events import make_events
from cvstereo.matches import concat_matches
from cvstereo.registry import create_matcher


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
    # ... unless max_cost is below that SAD (also under its old name max_sad).
    assert _run(right[:0], right, max_cost=1.0).size == 0
    assert _run(right[:0], right, max_sad=1.0).size == 0


def test_variant_parameters():
    assert EventAreaMatcher.make_params("no-gaussian").threshold == 4.0
    assert EventAreaMatcher.make_params("no-gaussian").gaussian is False
    assert EventAreaMatcher.make_params().threshold == 1.2
    with pytest.raises(ValueError, match="block"):
        EventAreaParams(block=4)


