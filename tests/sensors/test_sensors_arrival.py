"""The wrap clock on hand-computed cases: which count a reading decides, when it leaves it open, what it learns."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.sensors.arrival import ARRIVAL_JITTER_US, Arrivals, Pieces, WrapClock

W = 1 << 16
E = 1_000_000  # host us at which the board's clock read 0


def fresh(readings):
    r = np.asarray(readings, np.float64)
    return Arrivals(r, r.copy(), np.ones(r.size, bool), np.ones(r.size, bool))


def late(after, readings):
    r = np.asarray(readings, np.float64)
    return Arrivals(r, np.full(r.size, float(after)), np.zeros(r.size, bool), np.zeros(r.size, bool))


@pytest.mark.parametrize("jitter", [-19_000, -5_000, 0, 7_000, 19_000])
@pytest.mark.parametrize("wraps", [0, 1, 3, 30])
def test_a_reading_within_the_jitter_decides_the_count(jitter, wraps):
    clock = WrapClock(W)
    clock.reset(E)
    t_true = 1_000 + wraps * W + 40_000  # decoded as 41,000 from its timestamp alone
    got = clock.decide(np.array([41_000.0]), fresh([E + t_true + jitter]))
    assert got.added.tolist() == [wraps] and got.decided.tolist() == [True]


def test_a_reading_far_outside_the_band_is_left_open():
    # Offsets seen within 1 ms; a reading 33 ms beyond them allows both the nearest count and the next one.
    clock = WrapClock(W)
    clock.reset(E)
    clock.observe(np.array([0.0]), fresh([E + 1_000]), None)
    got = clock.decide(np.array([0.0]), fresh([E + 100_000]))  # one wrap + 34.5 ms, or two wraps - 31 ms
    assert got.decided.tolist() == [False]
    assert (got.fewest[0], got.most[0]) == (1, 2) and got.added[0] == 1  # the fewest: a wrap too few can be made up


def test_a_late_reader_takes_the_fewest_possible_and_says_so():
    # The reader's last empty look was 4 ms before the event arrived, its read 90 ms after. With only the epoch
    # known a reading may lie 40 ms (+2 ms slack) either side of it: 5, 6 or 7 wraps (7: read 41 ms early).
    clock = WrapClock(W)
    clock.reset(E)
    t = 5 * W + 10_000.0
    got = clock.decide(np.array([10_000.0]), late(E + t - 4_000, [E + t + 90_000]))
    assert got.added.tolist() == [5] and not got.decided[0]
    assert (got.fewest[0], got.most[0]) == (5, 7)


def test_a_timely_later_event_bounds_the_wraps_of_late_ones():
    # A sender that stalled 70 ms: its first events come late (as if one wrap later), the last one is timely.
    clock = WrapClock(W)
    clock.reset(E)
    t = np.array([1_000.0, 2_000.0, 71_000.0])
    got = clock.decide(t, fresh([E + 71_000, E + 71_000, E + 71_000]))
    assert got.added.tolist() == [0, 0, 0] and got.decided.all()


def test_the_band_follows_a_drifting_offset_and_forgets_readings_beyond_the_spread():
    clock = WrapClock(W)
    clock.reset(E)
    clock.observe(np.array([0.0]), fresh([E + 30_000]), None)
    assert (clock.lo, clock.hi) == (E, E + 30_000)
    clock.observe(np.array([0.0]), fresh([E + 90_000]), None)  # the offset moved by 90 ms: the old edge goes
    assert clock.hi == E + 90_000 and clock.lo == pytest.approx(E + 90_000 - 2 * ARRIVAL_JITTER_US)


def test_undecided_readings_teach_the_clock_nothing():
    clock = WrapClock(W)
    clock.reset(E)
    got = clock.decide(np.array([0.0]), late(E - 10_000, [E + 200_000]))
    clock.observe(np.array([0.0]), Arrivals(np.array([E + 200_000.0]), np.array([E - 10_000.0]), np.array([True]),
                                            np.array([True])), got)
    assert (clock.lo, clock.hi) == (E, E) and clock.undecided


def test_pieces_give_each_event_its_arrival():
    # Two pieces: 8 bytes read fresh at 100,000 (last look empty at 99,000), then 6 bytes read late at 200,000.
    pieces = Pieces()
    pieces.add(8, 100_000, True, 99_000)
    pieces.add(14, 200_000, False, 99_000)
    arr = pieces.arrivals(np.array([0, 4, 8]), np.array([4, 8, 12]), byte_rate=400_000)
    # The link carries a byte in 2.5 us: the first event's bytes came at least 8 bytes (20 us) before the read.
    np.testing.assert_allclose(arr.hi, [100_000 - 20, 100_000 - 10, 200_000 - 15])
    np.testing.assert_allclose(arr.lo, [99_000, 99_000, 99_000])
    assert arr.seen.tolist() == [False, True, False]  # the last event of the fresh piece measures the offset
    pieces.drop(8)
    assert pieces.arrivals(np.array([0]), np.array([4]), 400_000).hi.tolist() == [200_000 - 15]
    pieces.add(20, None, True, None)
    assert pieces.arrivals(np.array([0]), np.array([4]), 400_000) is None


def test_a_burst_behind_a_stalled_sender_bounds_its_wraps_from_above_only():
    # The sender stalled and sent three events 0, 25 and 50 ms apart at once, 85 ms after the first. Read alone,
    # the first is decided a wrap later (85 - 65.5 ms lies within the jitter, 85 ms does not); read with the
    # others, it is seen to have waited 50 ms longer than the last (beyond the readings' spread), and so have
    # the bytes queued behind it: no count is decided, and the fewest is taken.
    clock = WrapClock(W)
    clock.reset(E)
    t = np.array([0.0, 25_000.0, 50_000.0])
    read = np.full(3, E + 85_000.0)
    alone = clock.decide(t[:1], Arrivals(read[:1], read[:1], np.ones(1, bool), np.ones(1, bool)))
    assert alone.added.tolist() == [1] and alone.decided.tolist() == [True]
    waited = np.array([True, False, False])
    got = clock.decide(t, Arrivals(read, read, waited, waited))
    assert got.added.tolist() == [0, 0, 0] and not got.decided.any()
