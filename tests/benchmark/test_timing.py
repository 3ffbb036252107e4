"""cvstereo.benchmark.timing: repeat until two runs agree within 10 %, with a fake clock and a fake load (no real
timing)."""

from __future__ import annotations

import math

import pytest

from cvstereo.benchmark.timing import Agreement, measure


class FakeClock:
    """A clock that advances by the next scripted duration on every second reading (end of a run)."""

    def __init__(self, durations):
        self.durations = list(durations)
        self.now = 100.0
        self.readings = 0

    def __call__(self):
        if self.readings % 2:
            self.now += self.durations.pop(0)
        self.readings += 1
        return self.now


def loads(*values):
    it = iter(values)
    return lambda: next(it)


def test_first_agreeing_pair_gives_its_faster_run():
    # 2.0 and 1.0 are 100 % apart; 1.08 is within 10 % of 1.0 (not of 2.0): the figure is 1.0, after 3 runs.
    clock = FakeClock([2.0, 1.0, 1.08, 5.0])
    t = measure(lambda: None, clock=clock, load=loads(0.5, 0.6, 0.7, 0.9))
    assert t.agreed and t.runs == 3
    assert t.seconds == pytest.approx(1.0)
    assert t.all_seconds == pytest.approx((2.0, 1.0, 1.08))
    # Load before the first run and after the last.
    assert (t.load_before, t.load_after) == (0.5, 0.9)
    assert clock.durations == [5.0]  # the fourth run never happened


def test_pair_need_not_be_consecutive_and_boundary_counts_as_agreeing():
    # 1.0, 3.0, then 1.1 = exactly 10 % slower than 1.0: agrees with the first run.
    own = iter([1.0, 3.0, 1.1])
    t = measure(lambda: next(own), load=lambda: 0.0)
    assert t.agreed and t.runs == 3 and t.seconds == pytest.approx(1.0)


def test_never_agreeing_stops_at_the_cap_and_reports_the_fastest_flagged():
    durations = [1.0, 2.0, 4.0, 8.0, 0.5, 16.0, 32.0]
    clock = FakeClock(durations)
    t = measure(lambda: None, clock=clock, max_runs=6, load=lambda: 2.0)
    assert not t.agreed and t.runs == 6
    assert t.seconds == pytest.approx(0.5)
    assert clock.durations == [32.0]
    assert "no two within 10 %" in t.note() and "6 runs" in t.note()


def test_run_reporting_its_own_duration_overrides_the_clock():
    own = iter([0.30, 0.31])
    t = measure(lambda: next(own), clock=FakeClock([9.0, 9.0]), load=lambda: 0.0)
    assert t.agreed and t.runs == 2 and t.seconds == pytest.approx(0.30)


def test_interleaved_agreements_and_bad_input():
    a, b = Agreement(load=lambda: 1.0), Agreement(load=lambda: 1.0)
    for x, y in [(1.0, 3.0), (1.5, 2.0), (1.05, 2.1)]:
        if not a.done:
            a.add(x)
        if not b.done:
            b.add(y)
    assert a.result().seconds == pytest.approx(1.0) and a.result().runs == 3
    assert b.result().seconds == pytest.approx(2.0) and b.result().runs == 3
    assert math.isnan(Agreement(load=lambda: 1.0).load_after)
    with pytest.raises(ValueError, match="no run was timed"):
        Agreement().result()
    with pytest.raises(ValueError, match="max_runs must be at least 2"):
        Agreement(max_runs=1)
    with pytest.raises(ValueError, match=">= 0"):
        Agreement(load=lambda: 0.0).add(float("nan"))
