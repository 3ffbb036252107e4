"""The fused matcher: fast == reference on random streams and packet cuts, and what each part promises."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, moving_edges
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.matchers.fused._answers import median_of
from cvstereo.matchers.fused.matcher import FusedMatcher
from cvstereo.matchers.fused.params import FusedParams
from cvstereo.matchers.fused.reference import fused_reference
from cvstereo.matchers.registry import create_matcher
from cvstereo.model.events import make_events
from cvstereo.model.matches import validate_matches


def _events_of(parts) -> np.ndarray:
    """One camera's events from its (t, x, y, p) parts, in time order."""
    t, x, y, p = (np.concatenate(c) for c in zip(*parts, strict=True))
    order = np.argsort(t, kind="stable")
    return make_events(t[order], x[order], y[order], p[order])


def textured_pair(seed: int, *, windows: int = 4, shift: int = 5, size: tuple[int, int] = (40, 16), noise: int = 40,
                  jagged: bool = False):
    """Random vertical-ish texture sliding right, seen by the right camera ``shift`` px further left, with noise.

    ``jagged``: each row's edges are offset by their own 0..5 px, so that rows differ (a row offset between
    the cameras then matters). Returns left, right and the resolution.
    """
    rng = np.random.default_rng(seed)
    w, h = size
    edges = rng.integers(shift + 2, w - 6, 6)
    pols = rng.integers(0, 2, 6)
    row_offset = rng.integers(0, 6, h) if jagged else np.zeros(h, int)
    cams = [[], []]
    for k in range(windows * 8):  # 5 ms steps: each edge moves 1 px per step
        t0 = k * 5_000
        for e, p in zip(edges, pols, strict=True):
            ys = np.flatnonzero(rng.random(h) < 0.7)
            x = (e + k // 4 + row_offset[ys]) % (w - 1)
            t = t0 + rng.integers(0, 5_000, ys.size)
            cams[0].append((t, x, ys, np.full(ys.size, p)))
            xr = x - shift
            ok = xr >= 0
            cams[1].append((t[ok] + rng.integers(0, 300, np.count_nonzero(ok)), xr[ok], ys[ok],
                            np.full(np.count_nonzero(ok), p)))
    for cam in cams:
        cam.append((rng.integers(0, windows * 40_000, noise), rng.integers(0, w, noise), rng.integers(0, h, noise),
                    rng.integers(0, 2, noise)))
    return (*(_events_of(parts) for parts in cams), size)


PARAM_AXES = {
    "sgm_paths": [0, 2, 4], "lr_tolerance": [-1, 0, 1], "subpixel": [True, False], "temporal_weight": [0.0, 0.3],
    "support_radius": [0, 1, 2], "path_radius": [0, 1, 3], "fill_radius": [0, 2, 12], "row_tolerance": [0, 1],
    "min_neighbours": [1, 3], "max_uncertainty": [1.0, 0.5, 0.3], "fill_confirms": [True, False],
    "isolated_max_uncertainty": [0.0, 0.1, 0.3], "occlusion_margin": [-1, 0.0, 1.0, 2.5],
    "occlusion_support": [1, 2, 3], "border_rows": [-1, 0, 2], "segment_min_answers": [0, 8, 50],
    "max_disparity": [12, 20],
}


@settings(max_examples=12, deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1), n_cuts=st.integers(0, 25))
def test_fast_equals_reference_across_packet_cuts(data, seed, n_cuts):
    params = FusedParams(**{k: data.draw(st.sampled_from(v), label=k) for k, v in PARAM_AXES.items()})
    left, right, resolution = textured_pair(seed)
    expected, unc_expected = fused_reference(left, right, params, resolution=resolution, with_uncertainty=True)
    cuts = np.random.default_rng(seed).choice(np.concatenate([left["t"], right["t"]]), n_cuts)
    matcher = FusedMatcher(params, resolution=resolution)
    got = feed_cut(matcher, left, right, cuts)
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(matcher.take_uncertainty(), unc_expected)
    validate_matches(got)


def test_finds_the_shift_of_a_textured_pair():
    left, right, resolution = textured_pair(1, windows=6, noise=0)
    got = feed_cut(FusedMatcher(resolution=resolution), left, right, [])
    # Edges near the left border have no partner in the right camera; the rest must be found at 5 px.
    assert got.size > 100
    assert np.mean(np.abs(got["disparity"] - 5.0) <= 1.0) > 0.9


