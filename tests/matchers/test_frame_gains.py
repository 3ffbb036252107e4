"""The frames' gains between the cameras (value_units of the area matchers): per frame, causal, with a fallback."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.matchers._shared.frame_gains import FrameGains, threshold_gains
from cvstereo.matchers._shared.signal_level import SignalLevel, SignalLevelParams


class _Gains:
    """A FrameGains and the signal level it reads (split by frame where the gains estimate), as a matcher holds."""

    def __init__(self, params, *, n_frames, unit, units):
        self.frame_gains = FrameGains(params, n_frames=n_frames, unit=unit, units=units)
        self.level = SignalLevel(params, absolute=1.0, unit=unit, n_parts=self.frame_gains.parts)
        self.estimates = self.frame_gains.estimates

    def add(self, k, cam, values, slots):
        self.frame_gains.add(self.level, k, cam, np.asarray(values, np.float64), np.asarray(slots))

    def gains(self, k, thresholds):
        return self.frame_gains.gains(k, thresholds, self.level)


def test_gains_are_the_ratio_of_each_frames_levels_once_warm():
    params = SignalLevelParams(level_warmup=10, level_quantile=0.5, threshold_scale=1.0)
    gains = _Gains(params, n_frames=2, unit=0.1, units="polarity")
    thresholds = np.array([2.0, 1.0])
    # Nothing seen: the thresholds' ratio for every frame.
    np.testing.assert_allclose(gains.gains(0, thresholds), [[2.0, 2.0], [0.5, 0.5]])
    rng = np.random.default_rng(0)
    left_off, left_on = rng.uniform(0, 2, 200), rng.uniform(0, 8, 200)      # medians ~1 and ~4
    right_off, right_on = rng.uniform(0, 6, 200), rng.uniform(0, 2, 200)    # medians ~3 and ~1
    gains.add(0, 0, np.r_[left_off, left_on], np.r_[np.zeros(200, int), np.ones(200, int)])
    gains.add(0, 1, np.r_[right_on, right_off], np.r_[np.ones(200, int), np.zeros(200, int)])
    # Window 0 is still open for window 0 itself (causal): the fallback; from window 1 on, the frames' own levels.
    np.testing.assert_allclose(gains.gains(0, thresholds), [[2.0, 2.0], [0.5, 0.5]])
    got = gains.gains(1, thresholds)
    off = np.median(left_off) / np.median(right_off)
    on = np.median(left_on) / np.median(right_on)
    np.testing.assert_allclose(got, [[off, on], [1 / off, 1 / on]])
    assert got[0, 0] < 1 < got[0, 1]  # the two polarities' ratios on opposite sides of 1


def test_a_frame_still_warming_up_keeps_the_fallback_and_nan_values_are_left_out():
    gains = _Gains(SignalLevelParams(level_warmup=10, level_quantile=0.5, threshold_scale=1.0), n_frames=2,
                   unit=0.1, units="polarity")
    gains.add(0, 0, np.r_[np.full(20, 1.0), np.full(5, 3.0), np.nan], np.r_[np.zeros(20, int), np.ones(6, int)])
    gains.add(0, 1, np.r_[np.full(20, 4.0), np.full(5, 3.0)], np.r_[np.zeros(20, int), np.ones(5, int)])
    np.testing.assert_allclose(gains.gains(1, [3.0, 1.0]), [[0.25, 3.0], [4.0, 1 / 3]])


def test_threshold_gains():
    np.testing.assert_allclose(threshold_gains([0.5, 2.0]), [0.25, 4.0])
    np.testing.assert_array_equal(threshold_gains([0.0, 2.0]), [1.0, 1.0])


def test_levels_below_the_floor_count_as_the_floor():
    # The right camera's ON frame holds only decayed values far below one isolated event's: its threshold would be
    # the floor (level_floor * unit = 1), so the ON gain is 3 / 1, not 3 / 1e-5.
    params = SignalLevelParams(level_warmup=10, level_quantile=0.5, level_floor=1.0, threshold_scale=1.0)
    gains = _Gains(params, n_frames=2, unit=1.0, units="polarity")
    gains.add(0, 0, np.r_[np.full(20, 2.0), np.full(20, 3.0)], np.r_[np.zeros(20, int), np.ones(20, int)])
    gains.add(0, 1, np.r_[np.full(20, 4.0), np.full(20, 1e-5)], np.r_[np.zeros(20, int), np.ones(20, int)])
    np.testing.assert_allclose(gains.gains(1, [2.0, 1.0]), [[0.5, 3.0], [2.0, 1 / 3]])
    # With a threshold scale the floor binds from level_floor * unit / scale on: both at the floor give 1.
    gains = _Gains(SignalLevelParams(level_warmup=10, level_quantile=0.5, level_floor=1.0, threshold_scale=0.25),
                   n_frames=1, unit=1.0, units="polarity")
    gains.add(0, 0, np.full(20, 2.0), np.zeros(20, int))
    gains.add(0, 1, np.full(20, 3.0), np.zeros(20, int))
    np.testing.assert_allclose(gains.gains(1, [2.0, 1.0]), [[1.0], [1.0]])


def test_one_gain_per_camera_is_the_thresholds_ratio_whatever_the_frames_hold():
    gains = _Gains(SignalLevelParams(level_warmup=1), n_frames=2, unit=1.0, units="camera")
    gains.add(0, 0, np.full(20, 9.0), np.zeros(20, int))
    np.testing.assert_allclose(gains.gains(1, [0.5, 2.0]), [[0.25, 0.25], [4.0, 4.0]])


def test_own_units_are_all_one_and_unknown_units_are_refused():
    gains = _Gains(SignalLevelParams(), n_frames=2, unit=1.0, units="own")
    assert not gains.estimates
    np.testing.assert_array_equal(gains.gains(3, [0.5, 2.0]), np.ones((2, 2)))
    with pytest.raises(ValueError, match="own, camera, polarity"):
        FrameGains(SignalLevelParams(), n_frames=1, unit=1.0, units="frame")


def test_the_parts_share_the_cameras_windows_and_leave_its_thresholds_as_they_are():
    """Split by frame, a camera's level is the same quantile of the same windows (bit for bit); each part's level
    is the quantile of that part's values in those windows, the windows a level without parts would keep."""
    params = SignalLevelParams(threshold_mode="relative", level_windows=3, level_warmup=5, threshold_scale=0.5)
    whole = SignalLevel(params, absolute=1.0, unit=0.1)
    split = SignalLevel(params, absolute=1.0, unit=0.1, n_parts=2)
    rng = np.random.default_rng(3)
    kept = []  # per window: the camera's (values, slots)
    for k in range(12):
        if k % 4 != 3:  # some windows hold nothing of camera 0 (they do not count among its 3)
            values, slots = rng.exponential(1 + k % 3, 40), rng.integers(0, 2, 40)
            whole.add(k, 0, values)
            split.add(k, 0, values[slots == 0], part=0)
            split.add(k, 0, values[slots == 1], part=1)
            kept.append((values, slots))
        assert whole.thresholds(k + 1).tobytes() == split.thresholds(k + 1).tobytes()
        last = kept[-3:]
        for part in (0, 1):
            expected = np.quantile(np.concatenate([v[s == part] for v, s in last]), 0.9)
            assert split.part_levels(k + 1)[0, part] == expected
        assert np.isnan(split.part_levels(k + 1)[1]).all()  # camera 1 saw nothing: warming up
