"""The online signal level and the relative thresholds built on it: causal, cut-independent, fast == reference."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut

from calibration_free import create_matcher
from cvstereo.evaluation.diagnostics import silence_warning
from cvstereo.matchers._shared.signal_level import SignalLevel, SignalLevelParams
from cvstereo.matchers.frame.matcher import FrameClusterMatcher
from cvstereo.model.matches import concat_matches
from tests._paths import DATA

REL = {"threshold_mode": "relative"}


def level(**kw):
    return SignalLevel(SignalLevelParams(**{**REL, **kw}), absolute=1.2, unit=0.1)


def test_threshold_of_a_window_comes_from_earlier_windows_only():
    lv = level(threshold_scale=0.5, level_warmup=3, level_floor=0)
    assert lv.thresholds(0).tolist() == [1.2, 1.2]  # nothing seen: the absolute threshold
    lv.add(0, 0, [1, 2, 3, 4, -5])  # |value| counts
    lv.add(0, 1, [10, 10])  # two values: camera 1 still warms up
    # 0.9 quantile of 1..5 by linear interpolation: 4 + 0.6 * 1 = 4.6
    assert lv.thresholds(1).tolist() == pytest.approx([2.3, 1.2])
    lv.add(1, 0, [100] * 5)  # window 1's own values do not move window 1's threshold
    assert lv.thresholds(1).tolist() == pytest.approx([2.3, 1.2])
    # window 2: sorted 1..5, 100 x 5; position 0.9 * 9 = 8.1 lies between two 100s
    assert lv.thresholds(2)[0] == pytest.approx(50.0)
    with pytest.raises(ValueError, match="window 0"):
        lv.add(0, 0, [1.0])


def test_history_keeps_the_last_windows_and_reaches_back_when_sparse():
    lv = level(threshold_scale=1.0, level_windows=4, level_warmup=10, level_floor=0, level_quantile=1.0)
    for k in range(8):  # window k holds 20 values k
        lv.thresholds(k)
        lv.add(k, 0, np.full(20, float(k)))
    assert lv.thresholds(8)[0] == 7.0  # the maximum of windows 4..7
    sparse = level(threshold_scale=1.0, level_windows=2, level_warmup=10, level_floor=0, level_quantile=0.01)
    for k in range(5):  # 2 values a window: 5 windows before 10 values
        assert sparse.thresholds(k)[0] == 1.2
        sparse.add(k, 0, [k + 1.0, k + 1.0])
    # 10 values from 5 windows though level_windows is 2: the minimum is window 0's
    assert sparse.thresholds(5)[0] == 1.0


def test_floor_and_absolute_mode():
    lv = level(threshold_scale=0.5, level_warmup=1, level_floor=3.0)  # floor 3 x unit 0.1
    lv.add(0, 0, [0.01])
    assert lv.thresholds(1)[0] == pytest.approx(0.3)
    absolute = SignalLevel(SignalLevelParams(), absolute=0.8, unit=0.1)
    absolute.add(0, 0, np.full(500, 9.0))
    assert absolute.thresholds(1).tolist() == [0.8, 0.8]


def test_values_in_chunks_give_the_thresholds_of_the_values_at_once(rng):
    whole, chunked = level(level_warmup=50), level(level_warmup=50)
    for k in range(6):
        v = rng.exponential(1.0, 300)
        np.testing.assert_array_equal(whole.thresholds(k), chunked.thresholds(k))
        whole.add(k, 1, v)
        for part in np.array_split(v[rng.permutation(v.size)], 7):
            chunked.add(k, 1, part)
    np.testing.assert_array_equal(whole.thresholds(6), chunked.thresholds(6))


def test_levels_side_by_side_are_the_levels_one_after_the_other(rng):
    # Both cameras' histories, parts (OFF and ON) and a camera still warming up: every level and part level equal to
    # the one-thread order's, and to numpy's quantile of the values.
    made = [SignalLevel(SignalLevelParams(**REL, level_warmup=400, level_windows=3), absolute=1.2, unit=0.1,
                        n_parts=2) for _ in range(2)]
    made[1].side_by_side = True
    seen = [[], []]
    for k in range(8):
        levels = [(lv.levels(k), lv.part_levels(k)) for lv in made]
        np.testing.assert_array_equal(levels[0][0], levels[1][0])
        np.testing.assert_array_equal(levels[0][1], levels[1][1])
        history = [np.concatenate(v[-6:]) if v else np.empty(0) for v in seen]  # 3 windows of 2 parts
        for cam in range(2):
            expected = np.quantile(history[cam], 0.9) if history[cam].size >= 400 else np.nan
            np.testing.assert_array_equal(levels[1][0][cam], expected)
        for cam, n in ((0, 300), (1, 40 * k)):  # camera 1 warms up from window 4 on
            for part in range(2):
                v = rng.exponential(1.0 + part, n)
                seen[cam].append(v)
                for lv in made:
                    lv.add(k, cam, v, part)
    assert made[1].diagnostics() == made[0].diagnostics()  # the windows closed on two threads: the same trace


def test_invalid_level_parameters_say_what_to_do():
    with pytest.raises(ValueError, match="'threshold_mode' must be one of absolute, relative, got 'auto'"):
        SignalLevelParams(threshold_mode="auto")
    with pytest.raises(ValueError, match=r"'level_quantile' must be in \(0, 1\]"):
        FrameClusterMatcher.make_params(level_quantile=1.5)


# -- the matchers in relative mode ------------------------------------------------------------------------
# Fast == reference in relative mode is part of the one parametrised test, tests/test_fast_vs_reference.py.


@pytest.fixture(scope="module")
def clip():

    from cvstereo.io.npz import read_recording_npz

    return read_recording_npz(DATA / "thesis_clip.npz")


@pytest.mark.parametrize("method", ["frame", "frame-area", "event-time", "event-area", "event-vector"])
def test_adaptive_defaults_do_not_depend_on_the_packets(clip, method):
    left, right = (e[e["t"] < 300_000] for e in (clip.left, clip.right))
    m = create_matcher(method, level_warmup=100)
    whole = concat_matches([m.feed(left, right), m.flush()])
    cuts = np.random.default_rng(3).integers(0, 300_000, 25)
    got = feed_cut(create_matcher(method, level_warmup=100), left, right, cuts)
    assert whole.size > 0
    np.testing.assert_array_equal(got, whole)
    assert m.diagnostics()["threshold_mode"] == "relative"


def test_silence_warning_says_why_and_what_to_try():
    quiet = {"param_set": "thesis", "diagnostics": {
        "windows_with_events": 245, "windows_with_matches": 0, "windows_with_candidates": 0,
        "value_name": "filtered value", "highest_value": 1.1, "its_threshold": 1.2}}
    text = silence_warning(quiet, n_matches=0)
    assert text.startswith("no window reached the threshold: highest filtered value 1.1 < 1.2")
    assert "--param-set adaptive" in text
    few = {"param_set": "adaptive", "diagnostics": {"windows_with_events": 1000, "windows_with_matches": 9,
                                                    "windows_with_candidates": 800}}
    assert "matches in only 9 of 1000 windows" in silence_warning(few, n_matches=40)
    enough = {"diagnostics": {"windows_with_events": 1000, "windows_with_matches": 10}}
    assert silence_warning(enough, n_matches=40) is None


def _cells(matches, anchor):
    """Per (window, camera, pixel) cell with matches: the median disparity."""
    t = matches["t"].astype(np.int64) - (1 if anchor == "window" else 0)  # a window's stamp is its end
    key = ((t // 40_000) * 2 + matches["camera"]) * 128 * 128 + matches["y"].astype(np.int64) * 128 + matches["x"]
    order = np.argsort(key, kind="stable")
    key, d = key[order], matches["disparity"][order]
    u, start = np.unique(key, return_index=True)
    return dict(zip(u.tolist(), (float(np.median(p)) for p in np.split(d, start[1:])), strict=True))


def _event_cells(rec, cameras):
    n = 0
    for cam in cameras:
        ev = (rec.left, rec.right)[cam]
        n += np.unique(((ev["t"].astype(np.int64) // 40_000) * 128 + ev["y"]) * 128 + ev["x"]).size
    return n


#: (method, stream) pairs that do not reach the bar yet (measured on this clip; see issue 12's closing note).
_SHORT: set[tuple[str, str]] = set()


@pytest.mark.parametrize("stream", ["twice", "every second"])
@pytest.mark.parametrize("method", ["frame", "frame-area", "event-time", "event-area", "event-vector"])
def test_duplicated_or_thinned_events_give_the_same_disparities(clip, method, stream, request):
    if (method, stream) in _SHORT:
        request.applymarker(pytest.mark.xfail(strict=True, reason="below the 95 % / 20 % bar on this clip"))
    from calibration_free import match
    from cvstereo.model.recording import Recording

    rec = clip.slice_time(0, 500_000)
    change = (lambda e: np.repeat(e, 2)) if stream == "twice" else (lambda e: e[::2])
    other = Recording(change(rec.left), change(rec.right), resolution=rec.resolution)
    a, b = match(rec, method=method), match(other, method=method)
    ca, cb = _cells(a.matches, a.meta["anchor"]), _cells(b.matches, b.meta["anchor"])
    both = sorted(set(ca) & set(cb))
    assert len(both) > 200
    agree = np.mean([abs(ca[k] - cb[k]) <= 1 for k in both])
    cameras = a.meta["anchor_cameras"]
    coverage_a = len(ca) / _event_cells(rec, cameras)
    coverage_b = len(cb) / _event_cells(other, cameras)
    assert agree >= 0.95 and 0.8 <= coverage_b / coverage_a <= 1.2, (agree, coverage_b / coverage_a)
