"""Event-area matcher: moving edges, search side, borders and ties."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges, simulated_clip

from cvstereo.matchers.event_area.matcher import EventAreaMatcher, EventAreaParams
from cvstereo.matchers.event_area.reference import event_area_reference
from cvstereo.matchers.registry import create_matcher
from cvstereo.model.events import make_events
from cvstereo.model.matches import concat_matches


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




def _blob(x, n, *, y=30, t0=0):
    """``n`` events at one pixel at times t0 .. t0 + n - 1 (within the first decay period: no decay)."""
    return np.arange(t0, t0 + n), [x] * n, [y] * n


def _events(*parts):
    """One camera's events from (t, x, y, p) parts, time-ordered."""
    t, x, y, p = (np.concatenate([np.asarray(part[k]) for part in parts]) for k in range(4))
    order = np.argsort(t, kind="stable")
    return make_events(t[order], x[order], y[order], p[order])


def test_sad_over_all_frames_uses_the_other_polarity_to_break_a_tie():
    # Right camera: an ON blob at x = 36 (probed at t = 100) and an OFF blob at x = 33, whose 3x3 updates reach
    # into the probe's 5x5 patch. Left camera: two identical ON blobs, at 40 (d = 4, a decoy) and 50 (d = 14),
    # and the OFF blob at 47 (d = 14). The ON frames alone tie at d = 4 and 14 (ties: the smaller); the OFF
    # frame decides for 14.
    on, off = 1, 0
    right = _events((*_blob(36, 10), [on] * 10), (*_blob(33, 10), [off] * 10), ([100], [36], [30], [on]))
    left = _events((*_blob(40, 10), [on] * 10), (*_blob(50, 10), [on] * 10), (*_blob(47, 10), [off] * 10))

    def probe(**params):
        m = _run(left, right, polarity="separate", max_disparity=20, **params)
        return m[(m["t"] == 100) & (m["camera"] == 1)]["disparity"].tolist()

    assert probe() == [4.0]                      # own frame (the thesis): the tie goes to the decoy
    assert probe(sad_frames="all") == [14.0]
    # With one shared frame per camera there is one frame to compare: "all" changes nothing.
    shared = [_run(left, right, max_disparity=20, sad_frames=s) for s in ("own", "all")]
    np.testing.assert_array_equal(shared[0], shared[1])


@pytest.mark.parametrize(("m", "expected"), [(6, [4.0]), (3, [])])
def test_own_ratio_needs_the_match_to_explain_part_of_the_own_patch(m, expected):
    # Right: 10 ON events at one pixel, then a probe there: its patch is 10 * 2 * G (sum 20, no decay yet).
    # Left: m events at the pixel 4 px to the right: SAD at d = 4 is (10 - m) * 2, every other candidate's more.
    # own_ratio 0.6 keeps the match iff (10 - m) * 2 < 0.6 * 20, i.e. m > 4; without it, it always stands.
    right = _events((*_blob(36, 10), [1] * 10), ([100], [36], [30], [1]))
    left = _events((*_blob(40, m), [1] * m))
    for ratio, want in ((0.0, [4.0]), (0.6, expected)):
        got = _run(left, right, own_ratio=ratio)
        assert got[(got["t"] == 100) & (got["camera"] == 1)]["disparity"].tolist() == want


def test_new_checks_are_off_by_default_and_validated():
    p = EventAreaParams()
    assert p.sad_frames == "own" and p.own_ratio == 0.0 and p.uniqueness == 0.0
    assert EventAreaParams(polarity="separate", sad_frames="all").compared_frames == 2
    assert EventAreaParams(sad_frames="all").compared_frames == 1
    with pytest.raises(ValueError, match="sad_frames"):
        EventAreaParams(sad_frames="both")
    with pytest.raises(ValueError, match="own_ratio"):
        EventAreaParams(own_ratio=-0.1)
    with pytest.raises(ValueError, match="uniqueness"):
        EventAreaParams(uniqueness=-0.1)


