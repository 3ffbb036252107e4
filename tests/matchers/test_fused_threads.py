"""The fused matcher on several threads: the same matches as on one (issue 28), at every sensor size, for both
parameter sets, however the stream is cut; and the same as the reference."""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import pytest
from _event_scenes import feed_cut
from hypothesis import given, settings
from hypothesis import strategies as st
from test_fused import PARAM_AXES, textured_pair

from cvstereo.matchers.fused import _kernels
from cvstereo.matchers.fused.matcher import FusedMatcher
from cvstereo.matchers.fused.params import FusedParams
from cvstereo.matchers.fused.reference import fused_reference
from cvstereo.matchers.registry import create_matcher

#: Thread counts against the one-thread matches: 3 splits the work differently from 2 (more chunks) even where
#: numba has fewer threads.
THREAD_COUNTS = (2, 3)


def on_threads(matcher, n: int):
    """``matcher`` on ``n`` threads: its feed and flush set numba's and OpenCV's counts themselves
    (:func:`cvstereo._threads.using_threads`)."""
    matcher.threads = n
    return nullcontext(matcher)


def _matched(make, left, right, cuts, n):
    """Matches and uncertainties of a fresh matcher (``make()``) on ``n`` threads."""
    with on_threads(make(), n) as m:
        got = feed_cut(m, left, right, cuts)
        return got, m.take_uncertainty()


@pytest.mark.parametrize("param_set", ["adaptive", "thesis"])
@pytest.mark.parametrize("size", [(128, 128), (346, 260), (640, 480)])
def test_threads_give_the_one_thread_matches(size, param_set):
    # Edges over the whole sensor (rows of every chunk busy), noise, and a rig one row off (row tolerance).
    left, right, resolution = textured_pair(7, windows=3, size=size, noise=400, jagged=True)

    def make():
        return create_matcher("fused", resolution=resolution, param_set=param_set, max_disparity=20)

    one, unc_one = _matched(make, left, right, [], 1)
    assert one.size > 1000
    assert np.mean(np.abs(one["disparity"] - 5.0) <= 1.0) > 0.5  # the texture's shift: a real matching to repeat
    for n in THREAD_COUNTS:
        got, unc = _matched(make, left, right, [], n)
        np.testing.assert_array_equal(got, one)
        np.testing.assert_array_equal(unc, unc_one)


@settings(max_examples=10, deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1), n_cuts=st.integers(0, 25), threads=st.sampled_from([2, 3, 5]))
def test_threads_and_packet_cuts_give_the_reference_matches(data, seed, n_cuts, threads):
    params = FusedParams(**{k: data.draw(st.sampled_from(v), label=k) for k, v in PARAM_AXES.items()})
    left, right, resolution = textured_pair(seed, size=(72, 20))
    expected, unc_expected = fused_reference(left, right, params, resolution=resolution, with_uncertainty=True)
    cuts = np.random.default_rng(seed).choice(np.concatenate([left["t"], right["t"]]), n_cuts)
    got, unc = _matched(lambda: FusedMatcher(params, resolution=resolution), left, right, cuts, threads)
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(unc, unc_expected)



@pytest.mark.parametrize("stored_max", [0, 1 << 40], ids=["directions", "fused"])
@settings(max_examples=6, deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1))
def test_one_thread_gives_the_reference_matches_either_way(stored_max, data, seed):
    # One thread runs the fused passes where a window's planes fit the caches and the direction passes, one after
    # the other, where they do not: both ways forced here, on every parameter axis.
    params = FusedParams(**{k: data.draw(st.sampled_from(v), label=k) for k, v in PARAM_AXES.items()})
    left, right, resolution = textured_pair(seed, size=(72, 20))
    expected, unc_expected = fused_reference(left, right, params, resolution=resolution, with_uncertainty=True)
    limit = _kernels.STORED_COSTS_MAX_BYTES
    _kernels.STORED_COSTS_MAX_BYTES = stored_max
    try:
        got, unc = _matched(lambda: FusedMatcher(params, resolution=resolution), left, right, [], 1)
    finally:
        _kernels.STORED_COSTS_MAX_BYTES = limit
    assert expected.size > 0
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(unc, unc_expected)