def test_moving_edges_are_matched_at_their_disparity():
    left, right = moving_edges(shift=6)
    got = feed_cut(FusedMatcher(resolution=(128, 128)), left, right, [])
    assert got.size > 0
    assert np.median(np.abs(got["disparity"] - 6.0)) <= 0.5


def test_uncertainty_threshold_keeps_exactly_the_matches_below_it():
    left, right, resolution = textured_pair(3, windows=6)
    full = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0), resolution=resolution)
    m_all = feed_cut(full, left, right, [])
    u = full.take_uncertainty()
    assert u.shape == m_all.shape and u.dtype == np.float32 and ((u >= 0) & (u <= 1)).all()
    assert full.take_uncertainty().size == 0  # taken once
    for limit in (0.5, 0.3):
        strict = FusedMatcher(FusedParams(max_uncertainty=limit, temporal_weight=0.0), resolution=resolution)
        np.testing.assert_array_equal(feed_cut(strict, left, right, []), m_all[u <= np.float32(limit)])


def test_left_right_failures_rank_behind_consistent_matches():
    left, right, resolution = textured_pair(4, windows=6)
    runs = {}
    for tol in (-1, 1):
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0, lr_tolerance=tol, fill_radius=0,
                                     occlusion_margin=-1, border_rows=-1, segment_min_answers=0),
                         resolution=resolution)
        runs[tol] = (feed_cut(m, left, right, []), m.take_uncertainty())
    # Same winners; the check only adds 0.5 to the uncertainty of the inconsistent ones, and some fail it.
    np.testing.assert_array_equal(runs[1][0], runs[-1][0])
    added = runs[1][1].astype(np.float64) - runs[-1][1]
    assert np.all(np.isclose(added, 0.0) | np.isclose(added, 0.5))
    assert 0 < np.count_nonzero(np.isclose(added, 0.5)) < added.size
    assert (runs[-1][1] <= 0.5).all()


def test_inconsistent_matches_take_the_median_of_consistent_neighbours():
    left, right, resolution = textured_pair(4, windows=6)
    m = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0, fill_radius=2, fill_confirms=False,
                                 border_rows=-1, segment_min_answers=0), resolution=resolution)
    got = feed_cut(m, left, right, [])
    u = m.take_uncertainty()
    ok = u <= 0.5
    filled = 0
    for i in np.flatnonzero(~ok):
        near = ok & (got["t"] == got["t"][i]) & (np.abs(got["x"].astype(int) - got["x"][i]) <= 2) & \
            (np.abs(got["y"].astype(int) - got["y"][i]) <= 2)
        if near.any():
            assert got["disparity"][i] == pytest.approx(np.median(got["disparity"][near]), abs=1e-5)
            filled += 1
    assert filled > 0


def test_a_failed_winner_that_agrees_with_its_fill_is_confirmed():
    left, right, resolution = textured_pair(4, windows=6)
    runs = {}
    for confirm in (False, True):
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0, fill_radius=2, fill_confirms=confirm,
                                     border_rows=-1, segment_min_answers=0), resolution=resolution)
        runs[confirm] = (feed_cut(m, left, right, []), m.take_uncertainty().astype(np.float64))
    (filled, u_filled), (confirmed, u_confirmed) = runs[False], runs[True]
    for key in ("t", "x", "y", "p"):
        np.testing.assert_array_equal(confirmed[key], filled[key])
    same = (u_confirmed == u_filled) & (confirmed["disparity"] == filled["disparity"])
    lifted = np.isclose(u_confirmed, u_filled - 0.5)
    assert np.all(same | lifted)
    assert lifted.any()
    # A confirmed winner failed the check (its penalty is gone) and lies within 1 px of the median that filled it.
    assert np.all(u_filled[lifted] > 0.5)
    assert np.all(np.abs(confirmed["disparity"][lifted] - filled["disparity"][lifted]) <= 1.0 + 1e-6)


