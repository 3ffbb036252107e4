"""Random valid event streams and recordings for the I/O tests (plain numpy and hypothesis strategies)."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording


def random_events(rng: np.random.Generator, n: int, resolution=(128, 128), *, t0: int = 0,
                  max_step: int = 50) -> np.ndarray:
    """``n`` valid, time-ordered events (repeated timestamps included) of EVENT_DTYPE."""
    t = t0 + np.cumsum(rng.integers(0, max_step, n))
    return make_events(t, rng.integers(0, resolution[0], n), rng.integers(0, resolution[1], n), rng.integers(0, 2, n))


def random_recording(rng: np.random.Generator, n_left: int, n_right: int, resolution=(128, 128), *,
                     truth: bool = False, meta: dict | None = None) -> Recording:
    """A recording of random events; with ``truth``, disparities with some NaN."""
    left, right = random_events(rng, n_left, resolution), random_events(rng, n_right, resolution)
    ld = rd = None
    if truth:
        ld, rd = (np.where(rng.random(n) < 0.3, np.nan, rng.uniform(0, 30, n)).astype(np.float32)
                  for n in (n_left, n_right))
    return Recording(left, right, ld, rd, resolution, meta or {})


@st.composite
def recordings(draw, *, resolution=(128, 128), truth: bool = False, max_events: int = 200) -> Recording:
    """Hypothesis strategy: a random valid recording (either camera may be empty)."""
    seed = draw(st.integers(0, 2**32 - 1))
    n_left, n_right = draw(st.integers(0, max_events)), draw(st.integers(0, max_events))
    return random_recording(np.random.default_rng(seed), n_left, n_right, resolution, truth=truth)


def assert_same_events(a: np.ndarray, b: np.ndarray) -> None:
    """Equal event arrays (dtype and every field)."""
    assert a.dtype == b.dtype
    np.testing.assert_array_equal(a, b)


def textured_blobs(seed: int = 0, windows: int = 4, *, disparity: int = 13, window_us: int = 40_000) -> Recording:
    """Textured 5x4 blobs, three events a pixel, twelve a 40 ms window, seen by the right camera ``disparity``
    px to the left: frame matchers find them; the truth is ``disparity`` for every event."""
    rng = np.random.default_rng(seed)
    xs, ys, ps, ts = [], [], [], []
    for k in range(windows):
        for _ in range(12):
            yy, xx = np.mgrid[0:4, 0:5]
            x0, y0 = rng.integers(20, 120), rng.integers(3, 120)
            n = xx.size * 3
            xs.append(np.repeat((xx + x0).ravel(), 3))
            ys.append(np.repeat((yy + y0).ravel(), 3))
            ps.append(np.full(n, rng.integers(0, 2)))
            ts.append(rng.integers(k * window_us, (k + 1) * window_us, n))
    x, y, p, t = (np.concatenate(a) for a in (xs, ys, ps, ts))
    order = np.argsort(t, kind="stable")
    x, y, p, t = x[order], y[order], p[order], t[order]
    truth = np.full(t.size, disparity, np.float32)
    return Recording(make_events(t, x, y, p), make_events(t, x - disparity, y, p), truth, truth.copy())
