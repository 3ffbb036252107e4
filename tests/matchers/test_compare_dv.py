"""dv-processing's SemiDenseStereoMatcher through our matcher protocol (extra `compare`)."""

from __future__ import annotations

import numpy as np
import pytest

from calibration_free import create_matcher
from cvstereo.matchers.registry import available_methods, matcher_class
from cvstereo.model.events import make_events

pytest.importorskip("dv_processing", reason="dv-processing (extra 'compare') is not installed")

W = 40_000


def _shifted_texture(rng, k, *, n=20_000, windows=2, size=(128, 128)):
    # The same random texture in both cameras, k px further left in the right camera.
    x, y, p = rng.integers(0, size[0], n), rng.integers(0, size[1], n), rng.integers(0, 2, n)
    t = np.sort(rng.integers(0, windows * W, n))
    keep = x >= k
    return make_events(t, x, y, p), make_events(t[keep], x[keep] - k, y[keep], p[keep])


def test_listed_when_installed():
    assert "dv-semidense" in available_methods()


@pytest.mark.parametrize("k", [5, 14])
def test_recovers_the_shift_of_a_texture(rng, k):
    left, right = _shifted_texture(rng, k)
    m = create_matcher("dv-semidense")
    out = np.concatenate([m.feed(left, right), m.flush()])
    assert out.size > 1000
    assert set(np.unique(out["t"])) <= {W, 2 * W}
    assert (out["camera"] == 0).all()
    # dv-processing's SGBM leaves its left strip (48 disparities) empty; inside it the shift is found.
    inner = out[out["x"] >= 48 + 6]
    assert np.mean(np.abs(inner["disparity"] - k) <= 1.0) > 0.9


def test_anchors_are_left_pixels_with_events(rng):
    left, right = _shifted_texture(rng, 8, n=8000, windows=1)
    m = create_matcher("dv-semidense")
    out = np.concatenate([m.feed(left, right), m.flush()])
    seen = set(zip(left["x"].tolist(), left["y"].tolist(), strict=True))
    assert out.size and all((x, y) in seen for x, y in zip(out["x"].tolist(), out["y"].tolist(), strict=True))


@pytest.mark.parametrize(("width", "expected"), [(128, 47), (240, 95), (346, 143), (640, 239)])
def test_range_follows_the_opencv_baselines_rule(width, expected):
    # dv-processing's 48 disparities at 128 px, times width / 128, rounded up to a multiple of 16 (as SGBM's 64).
    cls = matcher_class("dv-semidense")
    assert cls.params_for(resolution=(width, 96)).max_disparity == expected
    assert cls.params_for(resolution=(width, 96), max_disparity=31).max_disparity == 31  # given wins


def test_a_wide_sensor_finds_disparities_beyond_dv_processings_48(rng):
    # 256 px wide: 96 disparities (0 .. 95); a texture at 70 px, out of dv-processing's own reach.
    left, right = _shifted_texture(rng, 70, n=60_000, size=(256, 64))
    m = create_matcher("dv-semidense", resolution=(256, 64))
    assert m.params.max_disparity == 95
    out = np.concatenate([m.feed(left, right), m.flush()])
    inner = out[out["x"] >= 96 + 6]  # OpenCV leaves the left strip of its disparity count empty
    assert inner.size > 1000
    assert np.mean(np.abs(inner["disparity"] - 70) <= 1.0) > 0.9


def test_bad_range_says_which():
    with pytest.raises(ValueError, match=r"max_disparity \+ 1 must be a positive multiple of 16.*got max_disparity 50"):
        create_matcher("dv-semidense", max_disparity=50)


def _store(dv, events):
    """dv-processing's own event path: an EventStore filled one event at a time."""
    store = dv.EventStore()
    for t, x, y, p in zip(*(events[k].tolist() for k in "txyp"), strict=True):
        store.push_back(t, x, y, bool(p))
    return store


def test_edge_map_is_dv_processings_accumulator(rng):
    # Pixels with 0 to 7 events of either polarity (the 8-bit pixel saturates after the 4th), any order, and a
    # second window from the same accumulator (dv-processing starts every frame from 0).
    import dv_processing as dv

    from cvstereo.frames.accumulate import polarity_counts
    from cvstereo.matchers.dv.matcher import edge_map

    size = (37, 23)
    acc = dv.EdgeMapAccumulator(size)
    for _ in range(2):
        n = 600
        x, y, p = rng.integers(0, size[0], n), rng.integers(0, size[1], n), rng.integers(0, 2, n)
        events = make_events(np.sort(rng.integers(0, W, n)), x, y, p)
        acc.accept(_store(dv, events))
        ours = edge_map(polarity_counts(events, resolution=size))
        assert ours.dtype == np.uint8 and ours.shape == (size[1], size[0])
        np.testing.assert_array_equal(ours, acc.generateFrame().image)
        assert set(np.unique(ours)) >= {0, 64, 128, 192, 255}


def test_disparities_are_dv_processings_own_event_path(rng):
    # The matcher's images through dv-processing's compute() give the disparity map that its computeDisparity()
    # gives from the events, pixel for pixel.
    import dv_processing as dv

    left, right = _shifted_texture(rng, 9, n=12_000, windows=1)
    own = dv.SemiDenseStereoMatcher((128, 128), (128, 128)).computeDisparity(_store(dv, left), _store(dv, right))
    expected = np.where(own >= 0, own / 16.0, np.nan)
    out = np.concatenate([(m := create_matcher("dv-semidense")).feed(left, right), m.flush()])
    assert out.size > 1000
    np.testing.assert_array_equal(out["disparity"], expected[out["y"], out["x"]].astype(np.float32))
