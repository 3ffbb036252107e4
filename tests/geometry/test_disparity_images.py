"""``cvs.disparity_images(result)``: OpenCV-style dense float32 images per window, anchor and window from the meta."""

from __future__ import annotations

import numpy as np
import pytest

import cvstereo as cvs
from cvstereo.geometry.disparity_maps import window_disparity_images
from cvstereo.model.matches import MatchResult, make_matches


def _by_hand(matches, camera, resolution, window_us, anchor):
    """Each match's window from its time alone (a window anchor at t closes [t - W, t)), pixel means in loops."""
    w, h = resolution
    sums, counts = {}, {}
    for m in matches:
        if m["camera"] != camera or not np.isfinite(m["disparity"]):
            continue
        t = int(m["t"])
        k = (t - 1) // window_us if anchor == "window" else t // window_us
        sums.setdefault(k, np.zeros((h, w)))[m["y"], m["x"]] += m["disparity"]
        counts.setdefault(k, np.zeros((h, w)))[m["y"], m["x"]] += 1
    return {k * window_us: np.where(counts[k] > 0, sums[k] / np.maximum(counts[k], 1), np.nan) for k in sums}


@pytest.mark.parametrize("method", ["frame", "event-time"])
def test_disparity_images_of_a_real_run_are_the_hand_computed_windows(method):
    rec = cvs.simulate_preset("1arm-100cm", seconds=0.25, seed=3)
    result = cvs.match(rec, method=method)
    assert len(result) > 50
    camera = result.meta["anchor_cameras"][0]
    got = dict(cvs.disparity_images(result))
    window_us = result.meta["window_us"] or 40_000
    expected = _by_hand(result.matches, camera, rec.resolution, window_us, result.meta["anchor"])
    assert sorted(got) == sorted(expected)
    for t, image in got.items():
        assert image.dtype == np.float32 and image.shape == (rec.resolution[1], rec.resolution[0])
        np.testing.assert_allclose(image, expected[t].astype(np.float32), rtol=0, atol=1e-6, equal_nan=True)


def test_window_anchors_land_in_their_own_window_where_the_old_default_shifted_them():
    # Two windows of 40 ms closed at 40 ms and 80 ms: the first window's match belongs to [0, 40 ms).
    m = make_matches([40_000, 80_000], [1, 0], [0, 0], 0, 0, [5.0, 9.0])
    result = MatchResult(m, {"anchor": "window", "window_us": 40_000, "resolution": [2, 1], "anchor_cameras": [0]})
    got = list(cvs.disparity_images(result))
    assert [t for t, _ in got] == [0, 40_000]
    np.testing.assert_array_equal(got[0][1], [[np.nan, 5.0]])
    np.testing.assert_array_equal(got[1][1], [[9.0, np.nan]])
    # The old function without anchor= puts each one window later (issue 26): kept as it was.
    assert [t for t, _ in window_disparity_images(m, 0, resolution=(2, 1))] == [40_000, 80_000]


def test_meta_values_can_be_overridden_and_bad_input_is_named():
    m = make_matches([10, 50_010], [0, 1], [0, 0], 1, 1, [2.0, 3.0])  # anchored on the right camera
    result = MatchResult(m, {"anchor": "event", "window_us": 0, "resolution": [2, 1], "anchor_cameras": [1]})
    assert [t for t, _ in cvs.disparity_images(result)] == [0, 40_000]  # event anchors: 40 ms windows
    assert [t for t, _ in cvs.disparity_images(result, window_us=100_000)] == [0]
    assert list(cvs.disparity_images(result, camera=0)) == []
    assert next(cvs.disparity_images(result, resolution=(3, 2)))[1].shape == (2, 3)
    with pytest.raises(TypeError, match="window_disparity_images"):
        list(cvs.disparity_images(m))
    with pytest.raises(ValueError, match="no resolution; give resolution="):
        list(cvs.disparity_images(MatchResult(m, {"anchor": "event"})))