def half_occlusion(seed: int, *, windows: int = 4, size: tuple[int, int] = (64, 12)):
    """A flickering background at disparity 2 behind a foreground bar at disparity 8 over left columns 24..47.

    Every scene point fires at its own random times, seen at the same instants by each camera that sees it: the
    right camera sees the bar over columns 16..39, which hides the background of left columns 18..23 (the left
    view's half-occlusion); the background behind the bar's right end shows in the right view only. Returns
    left, right and the resolution.
    """
    rng = np.random.default_rng(seed)
    w, h = size
    cams = [[], []]
    points = [(x, 8) for x in range(24, 48)] + [(x, 2) for x in range(w)]  # (left column, disparity)
    for x, d in points:
        seen = (d == 8 or not 24 <= x < 48, d == 8 or not 16 <= x - 2 < 40)  # by the left, by the right camera
        for y in range(h):
            n = windows * 4
            t = np.sort(rng.choice(windows * 40_000, n, replace=False))
            p = rng.integers(0, 2, n)
            for cam, xc in ((0, x), (1, x - d)):
                if seen[cam] and 0 <= xc < w:
                    cams[cam].append((t, np.full(n, xc), np.full(n, y), p))
    return (*(_events_of(parts) for parts in cams), size)


def test_occlusion_test_ranks_the_hidden_background_behind():
    left, right, resolution = half_occlusion(5)
    runs = {}
    for margin in (-1, 1.0):
        # Low penalties: the flicker's costs differ little between disparities, and the default p2 would carry
        # the background's disparity across the bar.
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, p1=0.5, p2=2.0, occlusion_margin=margin,
                                     segment_min_answers=0), resolution=resolution)
        runs[margin] = (feed_cut(m, left, right, []), m.take_uncertainty().astype(np.float64))
    (got, u_off), (got_on, u_on) = runs[-1], runs[1.0]
    np.testing.assert_array_equal(got_on, got)  # the test changes uncertainties only, and the prior not at all
    x, d = got["x"].astype(int), got["disparity"]
    truth = np.where((x >= 24) & (x < 48), 8.0, 2.0)
    right_answer = (np.abs(d - truth) <= 0.5) & (u_off <= 0.5)
    bar_seen = np.zeros(got.size, bool)  # a right answer of the bar in the same window and row
    for i in np.flatnonzero(right_answer & (x >= 24) & (x < 48)):
        bar_seen |= (got["t"] == got["t"][i]) & (got["y"] == got["y"][i])
    # By the geometry alone: a background answer of left columns 19..23 maps to right column 17..21, and the
    # bar's answers map to 16..39: at least 1 px left of it, so it is hidden ...
    hidden = right_answer & (x >= 19) & (x < 24) & bar_seen
    assert hidden.sum() > 20
    np.testing.assert_allclose(u_on[hidden], u_off[hidden] + 0.5)
    # ... and the right answers away from the band are not (the bar's answers spill up to 3 px over the band,
    # as semi-global matchers' foregrounds do, and may hide a few of the background answers left of it).
    seen = right_answer & ((x < 14) | (x >= 24))
    assert seen.sum() > 500
    np.testing.assert_array_equal(u_on[seen], u_off[seen])


@pytest.mark.parametrize(("margin", "support", "max_uncertainty"), [(0.0, 1, 1.0), (1.0, 2, 0.5), (2.5, 3, 0.7)])
def test_fast_equals_reference_with_hidden_answers(margin, support, max_uncertainty):
    # textured_pair has one disparity, so nothing there is hidden: the occlusion test's branch needs this scene.
    left, right, resolution = half_occlusion(7, windows=3)
    params = FusedParams(p1=0.5, p2=2.0, occlusion_margin=margin, occlusion_support=support,
                         max_uncertainty=max_uncertainty)
    expected, unc_expected = fused_reference(left, right, params, resolution=resolution, with_uncertainty=True)
    matcher = FusedMatcher(params, resolution=resolution)
    np.testing.assert_array_equal(feed_cut(matcher, left, right, [50_000]), expected)
    np.testing.assert_array_equal(matcher.take_uncertainty(), unc_expected)
    off = FusedMatcher(FusedParams(p1=0.5, p2=2.0, occlusion_margin=-1, max_uncertainty=1.0), resolution=resolution)
    feed_cut(off, left, right, [])
    assert np.count_nonzero(off.take_uncertainty() <= 0.5) > np.count_nonzero(unc_expected <= 0.5)  # some hidden


