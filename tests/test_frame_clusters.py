"""The frame-based cluster matcher (thesis 3.3) against independent expectations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration_free import match
from calibration_free.frame_clusters import (
    FrameClusterMatcher,
    FrameClusterParams,
    match_frame_pair,
    row_runs,
)
from cvstereo.events import make_events
from cvstereo.frames import gaussian_filter, signed_frame
from cvstereo.matches import MATCH_DTYPE
from cvstereo.recording import Recording

W = 40_000


def naive_runs(signs):
    """Row by row, pixel by pixel: (row, left, right, sign) of every maximal run of one nonzero sign."""
    out = []
    for y, row in enumerate(signs):
        x = 0
        while x < len(row):
            if row[x] == 0:
                x += 1
                continue
            start = x
            while x + 1 < len(row) and row[x + 1] == row[start]:
                x += 1
            out.append((y, start, x, int(row[start])))
            x += 1
    return out


def run_all(matcher, left, right):
    return np.concatenate([matcher.feed(left, right), matcher.flush()])


def blob_events(rng, n_blobs, *, shift=0, t0=0, size=128, reps=3, polarity=None):
    """Events of rectangular blobs (several events per pixel, so that the filtered frame passes 1.2).

    Returns the left events, and the right ones: the same blobs ``shift`` px further left.
    """
    xs, ys, ps = [], [], []
    for _ in range(n_blobs):
        w, h = rng.integers(2, 7), rng.integers(2, 6)
        x0, y0 = rng.integers(shift + 2, size - w - 2), rng.integers(2, size - h - 2)
        p = rng.integers(0, 2) if polarity is None else polarity
        yy, xx = np.mgrid[y0:y0 + h, x0:x0 + w]
        xs.append(xx.ravel())
        ys.append(yy.ravel())
        ps.append(np.full(xx.size, p))
    x = np.repeat(np.concatenate(xs), reps)
    y = np.repeat(np.concatenate(ys), reps)
    p = np.repeat(np.concatenate(ps), reps)
    t = np.sort(rng.integers(t0, t0 + W, x.size))
    return make_events(t, x, y, p), make_events(t, x - shift, y, p)


def test_row_runs_equal_a_pixel_loop(rng):
    for _ in range(20):
        signs = rng.choice([-1, 0, 0, 1], size=(9, 23)).astype(np.int8)
        r = row_runs(signs)
        assert list(zip(r.row.tolist(), r.left.tolist(), r.right.tolist(), r.sign.tolist(), strict=True)) == \
            naive_runs(signs)


@pytest.mark.parametrize("k", [0, 1, 7, 30])
def test_shifted_frame_gives_the_shift_for_every_cluster(rng, k):
    left = np.round(rng.normal(size=(40, 128)) * 2)
    left[:, 100:] = 0
    right = np.zeros_like(left)
    right[:, : 128 - k] = left[:, k:]  # x_right = x_left - k
    pairs = match_frame_pair(gaussian_filter(left), gaussian_filter(right))
    assert pairs.disparity.size > 20
    np.testing.assert_array_equal(pairs.disparity, k)


def row_frames(left_row, right_row):
    return np.array([left_row], float), np.array([right_row], float)


def test_unequal_counts_or_polarity_order_give_no_match():
    base = [0, 2, 2, 0, 0, -2, -2, 0, 0, 0, 0, 0]
    ok = match_frame_pair(*row_frames(np.roll(base, 2), base))
    assert ok.disparity.tolist() == [2.0, 2.0]
    extra = list(np.roll(base, 2))
    extra[10] = 2
    assert match_frame_pair(*row_frames(extra, base)).disparity.size == 0  # 3 clusters against 2
    swapped = [0, -2, -2, 0, 0, 2, 2, 0, 0, 0, 0, 0]
    assert match_frame_pair(*row_frames(np.roll(swapped, 2), base)).disparity.size == 0  # order OFF, ON
    # Adjacent runs of opposite sign are two clusters, not one.
    touching = [0, 2, -2, 0, 0, 0]
    assert match_frame_pair(*row_frames(touching, touching)).disparity.size == 2


@pytest.mark.parametrize(("wide", "narrow", "ok"), [(10, 7, True), (10, 6, False), (20, 14, True),
                                                    (20, 13, False), (5, 4, True), (4, 2, False)])
@pytest.mark.parametrize("left_is_wide", [True, False])
def test_width_rule_at_its_edge(wide, narrow, ok, left_is_wide):
    def row(width, start):
        r = np.zeros(64)
        r[start:start + width] = 3
        return r

    wl, wr = (wide, narrow) if left_is_wide else (narrow, wide)
    pairs = match_frame_pair(*row_frames(row(wl, 30), row(wr, 10)))
    assert (pairs.disparity.size == 1) is ok
    if ok:  # centres (30 + 30 + wl - 1) / 2 and (10 + 10 + wr - 1) / 2: half pixels happen
        assert pairs.disparity[0] == 20 + (wl - wr) / 2


def test_disparity_range():
    r = np.zeros(100)
    r[50:54] = 3
    assert match_frame_pair(*row_frames(r, np.roll(r, 5))).disparity.size == 0  # negative: impossible side
    assert match_frame_pair(*row_frames(r, np.roll(r, -40)), max_disparity=40).disparity.tolist() == [40.0]
    assert match_frame_pair(*row_frames(r, np.roll(r, -41)), max_disparity=40).disparity.size == 0


@pytest.mark.parametrize("variant", ["shared", "separate", "on", "off"])
@pytest.mark.parametrize("k", [0, 5, 23])
def test_matcher_on_shifted_events(rng, variant, k):
    left, right = blob_events(rng, 12, shift=k)
    out = run_all(FrameClusterMatcher.from_variant(variant), left, right)
    assert out.dtype == MATCH_DTYPE and out.size > 0
    np.testing.assert_array_equal(out["disparity"], k)
    if variant in ("on", "off"):
        assert set(out["p"].tolist()) == {1 if variant == "on" else 0}


def test_window_anchoring_at_pixels_that_saw_events(rng):
    # Events in the second window only, every other pixel of the blobs: the Gaussian fills the gaps, so the
    # clusters are wider than the set of pixels with events; only the latter may carry results.
    left, right = blob_events(rng, 10, shift=9, t0=W, reps=4)
    keep = (left["x"] % 2) == 0
    left, right = left[keep], right[keep]
    for camera in (0, 1):
        out = run_all(FrameClusterMatcher(FrameClusterParams(anchor_camera=camera)), left, right)
        assert out.size > 0 and set(out["t"].tolist()) == {2 * W}
        assert set(out["camera"].tolist()) == {camera}
        anchor = left if camera == 0 else right
        seen = set(zip(anchor["x"].tolist(), anchor["y"].tolist(), strict=True))
        assert set(zip(out["x"].tolist(), out["y"].tolist(), strict=True)) <= seen
        np.testing.assert_array_equal(out["disparity"], 9)
    assert FrameClusterMatcher().describe()["anchor"] == "window"
    assert FrameClusterMatcher().describe()["window_us"] == W


def test_separate_matches_polarities_on_their_own():
    # Row 20: an ON and an OFF blob in the left camera; the right camera has the ON blob only (shifted 6 px).
    def blob(x0, p, reps=5):
        yy, xx = np.mgrid[18:23, x0:x0 + 4]
        return np.repeat(xx.ravel(), reps), np.repeat(yy.ravel(), reps), p

    parts_l = [blob(40, 1), blob(60, 0)]
    parts_r = [blob(34, 1)]

    def events(parts):
        x = np.concatenate([p[0] for p in parts])
        y = np.concatenate([p[1] for p in parts])
        pol = np.concatenate([np.full(p[0].size, p[2]) for p in parts])
        return make_events(np.zeros(x.size, int), x, y, pol)

    left, right = events(parts_l), events(parts_r)
    assert run_all(FrameClusterMatcher.from_variant("shared"), left, right).size == 0
    out = run_all(FrameClusterMatcher.from_variant("separate"), left, right)
    assert out.size > 0 and set(out["p"].tolist()) == {1}
    np.testing.assert_array_equal(out["disparity"], 6)


def test_stacked_matcher_equals_frame_by_frame_reference(rng):
    for polarity in ("shared", "separate"):
        left, right = blob_events(rng, 25, shift=4)
        right = right[rng.random(right.size) < 0.8]  # break some rows
        m = FrameClusterMatcher(FrameClusterParams(polarity=polarity))
        out = run_all(m, left, right)
        expected = set()
        signs = [(1, -1)] if polarity == "shared" else [(1,), (-1,)]
        for s in signs:
            fl, fr = (gaussian_filter(signed_frame(e, signs=s)) for e in (left, right))
            pairs = match_frame_pair(fl, fr)
            seen = signed_frame(left[np.isin(left["p"] * 2 - 1, s)], signs=(1, -1)) != 0
            for y, a, b, sign, d in zip(*pairs, strict=True):
                expected |= {(x, y, int(sign > 0), d) for x in range(a, b + 1) if seen[y, x]}
        got = set(zip(out["x"].tolist(), out["y"].tolist(), out["p"].tolist(), out["disparity"].tolist(),
                      strict=True))
        assert expected and got == expected and len(got) == out.size


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), cuts=st.lists(st.integers(1, 160_000), max_size=8, unique=True),
       variant=st.sampled_from(["shared", "separate"]))
def test_result_does_not_depend_on_the_packets(seed, cuts, variant):
    rng = np.random.default_rng(seed)
    parts = [blob_events(rng, 6, shift=int(rng.integers(0, 20)), t0=k * W) for k in range(4)]
    left = np.concatenate([p[0] for p in parts])
    right = np.concatenate([p[1] for p in parts])
    whole = run_all(FrameClusterMatcher.from_variant(variant), left, right)
    m = FrameClusterMatcher.from_variant(variant)
    out, start = [], 0
    for stop in sorted(cuts):
        out.append(m.feed(left[(left["t"] >= start) & (left["t"] < stop)],
                          right[(right["t"] >= start) & (right["t"] < stop)], until=stop))
        start = stop
    out.append(m.feed(left[left["t"] >= start], right[right["t"] >= start]))
    out.append(m.flush())
    np.testing.assert_array_equal(np.concatenate(out), whole)


def test_match_runs_the_stream(rng):
    left, right = blob_events(rng, 8, shift=11)
    result = match(Recording(left, right), method="frame", variant="off", packet_us=7_000)
    assert result.meta["method"] == "frame" and result.meta["variant"] == "off"
    assert result.meta["params"]["polarity"] == "off" and result.meta["anchor"] == "window"
    np.testing.assert_array_equal(result.matches, run_all(FrameClusterMatcher.from_variant("off"), left, right))


def test_invalid_parameters_say_what_to_do():
    with pytest.raises(ValueError, match="width_tolerance"):
        FrameClusterParams(width_tolerance=-0.1)
    with pytest.raises(ValueError, match="anchor_camera"):
        FrameClusterParams(anchor_camera=2)
    with pytest.raises(ValueError, match="shared, separate, on, off"):
        FrameClusterMatcher.from_variant("both")


def truth_at_matches(rec: Recording, matches: np.ndarray, window_us: int = W) -> np.ndarray:
    """Per match: mean true disparity of the anchor camera's events at its pixel within its window (NaN: none)."""
    out = np.full(matches.size, np.nan)
    for cam in (0, 1):
        sel = np.flatnonzero(matches["camera"] == cam)
        ev, truth = rec.events(cam), rec.truth(cam)
        ok = ~np.isnan(truth)
        ev, truth = ev[ok], truth[ok]
        # Group the events by (window, y, x); a match at window end t looks up window t // W - 1.
        ev_key = ((ev["t"] // window_us) * 128 + ev["y"]) * 128 + ev["x"]
        keys, inverse = np.unique(ev_key, return_inverse=True)
        means = np.bincount(inverse, weights=truth) / np.bincount(inverse)
        m = matches[sel]
        m_key = ((m["t"] // window_us - 1) * 128 + m["y"]) * 128 + m["x"]
        pos = np.clip(np.searchsorted(keys, m_key), 0, keys.size - 1)
        found = keys[pos] == m_key
        out[sel[found]] = means[pos[found]]
    return out


@pytest.mark.slow
def test_mean_within_one_pixel_of_the_truth_on_a_one_arm_clip():
    simulate = pytest.importorskip("cvstereo.simulate")
    if not hasattr(simulate, "cached_preset"):
        pytest.skip("the simulator has no cached_preset")
    from cvstereo.io.npz import read_recording_npz

    rec = read_recording_npz(simulate.cached_preset("1arm-50cm", seconds=2))
    result = match(rec, method="frame")
    truth = truth_at_matches(rec, result.matches)
    known = ~np.isnan(truth)
    assert result.matches.size > 100 and known.mean() > 0.9
    assert abs(result.disparity[known].mean() - truth[known].mean()) < 1.0
