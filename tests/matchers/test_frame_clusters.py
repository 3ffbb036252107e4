"""The frame-based cluster matcher (thesis 3.3) against independent expectations."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_slices
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration_free import match
from cvstereo.frames.accumulate import gaussian_filter
from cvstereo.matchers.frame.matcher import FrameClusterMatcher, FrameClusterParams
from cvstereo.matchers.frame.reference import match_frame_pair, row_runs
from cvstereo.model.events import make_events
from cvstereo.model.matches import MATCH_DTYPE
from cvstereo.model.recording import Recording

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


def frame_events(frame):
    """Events whose signed frame is ``frame`` (whole numbers): |v| events of the sign of v at each pixel, t = 0."""
    f = np.asarray(frame).astype(int)
    ys, xs = np.nonzero(f)
    n = np.abs(f[ys, xs])
    return make_events(np.zeros(n.sum(), int), np.repeat(xs, n), np.repeat(ys, n),
                       np.repeat((f[ys, xs] > 0).astype(int), n))


#: The two implementations of steps 3-6: the readable numpy one, and the matcher's numba kernel.
IMPLEMENTATIONS = ["numpy", "matcher"]


def cluster_disparities(impl, left, right, **params):
    """Disparity of each matched cluster pair, in row-major order, from unfiltered frames of whole numbers.

    ``numpy``: :func:`match_frame_pair` on the frames. ``matcher``: the frames as events through
    :class:`FrameClusterMatcher` without the Gaussian; every pixel of a cluster then holds events, so the
    matcher's one output per cluster pixel is grouped back into clusters (runs of x in a row, one polarity).
    """
    if impl == "numpy":
        return match_frame_pair(left, right, **params).disparity.tolist()
    h, w = left.shape
    out = run_all(FrameClusterMatcher(FrameClusterParams(gaussian=False, **params), resolution=(w, h)),
                  frame_events(left), frame_events(right))
    y, x, p = (out[k].astype(int) for k in ("y", "x", "p"))
    first = np.ones(out.size, bool)
    first[1:] = (y[1:] != y[:-1]) | (x[1:] != x[:-1] + 1) | (p[1:] != p[:-1])
    return out["disparity"][first].tolist()


@pytest.mark.parametrize("k", [0, 1, 7, 30])
def test_shifted_frame_gives_the_shift_for_every_cluster(rng, k):
    left = np.round(rng.normal(size=(40, 128)) * 2)
    left[:, 100:] = 0
    right = np.zeros_like(left)
    right[:, : 128 - k] = left[:, k:]  # x_right = x_left - k
    pairs = match_frame_pair(gaussian_filter(left), gaussian_filter(right))
    assert pairs.disparity.size > 20
    np.testing.assert_array_equal(pairs.disparity, k)
    # The matcher (Gaussian on) on events that make these frames: every pixel it reports says k.
    out = run_all(FrameClusterMatcher(resolution=(128, 40)), frame_events(left), frame_events(right))
    assert out.size > 40
    np.testing.assert_array_equal(out["disparity"], k)


def row_frames(left_row, right_row):
    return np.array([left_row], float), np.array([right_row], float)


@pytest.mark.parametrize("impl", IMPLEMENTATIONS)
def test_unequal_counts_or_polarity_order_give_no_match(impl):
    base = [0, 2, 2, 0, 0, -2, -2, 0, 0, 0, 0, 0]
    assert cluster_disparities(impl, *row_frames(np.roll(base, 2), base)) == [2.0, 2.0]
    extra = list(np.roll(base, 2))
    extra[10] = 2
    assert cluster_disparities(impl, *row_frames(extra, base)) == []  # 3 clusters against 2
    swapped = [0, -2, -2, 0, 0, 2, 2, 0, 0, 0, 0, 0]
    assert cluster_disparities(impl, *row_frames(np.roll(swapped, 2), base)) == []  # order OFF, ON
    # Adjacent runs of opposite sign are two clusters, not one.
    touching = [0, 2, -2, 0, 0, 0]
    assert cluster_disparities(impl, *row_frames(touching, touching)) == [0.0, 0.0]
    # Rows are matched on their own: a broken row does not stop the others.
    two_rows = np.array([np.roll(base, 2), extra], float), np.array([base, base], float)
    assert cluster_disparities(impl, *two_rows) == [2.0, 2.0]


@pytest.mark.parametrize(("wide", "narrow", "tolerance", "ok"), [
    (10, 7, 0.3, True), (10, 6, 0.3, False), (20, 14, 0.3, True), (20, 13, 0.3, False), (5, 4, 0.3, True),
    (4, 2, 0.3, False),
    (90, 27, 0.7, True), (90, 26, 0.7, False),  # 0.7 * 90 rounds to 62.99999999999999 in floating point
])
@pytest.mark.parametrize("left_is_wide", [True, False])
@pytest.mark.parametrize("impl", IMPLEMENTATIONS)
def test_width_rule_at_its_edge(wide, narrow, tolerance, ok, left_is_wide, impl):
    def row(width, start):
        r = np.zeros(256)
        r[start:start + width] = 3
        return r

    wl, wr = (wide, narrow) if left_is_wide else (narrow, wide)
    found = cluster_disparities(impl, *row_frames(row(wl, 130), row(wr, 10)), width_tolerance=tolerance,
                                max_disparity=200)
    # centres (130 + 130 + wl - 1) / 2 and (10 + 10 + wr - 1) / 2: half pixels happen
    assert found == ([120 + (wl - wr) / 2] if ok else [])


@pytest.mark.parametrize("impl", IMPLEMENTATIONS)
def test_clusters_at_the_sensor_edges(impl):
    left = np.zeros(64)
    left[2:5], left[60:] = -2, 2   # the ON cluster ends at x = 63
    right = np.zeros(64)
    right[:3], right[55:59] = -2, 2  # the OFF cluster starts at x = 0
    assert cluster_disparities(impl, *row_frames(left, right)) == [2.0, 5.0]


@pytest.mark.parametrize("impl", IMPLEMENTATIONS)
def test_disparity_range(impl):
    r = np.zeros(100)
    r[50:54] = 3
    assert cluster_disparities(impl, *row_frames(r, np.roll(r, 5))) == []  # negative: impossible side
    assert cluster_disparities(impl, *row_frames(r, np.roll(r, -40)), max_disparity=40) == [40.0]
    assert cluster_disparities(impl, *row_frames(r, np.roll(r, -41)), max_disparity=40) == []
    assert cluster_disparities(impl, *row_frames(r, r), max_disparity=0) == [0.0]


@pytest.mark.parametrize("impl", IMPLEMENTATIONS)
def test_threshold_on_the_magnitude_at_its_edge(impl):
    # |value| >= threshold is kept, for ON and OFF alike; just below is not.
    row = np.zeros(40)
    row[10:13], row[20:22] = 3, -3
    assert cluster_disparities(impl, *row_frames(np.roll(row, 4), row), threshold=3.0) == [4.0, 4.0]
    assert cluster_disparities(impl, *row_frames(np.roll(row, 4), row), threshold=3.0001) == []


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


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), cuts=st.lists(st.integers(1, 160_000), max_size=8, unique=True),
       variant=st.sampled_from(["shared", "separate"]))
def test_result_does_not_depend_on_the_packets(seed, cuts, variant):
    rng = np.random.default_rng(seed)
    parts = [blob_events(rng, 6, shift=int(rng.integers(0, 20)), t0=k * W) for k in range(4)]
    left = np.concatenate([p[0] for p in parts])
    right = np.concatenate([p[1] for p in parts])
    whole = run_all(FrameClusterMatcher.from_variant(variant), left, right)
    np.testing.assert_array_equal(feed_slices(FrameClusterMatcher.from_variant(variant), left, right, cuts), whole)


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
