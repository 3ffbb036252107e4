"""cvstereo.frames.accumulate: accumulation, polarity handling, the thesis' Gaussian, window streaming."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.errors import EventFormatError
from cvstereo.frames.accumulate import (
    event_mask,
    gaussian_filter,
    polarity_counts,
    polarity_frames,
    signed_frame,
    stacked_frames,
)
from cvstereo.frames.windows import WindowAccumulator
from cvstereo.model.events import make_events
from cvstereo.model.polarity import OFF, ON

W = 40_000

# Thesis eq. 3.6: the 5x5 Gaussian, sigma 1, as printed (4 decimals).
THESIS_KERNEL = np.array([
    [0.0030, 0.0133, 0.0219, 0.0133, 0.0030],
    [0.0133, 0.0596, 0.0983, 0.0596, 0.0133],
    [0.0219, 0.0983, 0.1621, 0.0983, 0.0219],
    [0.0133, 0.0596, 0.0983, 0.0596, 0.0133],
    [0.0030, 0.0133, 0.0219, 0.0133, 0.0030],
])


def random_events(rng, n, *, t_max=200_000, size=16):
    t = np.sort(rng.integers(0, t_max, n))
    return make_events(t, rng.integers(0, size, n), rng.integers(0, size, n), rng.integers(0, 2, n))


def test_thesis_example_ten_off_two_on_give_minus_eight():
    ev = make_events(np.arange(12), [5] * 12, [7] * 12, [0] * 10 + [1] * 2)
    frame = signed_frame(ev)
    assert frame.shape == (128, 128) and frame.dtype == np.float32
    assert frame[7, 5] == -8
    assert np.count_nonzero(frame) == 1


def test_polarity_modes(rng):
    ev = random_events(rng, 500)
    on = np.zeros((16, 16))
    off = np.zeros((16, 16))
    for e in ev:  # the straightforward accumulation
        (on if e["p"] else off)[e["y"], e["x"]] += 1
    counts = polarity_counts(ev, resolution=(16, 16))
    np.testing.assert_array_equal(counts, [off, on])  # indexed by p
    np.testing.assert_array_equal(counts[ON], on)
    np.testing.assert_array_equal(counts[OFF], off)
    frames = {mode: polarity_frames(counts, polarity=mode) for mode in ("shared", "separate", "on", "off")}
    np.testing.assert_array_equal(frames["shared"][0][1], on - off)
    assert [c for c, _ in frames["separate"]] == [-1, 1]  # slot = p: OFF frame first
    np.testing.assert_array_equal(frames["separate"][0][1], -off)
    np.testing.assert_array_equal(frames["separate"][1][1], on)
    np.testing.assert_array_equal(frames["on"][0][1], on)
    np.testing.assert_array_equal(frames["off"][0][1], -off)
    np.testing.assert_array_equal(signed_frame(ev, resolution=(16, 16), signs=(-1,)), -off)
    np.testing.assert_array_equal(event_mask(counts), (on + off) > 0)
    np.testing.assert_array_equal(event_mask(counts, channel=1), on > 0)
    np.testing.assert_array_equal(event_mask(counts, channel=-1), off > 0)
    with pytest.raises(ValueError, match="shared, separate, on, off"):
        polarity_frames(counts, polarity="both")


@pytest.mark.parametrize("polarity", ["shared", "separate", "on", "off"])
@pytest.mark.parametrize("gap", [0, 2])
@pytest.mark.parametrize("seen_camera", [0, 1])
def test_stacked_frames_equal_the_frames_one_by_one(rng, polarity, gap, seen_camera):
    cams = [random_events(rng, 400, size=12), random_events(rng, 300, size=12)]
    res = (12, 10)
    cams = [ev[ev["y"] < 10] for ev in cams]
    stack, seen = stacked_frames(cams, polarity=polarity, resolution=res, gap=gap, seen_camera=seen_camera)
    per_camera = [polarity_frames(polarity_counts(ev, resolution=res), polarity=polarity) for ev in cams]
    n = len(per_camera[0])
    assert stack.dtype == np.float32 and stack.shape == (2 * n * (10 + gap), 12) and seen.shape == (n * 10, 12)
    blocks = stack.reshape(2 * n, 10 + gap, 12)
    for i, (_, frame) in enumerate(per_camera[0] + per_camera[1]):
        np.testing.assert_array_equal(blocks[i, :10], frame)
        assert not blocks[i, 10:].any()
    counts = polarity_counts(cams[seen_camera], resolution=res)
    for i, (channel, _) in enumerate(per_camera[0]):
        np.testing.assert_array_equal(seen[i * 10:(i + 1) * 10], event_mask(counts, channel=channel))


def test_stacked_frames_reject_events_off_the_sensor():
    ev = make_events([0, 1], [3, 16], [2, 0], [1, 0])
    with pytest.raises(EventFormatError, match=r"camera 1: event 1 at \(x=16, y=0\) lies outside the 16x16"):
        stacked_frames([ev[:1], ev], resolution=(16, 16))


def test_non_square_resolution():
    ev = make_events([0, 1], [39, 0], [9, 0], [1, 1])
    frame = signed_frame(ev, resolution=(40, 10))
    assert frame.shape == (10, 40) and frame[9, 39] == 1 and frame[0, 0] == 1


def test_gaussian_is_the_thesis_kernel_with_zero_border():
    impulse = np.zeros((9, 9), np.float32)
    impulse[4, 4] = 1
    np.testing.assert_allclose(gaussian_filter(impulse)[2:7, 2:7], THESIS_KERNEL, atol=6e-5)
    corner = np.zeros((9, 9), np.float32)
    corner[0, 0] = 1
    out = gaussian_filter(corner)
    # Zero padding: the mass that falls outside the sensor is lost (a replicated border would keep it).
    np.testing.assert_allclose(out.sum(), THESIS_KERNEL[2:, 2:].sum(), atol=2e-4)
    np.testing.assert_allclose(out[:3, :3], THESIS_KERNEL[2:, 2:], atol=6e-5)


@pytest.mark.parametrize(("kernel_size", "sigma"), [(4, 1.0), (0, 1.0), (5, 0.0)])
def test_bad_filter_or_window_parameters(kernel_size, sigma):  # sigma: the old name of kernel_sigma
    from cvstereo.matchers.frame.matcher import FrameClusterParams

    with pytest.raises(ValueError, match="FrameClusterParams"):
        FrameClusterParams(kernel_size=kernel_size, sigma=sigma)
    with pytest.raises(ValueError, match="window_us"):
        WindowAccumulator(0)


def test_windows_on_the_absolute_clock():
    ev = make_events([0, W - 1, W, 5 * W + 3], [1, 2, 3, 4], [0] * 4, [1] * 4)
    acc = WindowAccumulator(W)
    assert acc.push(ev[:2], ev[:0], watermark=W - 1) == []  # window 0 not complete yet
    first = acc.push(ev[2:3], ev[:0], watermark=W)
    assert [(w.index, w.t_start, w.t_end) for w in first] == [(0, 0, W)]
    assert first[0].left["x"].tolist() == [1, 2] and first[0].right.size == 0
    # Windows 2..4 are empty: nothing is emitted for them.
    second = acc.push(ev[3:], ev[3:], watermark=5 * W + 3)
    assert [w.t_end for w in second] == [2 * W]
    last = acc.flush()
    assert [(w.t_end, w.left.size, w.right.size) for w in last] == [(6 * W, 1, 1)]
    assert acc.flush() == []


def _windows_by_cuts(left, right, cuts):
    """Feed the streams cut at the given times; return (index, left, right) of every window emitted."""
    acc = WindowAccumulator(W)
    out = []
    start = 0
    for stop in [*sorted(cuts), None]:
        sl = [slice(np.searchsorted(e["t"], start), None if stop is None else np.searchsorted(e["t"], stop))
              for e in (left, right)]
        out += acc.push(left[sl[0]], right[sl[1]], watermark=stop)
        start = stop
    out += acc.flush()
    return [(w.index, w.left.tolist(), w.right.tolist()) for w in out]


@settings(deadline=None, max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), cuts=st.lists(st.integers(1, 400_000), max_size=12, unique=True))
def test_windows_do_not_depend_on_the_packets(seed, cuts):
    rng = np.random.default_rng(seed)
    left, right = random_events(rng, 300, t_max=400_000), random_events(rng, 200, t_max=400_000)
    whole = _windows_by_cuts(left, right, [])
    assert _windows_by_cuts(left, right, cuts) == whole
    assert [k for k, _, _ in whole] == sorted({int(t) // W for t in np.concatenate([left["t"], right["t"]])})
