"""The frame-area SAD matcher (thesis 3.5.1, Algorithm 2) against independent expectations."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_slices
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration_free import match
from cvstereo.matchers.frame_area.matcher import FrameAreaMatcher, FrameAreaParams, scan_sad
from cvstereo.matchers.frame_area.reference import sad_volume, scan_disparity_map
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording

W = 40_000


def numpy_sad(ref, oth, y, x, x2, r=2):
    """The SAD of eq. 3.11, written out: blocks around (y, x) and (y, x2)."""
    return np.abs(ref[y - r:y + r + 1, x - r:x + r + 1].astype(np.float64)
                  - oth[y - r:y + r + 1, x2 - r:x2 + r + 1]).sum()


def algorithm2(ref, oth, *, threshold, max_disparity, reference_camera=1, r=2, uniqueness=0.0):
    """Algorithm 2 as the thesis writes it (with the running minimum, 0 a valid disparity), pure Python; with
    ``uniqueness`` > 0 a search whose winner has a rival (> 1 px away, SAD <= (1 + uniqueness) x its own) writes
    NaN into its block."""
    h, w = ref.shape
    disp = np.full((h, w), np.nan, np.float32)
    written = np.zeros((h, w), bool)  # an ambiguous search writes its block too, with NaN
    step = 1 if reference_camera == 1 else -1
    for y in range(r, h - r):
        for x in range(r, w - r):
            if abs(ref[y, x]) < threshold or written[y, x]:
                continue
            minimum, best, sads = np.inf, None, {}
            for d in range(max_disparity + 1):
                x2 = x + step * d
                if not r <= x2 < w - r:
                    continue
                sad = sads[d] = numpy_sad(ref, oth, y, x, x2, r)
                if sad < minimum:
                    minimum, best = sad, d
            if uniqueness and any(abs(d - best) > 1 and sad <= minimum * (1 + uniqueness) for d, sad in sads.items()):
                best = np.nan
            disp[y - r:y + r + 1, x - r:x + r + 1] = best
            written[y - r:y + r + 1, x - r:x + r + 1] = True
    return disp


@pytest.mark.parametrize("reference_camera", [0, 1])
def test_sad_volume_equals_numpy_sad(rng, reference_camera):
    ref, oth = rng.normal(size=(2, 14, 30)).astype(np.float32)
    vol = sad_volume(ref, oth, max_disparity=12, reference_camera=reference_camera)
    step = 1 if reference_camera == 1 else -1
    for d in range(13):
        for y in range(14):
            for x in range(30):
                x2 = x + step * d
                if 2 <= y < 12 and 2 <= x < 28 and 2 <= x2 < 28:
                    assert vol[d, y, x] == pytest.approx(numpy_sad(ref, oth, y, x, x2), rel=1e-12)
                else:
                    assert vol[d, y, x] == np.inf


@pytest.mark.parametrize("reference_camera", [0, 1])
@pytest.mark.parametrize("integer", [False, True])
@pytest.mark.parametrize("uniqueness", [0.0, 0.1])
def test_fast_scan_equals_algorithm2(rng, reference_camera, integer, uniqueness):
    for _ in range(3):
        ref, oth = rng.normal(size=(2, 20, 40)) * 3
        if integer:  # frames without the Gaussian: many exact ties
            ref, oth = np.round(ref), np.round(oth)
        kw = {"threshold": 2.0, "uniqueness": uniqueness}
        expected = algorithm2(ref, oth, max_disparity=15, reference_camera=reference_camera, **kw)
        fast = scan_sad(ref, oth, max_disparity=15, reference_camera=reference_camera, **kw)
        volume = scan_disparity_map(ref, sad_volume(ref, oth, max_disparity=15, reference_camera=reference_camera),
                                    **kw)
        assert np.isfinite(expected).sum() > (50 if not uniqueness else 10)
        np.testing.assert_array_equal(fast, expected)
        np.testing.assert_array_equal(volume, expected)


@pytest.mark.parametrize("k", [0, 3, 17])
@pytest.mark.parametrize("reference_camera", [0, 1])
def test_shifted_frame_gives_the_shift(rng, k, reference_camera):
    left = rng.normal(size=(30, 128)) * 3
    right = np.zeros_like(left)
    right[:, : 128 - k] = left[:, k:]  # x_right = x_left - k
    ref, oth = (right, left) if reference_camera == 1 else (left, right)
    disp = scan_sad(ref, oth, threshold=2.0, max_disparity=40, reference_camera=reference_camera)
    # Pixels whose true block lies inside both sensors get the shift.
    inside = np.zeros_like(disp, bool)
    if reference_camera == 1:
        inside[2:-2, 2:126 - k] = True  # candidate x + k stays inside
    else:
        inside[2:-2, k + 2:126] = True  # candidate x - k stays inside
    assert np.isfinite(disp[inside]).sum() > 200
    vals = disp[inside & np.isfinite(disp)]
    assert np.mean(vals == k) > 0.97  # random texture: a rare better match elsewhere is possible


def test_ties_go_to_the_smaller_disparity_and_zero_is_a_disparity():
    row = np.tile([0.0, 0.0, 5.0, 0.0], 10)  # period 4: disparities 0, 4, 8, ... all fit exactly
    frame = np.tile(row, (7, 1))
    disp = scan_sad(frame, frame, threshold=2.0, max_disparity=12)
    assert np.isfinite(disp).any()
    np.testing.assert_array_equal(disp[np.isfinite(disp)], 0)
    disp = scan_sad(frame, np.roll(frame, 1, axis=1), threshold=2.0, max_disparity=12)
    np.testing.assert_array_equal(disp[np.isfinite(disp)], 1)


def test_uniqueness_leaves_a_periodic_texture_unanswered_and_keeps_a_unique_one(rng):
    # Period 4: disparities 0, 4, 8 fit exactly: ambiguous at any uniqueness > 0, answered (0) without the check,
    # where disparity 4 still lies inside the sensor (x <= 33; the blocks written reach 2 px further).
    frame = np.tile(np.tile([0.0, 0.0, 5.0, 0.0], 10), (7, 1))
    assert np.isfinite(scan_sad(frame, frame, threshold=2.0, max_disparity=12)[:, :30]).any()
    assert not np.isfinite(scan_sad(frame, frame, threshold=2.0, max_disparity=12, uniqueness=0.01)[:, :30]).any()
    # Random texture shifted by 5: the true disparity's SAD is 0, any other > 0, so it stands at any ratio.
    left = rng.normal(size=(9, 60)) * 3
    right = np.zeros_like(left)
    right[:, :55] = left[:, 5:]
    disp = scan_sad(right, left, threshold=2.0, max_disparity=12, uniqueness=5.0)
    assert np.isfinite(disp[:, :40]).sum() > 100
    np.testing.assert_array_equal(disp[:, :40][np.isfinite(disp[:, :40])], 5)
    # A block of the other frame with no content is one SAD at every empty disparity: the first empty candidate
    # and the later ones are rivals alike (the sparse scan skips the later ones), so a lone pixel is ambiguous.
    lone = np.zeros((9, 30))
    lone[4, 10] = 9
    assert not np.isfinite(scan_sad(lone, np.zeros_like(lone), threshold=2.0, max_disparity=6,
                                    uniqueness=0.1)).any()


def test_winner_overwrites_the_neighbourhood_and_border_is_not_searched():
    ref = np.zeros((9, 12))
    ref[4, 1] = 9  # within 2 of the border: not searched
    ref[4, 5] = 9
    ref[6, 6] = 9  # inside the 5x5 block written for (4, 5): not searched again
    disp = scan_sad(ref, ref, threshold=2.0, max_disparity=3)
    expected = np.full((9, 12), np.nan, np.float32)
    expected[2:7, 3:8] = 0
    np.testing.assert_array_equal(disp, expected)


def stereo_blobs(rng, shift, *, t0=0, n=15, reps=3):
    xs, ys, ps = [], [], []
    for _ in range(n):
        yy, xx = np.mgrid[0:4, 0:5]
        x0, y0 = rng.integers(shift + 3, 120), rng.integers(3, 120)
        xs.append((xx + x0).ravel())
        ys.append((yy + y0).ravel())
        ps.append(np.full(xx.size, rng.integers(0, 2)))
    x, y, p = (np.repeat(np.concatenate(a), reps) for a in (xs, ys, ps))
    t = np.sort(rng.integers(t0, t0 + W, x.size))
    return make_events(t, x, y, p), make_events(t, x - shift, y, p)


@pytest.mark.parametrize("variant", ["gaussian", "no-gaussian"])
def test_matcher_window_anchoring(rng, variant):
    left, right = stereo_blobs(rng, 8, t0=W)
    m = FrameAreaMatcher.from_variant(variant)
    out = np.concatenate([m.feed(left, right), m.flush()])
    assert out.size > 0 and set(out["t"].tolist()) == {2 * W}
    assert set(out["camera"].tolist()) == {1}  # the reference: the right camera, as the thesis
    seen = set(zip(right["x"].tolist(), right["y"].tolist(), strict=True))
    assert set(zip(out["x"].tolist(), out["y"].tolist(), strict=True)) <= seen
    assert np.median(out["disparity"]) == 8
    assert m.describe()["anchor_cameras"] == [1]
    assert FrameAreaMatcher.variant_of(m.params) == variant


def test_variant_no_gaussian_sets_threshold_four():
    p = FrameAreaMatcher.make_params("no-gaussian")
    assert p.gaussian is False and p.threshold == 4.0
    assert FrameAreaMatcher.make_params().threshold == 2.0


@settings(deadline=None, max_examples=20)
@given(seed=st.integers(0, 2**32 - 1), cuts=st.lists(st.integers(1, 120_000), max_size=8, unique=True))
def test_result_does_not_depend_on_the_packets(seed, cuts):
    rng = np.random.default_rng(seed)
    parts = [stereo_blobs(rng, int(rng.integers(0, 20)), t0=k * W, n=5) for k in range(3)]
    left = np.concatenate([p[0] for p in parts])
    right = np.concatenate([p[1] for p in parts])
    whole = match(Recording(left, right), method="frame-area", param_set="thesis").matches
    np.testing.assert_array_equal(feed_slices(FrameAreaMatcher(), left, right, cuts), whole)


def test_invalid_parameters_say_what_to_do():
    with pytest.raises(ValueError, match="'block' must be a positive odd number of px"):
        FrameAreaParams(block=4)
    with pytest.raises(ValueError, match="reference_camera"):
        FrameAreaParams(reference_camera=3)
    with pytest.raises(ValueError, match="gaussian, no-gaussian"):
        FrameAreaMatcher.from_variant("median")


@pytest.mark.parametrize("units", ["own", "camera", "polarity"])
def test_value_units_reference_compares_sensors_of_different_thresholds(units):
    # The same edges, 6 px apart; the left camera fires four times fewer events per edge than the right (a higher
    # contrast threshold), so its frames are about four times weaker. Relative thresholds, short windows.
    from _event_scenes import feed_cut, moving_edges

    from cvstereo.matchers.frame_area.reference import frame_area_reference
    from cvstereo.matchers.sets import resolve

    left, _ = moving_edges(shift=6, events_per_pixel=2, seed=1)
    _, right = moving_edges(shift=6, events_per_pixel=8, seed=2)
    _, values = resolve("frame-area", None, "adaptive")
    assert values["value_units"] == "polarity"  # the adaptive set's choice
    params = FrameAreaMatcher.make_params("gaussian", **{**values, "window_us": 4_000, "level_window_us": 4_000,
                                                         "level_warmup": 20, "value_units": units})
    got = feed_cut(FrameAreaMatcher(params), left, right, range(0, 40_000, 3_000))
    np.testing.assert_array_equal(got, frame_area_reference(left, right, params))  # fast == reference
    late = got[got["t"] >= 10_000]  # after the levels' warm-up
    if units == "own":  # in each camera's own units no block of the weak frame passes the left-right check
        assert late.size == 0
    else:  # in the reference camera's units (one gain, or one per frame) the shift is found
        assert late.size > 1000 and np.mean(late["disparity"] == 6) >= 0.95
