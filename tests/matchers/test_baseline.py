"""OpenCV StereoBM / StereoSGBM on the 40 ms frames (cvstereo.matchers.opencv.matcher)."""

from __future__ import annotations

import numpy as np
import pytest

from calibration_free import create_matcher, match
from cvstereo.matchers.opencv.matcher import StereoBMMatcher, StereoBMParams, StereoSGBMMatcher, StereoSGBMParams
from cvstereo.model.events import make_events
from cvstereo.model.polarity import OFF, ON
from cvstereo.model.recording import Recording

W = 40_000


def shifted_texture(rng, k, *, n=20_000, windows=2):
    """Random ON/OFF events over the sensor (a texture); the right camera sees them k px further left."""
    x, y, p = rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    t = np.sort(rng.integers(0, windows * W, n))
    keep = x >= k
    return make_events(t, x, y, p), make_events(t[keep], x[keep] - k, y[keep], p[keep])


@pytest.mark.parametrize("method", ["stereobm", "sgbm"])
@pytest.mark.parametrize("k", [4, 12, 25])
def test_recovers_the_shift_of_a_texture(rng, method, k):
    left, right = shifted_texture(rng, k)
    m = create_matcher(method)
    out = np.concatenate([m.feed(left, right), m.flush()])
    assert out.size > 5000
    # Left pixels with x < k have no counterpart in the right camera; elsewhere the shift is found.
    inner = out[out["x"] >= k + 8]
    assert np.mean(np.abs(inner["disparity"] - k) < 0.5) > 0.95
    assert np.median(out["disparity"]) == k


@pytest.mark.parametrize("method", ["stereobm", "sgbm"])
def test_results_anchor_on_left_pixels_with_events(rng, method):
    left, right = shifted_texture(rng, 10, n=6000, windows=3)
    left = left[left["y"] < 100]  # rows without left events must get no result
    out = np.concatenate([(m := create_matcher(method)).feed(left, right), m.flush()])
    assert set(out["camera"].tolist()) == {0}
    assert set(out["t"].tolist()) == {W, 2 * W, 3 * W}
    for t_end in (W, 2 * W, 3 * W):
        win = left[(left["t"] >= t_end - W) & (left["t"] < t_end)]
        got = out[out["t"] == t_end]
        assert set(zip(got["x"].tolist(), got["y"].tolist(), strict=True)) <= \
            set(zip(win["x"].tolist(), win["y"].tolist(), strict=True))
    # Fixed point handled: values are multiples of 1/16, non-negative with min_disparity 0.
    np.testing.assert_array_equal(out["disparity"] * 16, np.round(out["disparity"] * 16))
    assert out["disparity"].min() >= 0
    assert m.describe()["anchor"] == "window" and m.describe()["variant"] == "default"


def test_without_padding_the_left_strip_has_no_result(rng):
    left, right = shifted_texture(rng, 6)
    out = np.concatenate([(m := StereoBMMatcher(StereoBMParams(pad=False))).feed(left, right), m.flush()])
    assert out["x"].min() >= 64 - 1  # OpenCV leaves num_disparities - 1 columns empty
    padded = match(Recording(left, right), method="stereobm").matches
    assert padded["x"].min() < 20


def test_image_mapping():
    m = StereoBMMatcher()
    counts = np.zeros((2, 128, 128), int)
    counts[ON, 10, 10] = 40  # strongly ON
    counts[OFF, 50, 50] = 40  # strongly OFF
    img = m.image(counts)
    assert img.dtype == np.uint8 and img[0, 0] == 128 and img[10, 10] == 255 and img[50, 50] == 0
    counted = StereoSGBMMatcher(StereoSGBMParams(image="count", gaussian=False)).image(counts)
    assert counted[10, 10] == counted[50, 50] == 255 and counted[0, 0] == 0


@pytest.mark.parametrize(("cls", "kwargs", "message"), [
    (StereoBMParams, {"num_disparities": 40}, "multiple of 16"),
    (StereoBMParams, {"block_size": 8}, "odd"),
    (StereoBMParams, {"block_size": 3}, r"in 5\.\.255"),
    (StereoBMParams, {"block_size": 999}, r"in 5\.\.255"),
    (StereoSGBMParams, {"p1": 100, "p2": 50}, "p2 must exceed p1"),
    (StereoSGBMParams, {"image": "gray"}, "filtered"),
])
def test_invalid_parameters(cls, kwargs, message):
    with pytest.raises(ValueError, match=message):
        cls(**kwargs)


@pytest.mark.parametrize(("method", "block_size", "resolution"), [("stereobm", 129, (128, 128)),
                                                                   ("sgbm", 129, (128, 128)), ("sgbm", 61, (64, 60))])
def test_block_larger_than_the_sensor_is_refused_before_opencv(method, block_size, resolution):
    """OpenCV would stop with a C++ error on the first window; the matcher says what fits instead."""
    with pytest.raises(ValueError, match=f"block_size {block_size} does not fit"):
        create_matcher(method, block_size=block_size, resolution=resolution)
