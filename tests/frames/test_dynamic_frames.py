"""Dynamic frames: hand-computed values, the decay clock, polarity modes, fast == reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.frames.dynamic import FORGET_TICKS, DynamicFrameParams, FrameBank, update_kernel
from cvstereo.matchers._shared.reference_frames import DynamicFrames
from cvstereo.model.events import make_events
from cvstereo.model.polarity import POLARITY_MODES, slot_of_p

# Thesis eq. 3.8, to the four digits it prints.
G3 = np.array([[0.0751, 0.1238, 0.0751], [0.1238, 0.2042, 0.1238], [0.0751, 0.1238, 0.0751]])


def test_kernel_is_twice_the_thesis_gaussian():
    np.testing.assert_allclose(update_kernel(DynamicFrameParams()), 2 * G3, atol=2e-4)
    assert update_kernel(DynamicFrameParams(gaussian=False)).tolist() == [[1.0]]


def test_single_event_values_by_hand():
    frames = DynamicFrames()
    frames.add_event(t=0, x=10, y=20, p=1)
    v = frames.values()[0]
    assert v[20, 10] == pytest.approx(2 * 0.2042, abs=2e-4)
    assert v[20, 11] == pytest.approx(2 * 0.1238, abs=2e-4)
    assert v[19, 10] == pytest.approx(2 * 0.1238, abs=2e-4)
    assert v[21, 11] == pytest.approx(2 * 0.0751, abs=2e-4)
    assert np.count_nonzero(v) == 9
    frames.add_event(t=0, x=10, y=20, p=0)  # an OFF event at the same pixel and time cancels it
    assert np.abs(frames.values()).max() < 1e-15


def test_update_clipped_at_the_border():
    frames = DynamicFrames()
    frames.add_event(t=0, x=0, y=127, p=0)
    v = frames.values()[0]
    assert np.count_nonzero(v) == 4
    assert v[127, 0] == pytest.approx(-2 * 0.2042, abs=2e-4)
    assert v[126, 1] == pytest.approx(-2 * 0.0751, abs=2e-4)


def test_single_pixel_update_adds_the_sign():
    frames = DynamicFrames(DynamicFrameParams(gaussian=False))
    frames.add_event(t=0, x=3, y=4, p=1)
    frames.add_event(t=0, x=3, y=4, p=1)
    frames.add_event(t=0, x=5, y=4, p=0)
    v = frames.values()[0]
    assert v[4, 3] == 2.0 and v[4, 5] == -1.0 and np.count_nonzero(v) == 2


def test_decay_after_40ms_without_events():
    frames = DynamicFrames()
    frames.add_event(t=0, x=10, y=10, p=1)
    before = frames.value(0, 10, 10)
    frames.advance(40_000)  # ticks at 250, 500, ..., 40000: 160 of them
    assert frames.value(0, 10, 10) == pytest.approx(before * 0.99**160, rel=1e-12)
    assert 0.99**160 == pytest.approx(0.2, abs=0.001)  # "drops to 20 percent in 40 ms"


def test_decay_clock_is_absolute_and_a_tick_at_the_event_time_comes_first():
    frames = DynamicFrames()
    frames.add_event(t=249, x=10, y=10, p=1)
    v0 = frames.value(0, 10, 10)
    frames.advance(249)
    assert frames.value(0, 10, 10) == v0  # no tick yet
    frames.advance(250)  # the tick at exactly t = 250 applies before an event at 250
    assert frames.value(0, 10, 10) == pytest.approx(v0 * 0.99, rel=1e-15)
    frames.advance(499)
    assert frames.value(0, 10, 10) == pytest.approx(v0 * 0.99, rel=1e-15)


def test_untouched_frames_skip_their_ticks():
    frames = DynamicFrames()
    frames.advance(10**12)
    frames.add_event(t=10**12, x=1, y=1, p=1)
    assert frames.scale == 1.0 and frames.value(0, 1, 1) == pytest.approx(2 * 0.2042, abs=2e-4)


@pytest.mark.parametrize(("mode", "slots"), [("shared", [0, 0]), ("separate", [0, 1]), ("on", [-1, 0]),
                                             ("off", [0, -1])])
def test_polarity_modes(mode, slots):
    n, slot_by_p = slot_of_p(mode)
    assert slot_by_p.tolist() == slots and n == max(slots) + 1
    frames = DynamicFrames(DynamicFrameParams(polarity=mode))
    frames.add_event(t=0, x=5, y=5, p=1)
    frames.add_event(t=0, x=5, y=5, p=0)
    v = frames.values()
    if mode == "shared":
        assert np.abs(v).max() < 1e-15
    elif mode == "separate":
        assert v[1, 5, 5] > 0.4 and v[0, 5, 5] < -0.4
    else:
        assert v.shape[0] == 1 and (v[0, 5, 5] > 0.4 if mode == "on" else v[0, 5, 5] < -0.4)


def test_invalid_parameters_are_rejected():
    with pytest.raises(ValueError, match="polarity"):
        DynamicFrameParams(polarity="both")
    with pytest.raises(ValueError, match="kernel_size"):
        DynamicFrameParams(kernel_size=4)
    with pytest.raises(ValueError, match="decay"):
        DynamicFrameParams(decay=1.5)


def _reference_values(events, params, *, read_after):
    frames = DynamicFrames(params, resolution=(24, 6))
    values = frames.process(events, after=read_after)
    return np.array([np.nan if v is None else v for v in values]), frames


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from(POLARITY_MODES), gaussian=st.booleans(),
       decay=st.sampled_from([0.99, 0.5]), read_after=st.booleans(), gap=st.booleans())
def test_fast_equals_reference(seed, mode, gaussian, decay, read_after, gap):
    # decay 0.5 renormalises the lazy scale every ~83 ms; a gap beyond FORGET_TICKS clears the frames.
    rng = np.random.default_rng(seed)
    n = 400
    t = np.sort(rng.integers(0, 300_000, n))
    if gap:
        t[n // 2:] += (FORGET_TICKS + 5) * 250
    events = make_events(t, rng.integers(0, 24, n), rng.integers(0, 6, n), rng.integers(0, 2, n))
    params = DynamicFrameParams(polarity=mode, gaussian=gaussian, decay=decay)
    expected, ref = _reference_values(events, params, read_after=read_after)
    bank = FrameBank(1, params, resolution=(24, 6))
    cut = int(rng.integers(0, n))  # two calls: state carries over
    got = np.concatenate([bank.process(0, events[:cut], read="after" if read_after else "before"),
                          bank.process(0, events[cut:], read="after" if read_after else "before")])
    np.testing.assert_array_equal(got, expected)  # bit for bit, NaN where dropped
    np.testing.assert_array_equal(bank.values(0), ref.values())
    later = int(t[-1]) + 10_000
    clock, scale = bank.clock.copy(), bank.scale.copy()
    ref.advance(later)
    np.testing.assert_array_equal(bank.values(0, later), ref.values())
    assert np.array_equal(bank.clock, clock) and np.array_equal(bank.scale, scale)  # values() reads a copy


def _splat_stream(seed, n, *, height=7, width=20, half=2, decay=0.99, gap=False):
    """Random events through :func:`splat_summed` (separate frames, 3x3 Gaussian); the state after them."""
    from cvstereo.matchers._shared.frame_bounds import advance_due_summed, column_sums, splat_summed

    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(0, 200_000, n))
    if gap:
        t[n // 2:] += (FORGET_TICKS + 5) * 250
    kernel = update_kernel(DynamicFrameParams())
    stored, scale, clock = np.zeros((1, 2, height, width)), np.ones(1), np.zeros((1, 2), dtype=np.int64)
    sums, mass, pending = column_sums(stored)
    for k in range(n):
        x, y, p = int(rng.integers(0, width)), int(rng.integers(0, height)), int(rng.integers(0, 2))
        advance_due_summed(stored, scale, clock, sums, mass, pending, 0, int(t[k]), decay, 250, half)
        splat_summed(stored, scale, clock, sums, mass, pending, half, 0, p, x, y, 1.0 if p else -1.0, kernel,
                     (max(0, y - 1), min(height, y + 2)))  # the 3x3 window's rows on the sensor
    return stored, scale, sums, mass, pending


def _exact_column_sums(stored, half):
    padded = np.pad(stored, ((0, 0), (0, 0), (half, half), (0, 0)))
    return sum(padded[:, :, j:j + stored.shape[2]] for j in range(2 * half + 1))


@pytest.mark.parametrize("half", [1, 2])
@pytest.mark.parametrize("decay, gap", [(0.99, False), (0.5, False), (0.99, True)])
def test_column_sums_follow_the_frames_within_their_drift_bound(half, decay, gap):
    # decay 0.5 renormalises (a rebuild); a gap beyond FORGET_TICKS clears the frames (a rebuild of zeros).
    from cvstereo.matchers._shared.frame_bounds import sum_drift

    stored, scale, sums, mass, pending = _splat_stream(3, 3000, half=half, decay=decay, gap=gap)
    exact = _exact_column_sums(stored, half)
    # The frames ON >= 0 and OFF <= 0 (the kernel is positive), so mass bounds every entry.
    assert np.abs(exact).max() <= mass[0] and np.abs(stored).max() <= mass[0]
    drift = np.abs(sums - exact).max()
    assert drift <= sum_drift(mass[0], 2 * half + 1)
    assert 0 < pending[0] <= 3000
    if decay == 0.5:  # renormalised: rebuilt since, so fewer splats pending than events
        assert pending[0] < 3000 and scale[0] > 1e-100


def test_column_sums_rebuild_when_due():
    from cvstereo.matchers._shared.frame_bounds import SUM_REBUILD, advance_due_summed

    stored, scale, sums, mass, pending = _splat_stream(5, 200)
    clock = np.array([[1 << 40, 1]])  # next tick far ahead: only the count can make the rebuild due
    sums += 1.0  # spoiled: only a rebuild restores them
    advance_due_summed(stored, scale, clock, sums, mass, pending, 0, 0, 0.99, 250, 2)
    assert np.abs(sums - _exact_column_sums(stored, 2)).max() >= 0.5  # not due yet
    pending[0] = SUM_REBUILD
    advance_due_summed(stored, scale, clock, sums, mass, pending, 0, 0, 0.99, 250, 2)
    np.testing.assert_allclose(sums, _exact_column_sums(stored, 2), rtol=0, atol=1e-12)
    assert pending[0] == 0 and mass[0] == pytest.approx(np.abs(stored).sum())


def test_splat_bounded_adds_as_splat_does_and_bounds_each_block_by_its_maximum():
    """ON events only (no cancellation, no rescale): every pixel only grows, so the bounds kept per splat row must
    equal the exact block maxima of |stored|; the frame must equal :func:`splat`'s bit for bit. A 5x5 kernel on a
    sensor of 3 blocks puts windows across block edges and the sensor border."""
    from cvstereo.frames.dynamic import splat
    from cvstereo.matchers._shared.frame_bounds import BOUND_SHIFT, block_bounds, splat_bounded

    rng = np.random.default_rng(7)
    kernel = update_kernel(DynamicFrameParams(kernel_size=5, kernel_sigma=1.5))
    height, width = 6, 40
    stored = np.zeros((1, 1, height, width))
    plain = stored.copy()
    bound = block_bounds(stored)
    scale, clock = np.array([0.37]), np.zeros((1, 2), dtype=np.int64)
    for x, y in zip(rng.integers(0, width, 300), rng.integers(0, height, 300), strict=True):
        splat_bounded(stored, scale, clock, bound, 0, 0, int(x), int(y), 1.0, kernel,
                      (max(0, int(y) - 2), min(height, int(y) + 3)))  # the 5x5 window's rows on the sensor
        splat(plain, scale, clock, 0, 0, int(x), int(y), 1.0, kernel)
    np.testing.assert_array_equal(stored, plain)
    for b in range(bound.shape[3]):
        block = np.abs(stored[..., b << BOUND_SHIFT:(b + 1) << BOUND_SHIFT]).max(axis=-1)
        np.testing.assert_array_equal(bound[..., b], block)


def test_skip_below_stops_at_an_end_inside_the_row():
    """The search's forward skips end at hi + 1, anywhere in a block: the first column at or above the threshold
    before ``end``, by brute force, or ``end``."""
    from cvstereo.matchers._shared.frame_bounds import BOUND_SHIFT, skip_below

    rng = np.random.default_rng(11)
    width = 70
    for _ in range(300):
        stored = np.where(rng.random((1, 1, 1, width)) < 0.08, rng.normal(0, 2, (1, 1, 1, width)), 0.0)
        bound = np.abs(stored).reshape(-1)
        bound = np.array([bound[b << BOUND_SHIFT:(b + 1) << BOUND_SHIFT].max()
                          for b in range(-(-width >> BOUND_SHIFT))]).reshape(1, 1, 1, -1)
        c, threshold = float(rng.uniform(0.5, 2)), float(rng.uniform(0.5, 1.5))
        start = int(rng.integers(0, width))
        end = int(rng.integers(start, width + 1))
        hits = [k for k in range(start, end) if abs(stored[0, 0, 0, k] * c) >= threshold]
        assert skip_below(stored, bound, 0, 0, 0, start, 1, end, c, threshold) == (hits[0] if hits else end)
