"""The rig check on periodic scenes: a fan's blades give one coincidence peak per blade period, so the time
offset is ambiguous; the check reports the peak nearest 0, the period, and ``--auto`` must not apply it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.rigcheck import check_rig
from cvstereo.rigcheck.time_offset import equal_peaks
from tests.rigcheck.test_rigcheck import TIME_TOLERANCE_US, textured_patches, with_rig_errors

BLADE_PERIOD_US = 8_000


def periodic_fan(*, seconds=0.6, blades=8, blade_period_us=BLADE_PERIOD_US, points_per_blade=8, disparity=8.0,
                 time_offset_us=0, seed=0, step_us=50, jitter_us=150) -> Recording:
    """A textured fan rotating about the sensor's centre: ``blades`` identical sectors, one passing every
    ``blade_period_us``, so every pixel sees the same events once per blade period.

    Each blade carries ``points_per_blade`` points (random radius 12-46 px, angle, polarity); a point fires
    when it moves into another pixel. The left camera sees it ``disparity / 2`` px right of its position, the
    right one ``disparity / 2`` left and ``time_offset_us`` late (plus uniform jitter in each camera).
    """
    rng = np.random.default_rng(seed)
    r = np.tile(rng.uniform(12, 46, points_per_blade), blades)
    a = (rng.uniform(0, 2 * np.pi / blades, points_per_blade)[None, :]
         + 2 * np.pi / blades * np.arange(blades)[:, None]).ravel()
    pol = np.tile(rng.integers(0, 2, points_per_blade), blades)
    t = np.arange(0, int(seconds * 1e6), step_us)
    angle = a[:, None] + 2 * np.pi / (blades * blade_period_us) * t[None, :]
    cams = []
    for side, late in ((0.5, 0), (-0.5, time_offset_us)):
        x = np.floor(64 + r[:, None] * np.cos(angle) + side * disparity).astype(int)
        y = np.floor(64 + r[:, None] * np.sin(angle)).astype(int)
        pi, ti = np.nonzero((np.diff(x, axis=1) != 0) | (np.diff(y, axis=1) != 0))
        stamp = t[ti + 1] + rng.integers(0, jitter_us + 1, ti.size) + late
        keep = stamp >= 0
        ev = make_events(stamp[keep], x[pi, ti + 1][keep], y[pi, ti + 1][keep], pol[pi][keep])
        cams.append(ev[np.argsort(ev["t"], kind="stable")])
    return Recording(cams[0], cams[1], meta={"source": "periodic fan"})


@pytest.mark.parametrize(("swap", "true_us", "nearest_us", "other_us"), [
    (False, -3000, -3000, 5000),       # the true offset is the peak nearest 0
    (True, -3000, -3000, 5000),
    (False, 5000, -3000, 5000),        # it is not: only the ambiguity flag saves the user
])
def test_periodic_fan_time_offset_is_ambiguous_and_not_applied(swap, true_us, nearest_us, other_us):
    rec = periodic_fan(time_offset_us=true_us)
    report = check_rig(rec.swapped() if swap else rec)
    assert report.swap is swap
    assert abs(report.time_offset_us - nearest_us) <= TIME_TOLERANCE_US
    assert report.time_offset_ambiguous
    assert report.time_offset_period_us == pytest.approx(BLADE_PERIOD_US, rel=0.05)
    alternatives = np.array(report.time_offset_alternatives_us)
    assert np.min(np.abs(alternatives - other_us)) <= TIME_TOLERANCE_US
    # Every alternative lies a whole number of periods from the reported offset.
    periods = (alternatives - report.time_offset_us) / BLADE_PERIOD_US
    np.testing.assert_allclose(periods, np.round(periods), atol=0.1)
    assert not report.time_offset_applicable(min_confidence=0.0)
    assert report.match_kwargs(min_time_confidence=0.0)["time_offset_us"] == 0
    assert "ambiguous" in report.summary() and "periodic" in report.summary()
    data = report.to_dict()
    assert data["time_offset_ambiguous"] is True and data["time_offset_period_us"] > 0


def test_textured_patches_are_not_ambiguous_and_their_offset_applies():
    report = check_rig(with_rig_errors(textured_patches(seconds=0.6), time_us=2500))
    assert abs(report.time_offset_us - 2500) <= TIME_TOLERANCE_US
    assert not report.time_offset_ambiguous and report.time_offset_alternatives_us == ()
    assert math.isnan(report.time_offset_period_us) and report.to_dict()["time_offset_period_us"] is None
    assert report.time_offset_applicable()
    assert abs(report.match_kwargs()["time_offset_us"] - 2500) <= TIME_TOLERANCE_US
    assert "ambiguous" not in report.summary()


def _bump(n, at, height, sigma=1.5):
    return height * np.exp(-0.5 * ((np.arange(n) - at) / sigma) ** 2)


def test_equal_peaks_lists_peaks_within_the_tolerance_highest_first():
    v = _bump(101, 20, 1.0) + _bump(101, 60, 0.95) + _bump(101, 85, 0.5)
    var = np.zeros(101)
    assert equal_peaks(v, var, equal_share=0.1) == [20, 60]
    assert equal_peaks(v, var, equal_share=0.01) == [20]
    # Poisson uncertainty widens the tolerance: two standard deviations of the difference.
    assert equal_peaks(v, np.full(101, 0.2), equal_share=0.01) == [20, 60, 85]


def test_pairs_prefer_the_equal_peak_nearest_zero_lag():
    # The same periodic fan with a slightly stronger peak one period away: the search takes the nearer one.
    from cvstereo.rigcheck.time_offset import time_offset_pairs

    rec = periodic_fan(time_offset_us=-3000)
    # Extra coincidences at +5 ms only: events at random pixels and times (no period), each seen by the right
    # camera 8 px to the left and 5 ms late.
    rng = np.random.default_rng(1)
    n = rec.left.size // 4
    t = np.sort(rng.integers(0, 500_000, n))
    x, y, p = rng.integers(8, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    left = np.concatenate([rec.left, make_events(t, x, y, p)])
    right = np.concatenate([rec.right, make_events(t + 5000, x - 8, y, p)])
    left, right = (ev[np.argsort(ev["t"], kind="stable")] for ev in (left, right))
    far_higher = time_offset_pairs(left, right, row=0, disparity=8, resolution=(128, 128), max_lag_us=20_000,
                                   bin_us=200, equal_share=0.3)
    assert abs(far_higher.offset_us - (-3000)) <= TIME_TOLERANCE_US
    assert min(abs(a - 5000) for a in far_higher.alternatives_us) <= TIME_TOLERANCE_US
    strict = time_offset_pairs(left, right, row=0, disparity=8, resolution=(128, 128), max_lag_us=20_000,
                               bin_us=200, equal_share=0.0)
    assert abs(strict.offset_us - 5000) <= TIME_TOLERANCE_US       # the highest, when nothing counts as equal
