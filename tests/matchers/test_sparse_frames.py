"""Sparse frames (cvstereo.matchers._shared.sparse_frames): the Gaussian on the support equals cv2's dense filter bit
for bit,
and the frame matchers' sparse path gives the matches of their dense path."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut, random_pair

from cvstereo.errors import EventFormatError
from cvstereo.frames.accumulate import gaussian_filter, signed_frame, stacked_frames
from cvstereo.matchers._shared.sparse_frames import SparseFrames, cv2_layout
from cvstereo.matchers.registry import matcher_class
from cvstereo.model.events import make_events
from cvstereo.model.polarity import slot_of_p


def _sparse_or_skip(n_planes, resolution, **kw):
    sf = SparseFrames(n_planes, resolution=resolution, gaussian=True, **kw)
    if not sf.exact:
        pytest.skip("this OpenCV build's filter arithmetic is not reproduced here: the matchers use the dense path")
    return sf


def _events(rng, n, width, height):
    """Random events clustered on a few pixels (counts up to ~10, ON and OFF mixed: values that cancel)."""
    px = rng.integers(0, width, n // 4 + 1)
    py = rng.integers(0, height, n // 4 + 1)
    pick = rng.integers(0, px.size, n)
    return make_events(np.arange(n), px[pick], py[pick], rng.integers(0, 2, n))


@pytest.mark.parametrize("width", [128, 346, 640, 17, 5, 64])
@pytest.mark.parametrize("polarity", ["shared", "separate", "off"])
def test_filtered_planes_equal_cv2_bit_for_bit(rng, width, polarity):
    height = 37
    n_frames, channel_of = slot_of_p(polarity)
    sf = _sparse_or_skip(2 * n_frames, (width, height))
    for _ in range(3):
        cams = [_events(rng, int(rng.integers(1, 4 * width)), width, height) for _ in range(2)]
        sf.fill(cams, channel_of, n_frames)
        stack, _ = stacked_frames(cams, polarity=polarity, resolution=(width, height), gap=2)
        dense = gaussian_filter(stack)
        for plane in range(2 * n_frames):
            expected = dense[plane * (height + 2): plane * (height + 2) + height]
            assert sf.values[plane].tobytes() == expected.tobytes(), plane
            # The support covers every nonzero filtered value.
            bits = np.unpackbits(sf.support[plane].view(np.uint8), axis=1, bitorder="little")[:, :width]
            assert not expected[bits == 0].any()
        sf.clear()
        assert not sf.values.any() and not sf.support.any() and not sf.touched.any()


def test_other_kernels_and_off_sensor_events():
    assert cv2_layout(128, 1.0, 3) is None  # only the 5x5 kernel is reproduced: 3x3 keeps the dense path
    assert not SparseFrames(2, resolution=(128, 128), gaussian=True, kernel_size=3).exact
    sf = SparseFrames(2, resolution=(16, 8), gaussian=False)
    assert sf.exact  # without the Gaussian the frames are sums of signs: always exact
    ok = make_events([0, 1], [3, 4], [2, 2], [1, 0])
    bad = make_events([0, 1], [3, 16], [2, 2], [1, 1])
    with pytest.raises(EventFormatError, match=r"camera 1: event 1 at \(x=16, y=2\) lies outside the 16x8"):
        sf.fill([ok, bad], np.array([0, 0]), 1)
    assert not sf.values.any() and not sf.touched.any()  # cleared for the next window


def _shifted_patches(seed, *, width, height, windows=3):
    """Patches with 3 events a pixel, the right camera's a few px further left, plus noise: frames that pass the
    thresholds, blocks that match and blocks that do not."""
    rng = np.random.default_rng(seed)
    cams = [[], []]
    for k in range(windows):
        for _ in range(10):
            shift, w, h = rng.integers(0, 12), rng.integers(2, 9), rng.integers(2, 6)
            x0, y0 = rng.integers(shift, width - w), rng.integers(0, height - h)
            yy, xx = np.mgrid[y0:y0 + h, x0:x0 + w]
            x, y = np.repeat(xx.ravel(), 3), np.repeat(yy.ravel(), 3)
            t = rng.integers(k * 40_000, (k + 1) * 40_000, x.size)
            p = np.full(x.size, rng.integers(0, 2))
            cams[0].append((t, x, y, p))
            cams[1].append((t, x - shift, y, p))
        for cam in cams:
            n = 100
            cam.append((rng.integers(k * 40_000, (k + 1) * 40_000, n), rng.integers(0, width, n),
                        rng.integers(0, height, n), rng.integers(0, 2, n)))
    out = []
    for cam in cams:
        t, x, y, p = (np.concatenate(c) for c in zip(*cam, strict=True))
        order = np.argsort(t, kind="stable")
        out.append(make_events(t[order], x[order], y[order], p[order]))
    return out[0], out[1], (width, height)


def _dense_and_sparse(method, variant, left, right, resolution, cuts, **params):
    cls = matcher_class(method)
    sparse = cls(cls.make_params(variant, **params), resolution=resolution)
    dense = cls(cls.make_params(variant, **params), resolution=resolution)
    if sparse._sparse is None:
        pytest.skip("no sparse path on this machine")
    dense._sparse = None
    return feed_cut(sparse, left, right, cuts), feed_cut(dense, left, right, cuts), sparse, dense


@pytest.mark.parametrize("variant", ["shared", "separate", "on", "off"])
@pytest.mark.parametrize("mode", [{}, {"threshold_mode": "relative", "level_window_us": 5_000, "level_warmup": 20}])
def test_frame_matcher_sparse_path_equals_dense_path(variant, mode):
    left, right, resolution = random_pair(3, n=3000, width=70, height=9)
    got, expected, sparse, dense = _dense_and_sparse("frame", variant, left, right, resolution, [10_000, 25_000],
                                                     **mode)
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    assert sparse.diagnostics() == dense.diagnostics()  # the signal level saw the same values


@pytest.mark.parametrize("variant", ["gaussian", "no-gaussian"])
@pytest.mark.parametrize("params", [{}, {"reference_camera": 0, "max_disparity": 9},
                                    {"threshold_mode": "relative", "level_window_us": 5_000, "level_warmup": 20},
                                    {"block": 3}, {"block": 7, "max_disparity": 40}])
def test_frame_area_sparse_path_equals_dense_path(variant, params):
    left, right, resolution = _shifted_patches(5, width=90, height=30)
    extra = {"threshold": 1.5} if variant == "gaussian" else {"threshold": 3.0}
    got, expected, sparse, dense = _dense_and_sparse("frame-area", variant, left, right, resolution,
                                                     [10_000, 25_000], **{**extra, **params})
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    assert sparse.diagnostics() == dense.diagnostics()


@pytest.mark.parametrize("polarity", ["shared", "separate", "on", "off"])
@pytest.mark.parametrize("lr_check", [False, True])
@pytest.mark.parametrize("mode", [{}, {"threshold_mode": "relative", "level_window_us": 5_000, "level_warmup": 20}])
@pytest.mark.parametrize("reference_camera", [1, 0])
def test_frame_area_sparse_path_equals_dense_path_per_polarity_and_lr_check(polarity, lr_check, mode,
                                                                           reference_camera):
    """Every polarity mode (one frame pair per slot) and the left-right check on the sparse path: the dense
    path's matches, and the same values fed to the signal level (its diagnostics)."""
    left, right, resolution = _shifted_patches(11, width=90, height=30)
    got, expected, sparse, dense = _dense_and_sparse(
        "frame-area", "gaussian", left, right, resolution, [10_000, 25_000], threshold=1.5, polarity=polarity,
        lr_check=lr_check, reference_camera=reference_camera, max_disparity=20, **mode)
    assert expected.size > 0
    if polarity in ("on", "off"):
        assert (expected["p"] == (polarity == "on")).all()  # the other polarity's events are dropped
    np.testing.assert_array_equal(got, expected)
    assert sparse.diagnostics() == dense.diagnostics()