@pytest.mark.parametrize("support", [1, 2, 4])
def test_occlusion_test_penalises_exactly_the_crossed_answers(support):
    # Whole-pixel disparities (no sub-pixel) make the rule's comparison exact on the output's float32 values.
    left, right, resolution = half_occlusion(6)
    runs = {}
    for margin in (-1, 2.0):
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, p1=0.5, p2=2.0, subpixel=False, occlusion_margin=margin,
                                     occlusion_support=support, segment_min_answers=0), resolution=resolution)
        runs[margin] = (feed_cut(m, left, right, []), m.take_uncertainty().astype(np.float64))
    (got, u_off), (got_on, u_on) = runs[-1], runs[2.0]
    np.testing.assert_array_equal(got_on, got)
    # Every pair of answers of one window and row, both of uncertainty <= 0.5: j right of i crossing it.
    r = got["x"].astype(np.float64) - got["disparity"]
    ok = u_off <= 0.5
    same_row = (got["t"][:, None] == got["t"][None, :]) & (got["y"][:, None] == got["y"][None, :])
    crossed = same_row & ok[:, None] & ok[None, :] & (got["x"][None, :] > got["x"][:, None]) & \
        (r[None, :] <= r[:, None] - 2.0)
    hidden = crossed.sum(axis=1) >= support
    assert 0 < hidden.sum() < ok.sum()
    np.testing.assert_array_equal(u_on - u_off > 0.25, hidden)
    np.testing.assert_allclose(u_on, np.where(hidden, u_off + 0.5, u_off), atol=1e-6)  # float32 uncertainties


@pytest.mark.parametrize("rows", [0, 2])
def test_partner_test_penalises_exactly_the_answers_left_of_their_band(rows):
    # The texture is seen 9 px further left by the right camera: left columns 0..8 have no partner there.
    left, right, resolution = textured_pair(5, windows=6, shift=9)
    runs = {}
    for border in (-1, rows):
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0, occlusion_margin=-1, border_rows=border,
                                     segment_min_answers=0), resolution=resolution)
        runs[border] = (feed_cut(m, left, right, []), m.take_uncertainty().astype(np.float64))
    (got, u_off), (got_on, u_on) = runs[-1], runs[rows]
    np.testing.assert_array_equal(got_on, got)  # uncertainties only (no prior: temporal_weight 0)
    # The rule by hand: the median disparity of the band's answers of uncertainty <= 0.5 (at least 8 of them).
    ok = u_off <= 0.5
    outside = np.zeros(got.size, bool)
    for i in range(got.size):
        band = ok & (got["t"] == got["t"][i]) & (np.abs(got["y"].astype(int) - got["y"][i]) <= rows)
        if band.sum() >= 8:
            outside[i] = got["x"][i] < np.median(got["disparity"][band].astype(np.float64))
    outside &= ok
    assert 0 < outside.sum() and np.all(got["x"][outside] < 12)  # the strip, and nothing far from it
    np.testing.assert_allclose(u_on, np.where(outside, u_off + 0.5, u_off), atol=1e-6)  # float32 uncertainties
    # The strip's answers cannot be right (their partner is not in the right image): they rank last.
    assert np.mean(u_on[got["x"] < 9] > 0.5) > 0.95


def test_isolated_noise_gets_no_answer():
    # One event per pixel, far apart: no pixel has a neighbour that fired. The right camera's events lie rows
    # away, so no left event has a partner: every cost is flat, and the noise filter answers nowhere.
    t = np.arange(0, 40_000, 4_000)
    x = np.arange(2, 42, 4)
    ev = make_events(t, x, np.full(t.size, 5), np.ones(t.size, int))
    elsewhere = make_events(t, x, np.full(t.size, 10), np.ones(t.size, int))
    assert feed_cut(FusedMatcher(resolution=(48, 12)), ev, elsewhere, []).size == 0
    unfiltered = FusedParams(min_neighbours=1, max_uncertainty=1.0)  # every winner, ties included
    assert feed_cut(FusedMatcher(unfiltered, resolution=(48, 12)), ev, elsewhere, []).size > 0


def test_isolated_events_with_a_clear_partner_answer():
    # The same isolated events in both cameras: each has an exact partner at disparity 0, a clear match, which
    # answers unless isolated_max_uncertainty = 0 drops every isolated pixel.
    t = np.arange(0, 40_000, 4_000)
    x = np.arange(2, 42, 4)
    ev = make_events(t, x, np.full(t.size, 5), np.ones(t.size, int))
    assert feed_cut(FusedMatcher(FusedParams(isolated_max_uncertainty=0.0), resolution=(48, 12)), ev, ev, []).size == 0
    m = FusedMatcher(resolution=(48, 12))
    got = feed_cut(m, ev, ev, [])
    assert got.size > 0
    np.testing.assert_allclose(got["disparity"], 0.0, atol=0.5)
    assert np.all(m.take_uncertainty() < FusedParams().isolated_max_uncertainty)


