"""The references' own helpers (cvstereo/matchers/_shared/reference_*.py) against hand-computed values and against
the fast path's compiled twins, piece by piece: a disagreement here names the piece, where fast == reference on a
whole matcher only names the matcher."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.frames.accumulate import gaussian_filter as fast_gaussian
from cvstereo.frames.accumulate import signed_frame as fast_signed_frame
from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.frames.dynamic import update_kernel as fast_update_kernel
from cvstereo.matchers._shared.border import BorderRule
from cvstereo.matchers._shared.reference_border import border_filter
from cvstereo.matchers._shared.reference_checks import lr_consistent, support_counts
from cvstereo.matchers._shared.reference_frames import merged_events, update_kernel
from cvstereo.matchers._shared.reference_windows import gaussian_filter, signed_frame
from cvstereo.matchers._shared.support import lr_consistent as fast_lr_consistent
from cvstereo.matchers._shared.support import support_counts as fast_support_counts
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches


def test_the_gaussian_of_one_event_is_eq_3_6():
    frame = np.zeros((7, 7), np.float32)
    frame[3, 3] = 1.0
    axis = [math.exp(-(i * i) / 2) for i in range(-2, 3)]
    expected = np.outer(axis, axis) / sum(axis) ** 2  # hand: centre 1 / (1 + 2 e^-1/2 + 2 e^-2)^2 = 0.16210
    got = gaussian_filter(frame, sigma=1.0, kernel_size=5)
    assert got.dtype == np.float32 and round(float(got[3, 3]), 5) == 0.1621
    np.testing.assert_allclose(got[1:6, 1:6], expected, rtol=1e-6)
    assert not got[0].any() and not got[:, 0].any()  # beyond the kernel's reach


def test_the_gaussian_is_zero_outside_the_sensor():
    frame = np.zeros((5, 5), np.float32)
    frame[0, 0] = 1.0  # a corner event: the kernel's parts beyond the sensor add nothing
    g = [math.exp(-(i * i) / 2) for i in range(-2, 3)]
    got = gaussian_filter(frame, sigma=1.0, kernel_size=5)
    assert math.isclose(float(got[0, 0]), (g[2] / sum(g)) ** 2, rel_tol=1e-6)
    assert math.isclose(float(got[2, 1]), g[0] * g[1] / sum(g) ** 2, rel_tol=1e-6)


def test_symmetric_cancellation_gives_exactly_zero():
    # The neighbourhood the frame-area reference first disagreed on (blob scene, seed 10743): -3 and +3 at
    # offsets of equal weight. By eq. 3.6 the value is 0, and its sign is a match's polarity; summed offset by
    # offset in float64 it came out +3e-17 (polarity ON), cv2 gives 0.0.
    patch = np.array([[0, 0, 0, 0, 0], [0, -3, -3, -3, -3], [3, 0, 0, 0, -3], [3, 3, 3, 3, 0], [0, 0, 0, 0, 0]],
                     np.float32)
    assert gaussian_filter(patch, sigma=1.0, kernel_size=5)[2, 2] == 0.0
    assert fast_gaussian(patch)[2, 2] == 0.0
    # One ON and one OFF event at offsets (1, 2) and (2, -1): the same weight, so 0 by the definition; the
    # reference gives it, cv2's float32 passes leave a few 1e-10 (its rounding, the sign of which then decides
    # a frame-area match's p at such a pixel).
    pair = np.zeros((5, 5), np.float32)
    pair[3, 4], pair[4, 1] = 1.0, -1.0
    assert gaussian_filter(pair, sigma=1.0, kernel_size=5)[2, 2] == 0.0
    assert abs(float(fast_gaussian(pair)[2, 2])) < 1e-8


@pytest.mark.parametrize("seed", range(4))
def test_frames_and_gaussian_agree_with_the_fast_path(seed):
    rng = np.random.default_rng(seed)
    n = 400
    ev = make_events(np.sort(rng.integers(0, 1000, n)), rng.integers(0, 30, n), rng.integers(0, 20, n),
                     rng.integers(0, 2, n))
    for signs in ((1, -1), (1,), (-1,)):
        frame = signed_frame(ev, resolution=(30, 20), signs=signs)
        np.testing.assert_array_equal(frame, fast_signed_frame(ev, resolution=(30, 20), signs=signs))
        # Different summation orders: equal to float32 rounding, not bit for bit.
        np.testing.assert_allclose(gaussian_filter(frame, sigma=1.0, kernel_size=5), fast_gaussian(frame), atol=1e-6)


@pytest.mark.parametrize(("size", "sigma"), [(3, 1.0), (5, 1.5), (1, 1.0)])
def test_the_update_kernel_is_the_gain_times_the_gaussian(size, sigma):
    params = DynamicFrameParams(kernel_size=size, kernel_sigma=sigma)
    g = np.exp(-((np.arange(size) - size // 2) ** 2) / (2 * sigma**2))
    np.testing.assert_allclose(update_kernel(params), 2.0 * np.outer(g, g) / g.sum() ** 2, rtol=1e-12)
    np.testing.assert_allclose(update_kernel(params), fast_update_kernel(params), rtol=1e-12)
    assert update_kernel(DynamicFrameParams(gaussian=False)).tolist() == [[1.0]]


def test_the_merge_order_is_time_then_left_then_array_order():
    left = make_events([5, 5, 7], [1, 2, 3], [0, 0, 0], [1, 1, 1])
    right = make_events([3, 5, 7], [4, 5, 6], [0, 0, 0], [1, 1, 1])
    order = [(cam, i) for cam, i, _ in merged_events(left, right)]
    assert order == [(1, 0), (0, 0), (0, 1), (1, 1), (0, 2), (1, 2)]


@pytest.mark.parametrize("seed", range(6))
def test_support_counts_agree_with_the_fast_count(seed):
    rng = np.random.default_rng(seed)
    n = 300
    x, y = rng.integers(0, 25, n), rng.integers(0, 10, n)
    d = rng.integers(0, 8, n) + rng.choice([0.0, 0.5], n)
    np.testing.assert_array_equal(support_counts(x, y, d), fast_support_counts(x, y, d, width=25))


@pytest.mark.parametrize("seed", range(6))
def test_lr_check_agrees_with_the_fast_check(seed):
    rng = np.random.default_rng(seed)
    maps = [np.where(rng.random((6, 20)) < 0.4, np.nan, rng.integers(0, 6, (6, 20)) + rng.choice([0, 0.5, 1.5],
                                                                                                   (6, 20)))
            for _ in range(2)]
    for cam in (0, 1):
        np.testing.assert_array_equal(lr_consistent(*maps, reference_camera=cam),
                                      fast_lr_consistent(*maps, reference_camera=cam))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 3), horizon=st.sampled_from([50, 400, 5_000]))
def test_border_rule_agrees_with_the_compiled_rule(seed, rows, horizon):
    rng = np.random.default_rng(seed)
    n, width, height = 300, 24, 6
    t = np.sort(rng.integers(0, 2_000, n) // 40 * 40)  # several matches per time, as a window's
    x = rng.integers(0, width, n)
    m = make_matches(t, x, rng.integers(0, height, n), rng.integers(0, 2, n), rng.integers(0, 2, n),
                     (rng.integers(0, 14, n) + rng.choice([0.0, 0.5], n)).astype(np.float32))
    expected = BorderRule((width, height), horizon_us=horizon, rows=rows)(m)
    got = border_filter(m, horizon_us=horizon, rows=rows, resolution=(width, height))
    np.testing.assert_array_equal(got, expected)
    if horizon == 5_000 and rows:
        assert 0 < expected.size < n  # these scenes give the rule something to refuse (else it proves little)