@pytest.mark.parametrize(("second", "uniqueness", "expected"), [
    (False, 0.0, [4.0]), (False, 3.5, [4.0]), (False, 4.5, []), (True, 0.2, [4.0]), (True, 0.6, [])])
def test_uniqueness_drops_ambiguous_matches(second, uniqueness, expected):
    # Right: 10 events at one pixel and a probe there (patch 10 * 2 * G, sum 20). Left: 8 events 4 px to the
    # right, SAD 4 at d = 4. Hand-computed SADs of the others: 16.27 at d = 3 and 5 (the blob one pixel off:
    # neighbours of the best, never rivals), 20 for an empty patch, 22.8 two pixels off; with a second blob of
    # 7 events at d = 14, 6 there. A match stands only if no rival lies within the factor 1 + uniqueness of 4:
    # 3.5 -> 18 (only the neighbours, exempt), 4.5 -> 22 (empty patches), 0.2 -> 4.8, 0.6 -> 6.4 (the blob).
    right = _events((*_blob(36, 10), [1] * 10), ([100], [36], [30], [1]))
    left = _events((*_blob(40, 8), [1] * 8), *([(*_blob(50, 7), [1] * 7)] if second else []))
    got = _run(left, right, uniqueness=uniqueness)
    assert got[(got["t"] == 100) & (got["camera"] == 1)]["disparity"].tolist() == expected