def _rows(matches):
    return set(zip(*(matches[f].tolist() for f in ("x", "y", "p", "disparity")), strict=True))


def test_the_left_right_check_on_the_sparse_path_drops_unconfirmed_disparities():
    """lr_check keeps a subset of the one-direction matches, drops some on this scene (noise pixels whose
    back scan disagrees), and what it keeps agrees with the other camera's scan within 1 px (checked with the
    reference's cost volume scan, not the fast kernels)."""
    from cvstereo.matchers.frame_area.reference import sad_volume, scan_disparity_map
    left, right, resolution = _shifted_patches(11, width=90, height=30, windows=1)
    cls = matcher_class("frame-area")
    runs = {}
    for lr in (False, True):
        m = cls(cls.make_params("gaussian", threshold=1.5, polarity="separate", lr_check=lr, max_disparity=20),
                resolution=resolution)
        if m._sparse is None:
            pytest.skip("no sparse path on this machine")
        runs[lr] = feed_cut(m, left, right, [])
    one_way, checked = runs[False], runs[True]
    assert _rows(checked) < _rows(one_way)  # a strict subset: the check dropped some
    for p, signs in ((0, (-1,)), (1, (1,))):
        frames = [gaussian_filter(signed_frame(cam, resolution=resolution, signs=signs)) for cam in (left, right)]
        back = scan_disparity_map(frames[0], sad_volume(frames[0], frames[1], max_disparity=20, reference_camera=0),
                                  threshold=1.5)
        mine = checked[checked["p"] == p]
        assert mine.size > 0
        other = back[mine["y"], mine["x"] + mine["disparity"].astype(np.int64)]  # right x + d = left x
        assert (np.abs(other - mine["disparity"]) <= 1).all()


def test_a_threshold_of_zero_gives_the_references_result():
    """A relative threshold may reach 0 (floor 0, a level of 0: ON and OFF cancel at every pixel of window 0);
    frame-area then searches pixels without events too, which only its dense path does: the matches still
    equal the reference's. (The cluster matcher keeps no zero pixel at a threshold of 0: v >= 0 and v <= -0.)"""
    from cvstereo.matchers.frame_area.reference import frame_area_reference
    method = "frame-area"
    width, height = 40, 20
    yy, xx = np.mgrid[0:height, 0:width]
    n = xx.size
    cancel = make_events(np.arange(2 * n) % 40_000, np.repeat(xx.ravel(), 2), np.repeat(yy.ravel(), 2),
                         np.tile([0, 1], n))  # ON + OFF at every pixel: all frame values 0
    cams = []
    for patches in _shifted_patches(8, width=width, height=height, windows=1)[:2]:
        later = patches.copy()
        later["t"] += 40_000
        cams.append(np.concatenate([cancel, later]))
    params = matcher_class(method).make_params(
        None, gaussian=False, threshold_mode="relative", level_floor=0.0, level_warmup=10, level_windows=1,
        threshold=3.0)
    m = matcher_class(method)(params, resolution=(width, height))
    got = feed_cut(m, cams[0], cams[1], [20_000, 60_000])
    assert m._level.thresholds(1).tolist() == [0.0, 0.0]  # window 1 ran with a threshold of 0
    expected = frame_area_reference(cams[0], cams[1], params, resolution=(width, height))
    assert (expected["t"] == 80_000).sum() > 20
    np.testing.assert_array_equal(got, expected)