def test_registered_and_window_anchored():
    m = create_matcher("fused", resolution=(64, 32))
    assert isinstance(m, FusedMatcher)
    meta = m.describe()
    assert meta["anchor"] == "window" and meta["window_us"] == 40_000 and meta["anchor_cameras"] == [0]


@pytest.mark.parametrize(("field", "value", "words"), [
    ("sgm_paths", 3, "sgm_paths"), ("p2", 0.1, "p1 <= p2"), ("max_uncertainty", 0.0, "max_uncertainty"),
    ("tau_us", 0, "tau_us"), ("row_tolerance", 5, "row_tolerance"), ("lr_tolerance", -2, "lr_tolerance"),
    ("occlusion_margin", -0.5, "occlusion_margin"), ("occlusion_margin", float("nan"), "occlusion_margin"),
    ("occlusion_support", 0, "occlusion_support"), ("occlusion_support", 1.5, "occlusion_support"),
])
def test_bad_parameters_say_which(field, value, words):
    with pytest.raises(ValueError, match=words):
        FusedParams(**{field: value})


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.floats(1e-6, 1e6), min_size=1, max_size=300), q=st.sampled_from([0.0, 50.0, 90.0, 100.0]),
       rounded=st.booleans(), small=st.booleans())
def test_kernel_percentile_is_numpys(values, q, rounded, small):
    """Bit for bit; ``small``: values up to 10, spread over the counting bins (else most share the last one)."""
    from cvstereo.matchers.fused._features import percentile

    v = np.round(np.array(values), 0 if rounded else 12)  # rounding makes ties, the partial sort's hard case
    if small:
        v = v / 1e5
    assert percentile(v.copy(), q) == np.percentile(v, q)


@pytest.mark.parametrize(("rows", "time_us"), [(3, 0), (-4, 1500)])
def test_match_applies_the_rig_correction(rows, time_us):
    from cvstereo.model.recording import Recording
    from cvstereo.run import match

    left, right, resolution = textured_pair(5, windows=6, noise=0, jagged=True)
    # The rig's error: the right camera's rows shifted by `rows`, its clock late by `time_us` (events shifted
    # off the sensor are lost, as they would be on the real rig).
    y = right["y"].astype(int) + rows
    on_sensor = (y >= 0) & (y < resolution[1])
    shifted = right[on_sensor].copy()
    shifted["y"] = y[on_sensor]
    shifted["t"] = shifted["t"] + time_us
    clean = Recording(left, right[on_sensor], resolution=resolution)
    erred = Recording(left, shifted, resolution=resolution)
    fixed = match(erred, method="fused", row_offset=-rows, time_offset_us=time_us)
    assert fixed.meta["rig_correction"]["row_offset"] == -rows
    assert fixed.meta["rig_correction"]["time_offset_us"] == time_us
    # Corrected, the matcher sees the clean stream: the same matches and uncertainties.
    plain = match(clean, method="fused", rig_check=False)
    np.testing.assert_array_equal(fixed.matches, plain.matches)
    np.testing.assert_array_equal(fixed.arrays["uncertainty"], plain.arrays["uncertainty"])
    assert np.mean(np.abs(plain.matches["disparity"] - 5.0) <= 1.0) > 0.95
    # Uncorrected, rows 3-4 apart are beyond the row tolerance of 1: a third or more of the answers are wrong (all
    # of them: the segment test would rank many of the wrong ones out of the default output).
    raw = match(erred, method="fused", rig_check=False, max_uncertainty=1.0)
    assert np.mean(np.abs(raw.matches["disparity"] - 5.0) <= 1.0) < 0.75


@settings(max_examples=60, deadline=None)
@given(values=st.lists(st.integers(0, 96).map(lambda v: v / 16.0), min_size=1, max_size=80),
       n_bins=st.sampled_from([1, 8, 40, 100]))
def test_kernel_median_is_the_sorted_middle(values, n_bins):
    """The fill's median (counted in bins, then a selection in one) gives the reference's (sorted middle, mean of
    two when even), with many ties, the middles in one bin or two, and values beyond the last bin (which share it).
    """
    vals = np.array(values + [np.nan] * 3)  # room beyond c, as in the kernel's buffer
    srt = np.sort(np.array(values))
    c = len(values)
    expected = srt[c // 2] if c % 2 else (srt[c // 2 - 1] + srt[c // 2]) / 2.0
    hist = np.zeros(n_bins, np.int64)
    assert median_of(vals, c, hist, np.empty_like(vals)) == expected
    assert not hist.any()  # left zero for the next pixel
