"""The adaptive set's consistency checks: neighbour support (frame), left-right check (frame-area), relative SAD
bound (event-area), each against an independent expectation; off (the thesis' value) they change nothing."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.matchers._shared.support import lr_consistent, support_counts, supported
from cvstereo.matchers.event_area.params import EventAreaParams
from cvstereo.matchers.frame.params import FrameClusterParams
from cvstereo.matchers.frame_area.params import FrameAreaParams
from cvstereo.model.matches import make_matches


def _brute_support(x, y, d, radius=2, tolerance=1.0):
    n = len(x)
    return [sum(1 for j in range(n) if j != i and abs(x[i] - x[j]) <= radius and abs(y[i] - y[j]) <= radius
                and abs(d[i] - d[j]) <= tolerance) for i in range(n)]


@pytest.mark.parametrize("seed", range(5))
def test_support_counts_equal_a_brute_force_count(seed):
    rng = np.random.default_rng(seed)
    n = 300
    x, y = rng.integers(0, 20, n), rng.integers(0, 10, n)  # dense: many shared pixels, rows that wrap
    d = rng.integers(0, 6, n) + rng.choice([0.0, 0.5], n)
    got = support_counts(x, y, d, width=20)
    assert got.tolist() == _brute_support(x.tolist(), y.tolist(), d.tolist())


def test_supported_keeps_every_match_when_off_and_drops_loners_when_on():
    m = make_matches(40_000, [10, 11, 12, 13, 60], [5, 5, 5, 5, 5], [1] * 5, 0, [4.0, 4.0, 4.5, 4.0, 4.0])
    assert supported(m, 0, width=128).tolist() == m.tolist()
    # x = 10 and 13 have two neighbours within 2 px, 11 and 12 three; x = 60 stands alone.
    assert supported(m, 2, width=128)["x"].tolist() == [10, 11, 12, 13]
    assert supported(m, 3, width=128)["x"].tolist() == [11, 12]
    assert FrameClusterParams().min_support == 0  # the thesis keeps every match


def test_lr_check_keeps_only_pixels_whose_partner_agrees():
    nan = np.nan
    right = np.full((3, 12), nan)
    left = np.full((3, 12), nan)
    right[1, 2], left[1, 5] = 3.0, 3.0      # x_left = 2 + 3 = 5 agrees
    right[1, 6], left[1, 9] = 3.0, 5.0      # partner says 5: 2 px off
    right[1, 7], left[1, 10] = 3.0, 4.0     # partner says 4: within 1 px
    right[2, 10] = 4.0                      # partner x = 14 is off the sensor
    ok = lr_consistent(right, left, reference_camera=1)
    assert sorted(zip(*np.nonzero(ok), strict=True)) == [(1, 2), (1, 7)]
    # The left camera as reference looks the other way: x_right = x_left - d.
    assert sorted(zip(*np.nonzero(lr_consistent(left, right, reference_camera=0)), strict=True)) == [(1, 5), (1, 10)]
    assert FrameAreaParams().lr_check is False and FrameAreaParams().polarity == "shared"


def test_event_area_cost_bound_follows_the_threshold():
    assert EventAreaParams().max_costs(np.array([0.3, 2.0])).tolist() == [1000.0, 1000.0]  # thesis: max_cost
    p = EventAreaParams(cost_scale=0.5)
    assert p.max_costs(np.array([0.4, 2.0])).tolist() == pytest.approx([0.5 * 25 * 0.4, 0.5 * 25 * 2.0])
    assert EventAreaParams(cost_scale=100.0).max_costs(np.array([1.0, 1.0])).tolist() == [1000.0, 1000.0]
    with pytest.raises(ValueError, match="cost_scale"):
        EventAreaParams(cost_scale=-1)