def test_adaptive_checks_together_fast_equals_reference():
    # The adaptive set's combination (separate frames, SAD over both, own_ratio, uniqueness, cost bound) on a
    # simulated clip, with short level windows so that the thresholds change often, cut into packets.
    from cvstereo.matchers.sets import resolve

    _, values = resolve("event-area", None, "adaptive")
    assert values["sad_frames"] == "all" and values["own_ratio"] > 0 and values["uniqueness"] > 0
    params = EventAreaMatcher.make_params("gaussian", **{**values, "level_window_us": 5_000, "level_warmup": 20,
                                                         "level_windows": 3})
    left, right, resolution = simulated_clip(100_000)
    # Every StreamMatcher passes its answers through the set's border rule (cvstereo.matchers._shared.border); the
    # reference is the algorithm alone, so its answers go through the same rule here.
    from cvstereo.matchers._shared.border import border_rule_for

    expected = border_rule_for(params, resolution)(event_area_reference(left, right, params, resolution=resolution))
    got = feed_cut(EventAreaMatcher(params, resolution=resolution), left, right, range(0, 100_000, 2_777))
    assert expected.size > 100
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("sad_frames", ["own", "all"])
def test_fast_equals_reference_across_renormalisations_and_a_reset(sad_frames):
    # decay 0.9 renormalises the frames every ~0.55 s and a gap beyond FORGET_TICKS clears them: both rebuild
    # the column sums that the kernel's lower bound reads; the matches must stay the reference's.
    from _event_scenes import random_pair

    from cvstereo.frames.dynamic import FORGET_TICKS

    left, right, resolution = random_pair(11, n=6000, duration_us=2_400_000)
    for ev in (left, right):
        ev["t"][ev.size // 2:] += (FORGET_TICKS + 5) * 250
    params = EventAreaParams(decay=0.9, polarity="separate", sad_frames=sad_frames, max_disparity=20,
                             threshold=0.1, uniqueness=0.2)
    expected = event_area_reference(left, right, params, resolution=resolution)
    got = feed_cut(EventAreaMatcher(params, resolution=resolution), left, right, [700_000, 1_500_000])
    assert expected.size > 100
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("param_set", ["thesis", "adaptive"])
def test_a_reset_before_any_decay_tick_rebuilds_the_column_sums(param_set):
    # A burst inside the first 250 us tick (the scale is still exactly 1.0), a gap beyond FORGET_TICKS that
    # clears the frames, then the same burst again: the reset leaves the scale unchanged, and the column sums of
    # the cleared frames must still be rebuilt, or the SAD's lower bound prunes real winners (the fast path gave
    # 146 of the reference's 292 matches before).
    from cvstereo.frames.dynamic import FORGET_TICKS
    from cvstereo.matchers.sets import resolve

    rng = np.random.default_rng(0)
    shift, gap = 12, (FORGET_TICKS + 5) * 250

    def burst(t0, n, duration):
        t = np.sort(rng.integers(t0, t0 + duration, n))
        return t, 60 + rng.integers(0, 4, n), 4 + rng.integers(0, 2, n)

    bursts = [burst(0, 80, 200), burst(gap, 80, 3000)]
    t, x, y = (np.concatenate(column) for column in zip(*bursts, strict=True))
    left, right = make_events(t, x, y, np.ones(t.size, int)), make_events(t, x - shift, y, np.ones(t.size, int))
    variant, values = resolve("event-area", None, param_set)
    params = EventAreaMatcher.make_params(variant, **{**values, "max_disparity": 30})
    expected = event_area_reference(left, right, params, resolution=(120, 10))
    got = feed_cut(EventAreaMatcher(params, resolution=(120, 10)), left, right, [])
    assert expected.size > 100 and np.all(expected["disparity"][expected["t"] >= gap] == shift)
    np.testing.assert_array_equal(got, expected)


def _mismatched_sensors(rows=(20, 100)):
    """The same edges, 6 px apart: the right camera fires four times as many events per edge as the left (a lower
    contrast threshold), so its frame values are about four times as large."""
    left, _ = moving_edges(shift=6, events_per_pixel=2, seed=1, rows=rows)
    _, right = moving_edges(shift=6, events_per_pixel=8, seed=2, rows=rows)
    return left, right


def _adaptive_params(**changes):
    from cvstereo.matchers.sets import resolve

    _, values = resolve("event-area", None, "adaptive")
    return EventAreaMatcher.make_params("gaussian", **{**values, "level_window_us": 5_000, "level_warmup": 20,
                                                       **changes})


def test_value_units_event_compares_sensors_of_different_thresholds():
    left, right = _mismatched_sensors()
    assert _adaptive_params().value_units == "camera"  # the adaptive set's choice
    results = {}
    for units in ("own", "camera", "polarity"):
        matches = feed_cut(EventAreaMatcher(_adaptive_params(value_units=units)), left, right, range(0, 40_000, 3_000))
        results[units] = matches[matches["t"] >= 10_000]  # after the levels' warm-up
    # In each camera's own units a patch of the busy camera never resembles one of the quiet camera: (almost)
    # nothing matches, and nothing at the true shift. In the event's units both cameras' events find it.
    for units in ("camera", "polarity"):
        assert results["own"].size < 0.01 * results[units].size
        for cam in (0, 1):
            mine = results[units][results[units]["camera"] == cam]
            assert mine.size > 0.3 * (left.size if cam == 0 else right.size)
            assert np.mean(mine["disparity"] == 6) >= 0.9
    assert not np.any(results["own"]["disparity"] == 6)


@pytest.mark.parametrize("units", ["own", "camera", "polarity"])
def test_value_units_fast_equals_reference_on_mismatched_sensors(units):
    from cvstereo.matchers._shared.border import border_rule_for

    # Ten rows and 12 ms (the reference is slow): the gains are in force from the third 5 ms level window on.
    left, right = _mismatched_sensors(rows=(40, 50))
    left, right = left[left["t"] < 12_000], right[right["t"] < 12_000]
    params = _adaptive_params(value_units=units)
    expected = border_rule_for(params, (128, 128))(event_area_reference(left, right, params))
    got = feed_cut(EventAreaMatcher(params), left, right, range(0, 12_000, 1_333))
    if units != "own":  # matches after the warm-up, where the gains are far from 1
        assert (expected["t"] >= 10_000).sum() > 100
    np.testing.assert_array_equal(got, expected)
