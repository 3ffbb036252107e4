"""Small numeric helpers the estimators share: sub-sample peaks, peak contrast and width, confidences."""

from __future__ import annotations

import numpy as np

__all__ = ["clip01", "contrast", "fft_len", "half_width", "smooth_lags", "subsample_peak", "support"]


def subsample_peak(v, i):
    """Sub-sample position of the peak at index ``i`` by a parabola through its neighbours."""
    if i <= 0 or i >= len(v) - 1:
        return float(i)
    a, b, c = float(v[i - 1]), float(v[i]), float(v[i + 1])
    den = a - 2 * b + c
    return float(i) if den >= 0 else float(i + 0.5 * (a - c) / den)


def contrast(v, i, *, exclude):
    """How much the peak at ``i`` stands out: 1 - (best value beyond ``exclude`` samples of it) / (peak value),
    both measured above the median of ``v``; clipped to [0, 1]."""
    base = float(np.median(v))
    peak = float(v[i]) - base
    if peak <= 0:
        return 0.0
    out = np.ones(len(v), bool)
    out[max(0, i - exclude):i + exclude + 1] = False
    if not out.any():
        return 1.0
    return clip01(1.0 - max(float(v[out].max()) - base, 0.0) / peak)


def half_width(v, i):
    """Samples from the peak at ``i`` to where ``v`` first falls below half the peak's height above the median."""
    base = float(np.median(v))
    half = base + 0.5 * (float(v[i]) - base)
    below = np.flatnonzero(v < half)
    left = below[below < i]
    right = below[below > i]
    reach = [i - int(left[-1]) if left.size else i, int(right[0]) - i if right.size else len(v) - 1 - i]
    return max(1, max(reach))


def smooth_lags(c, sigma):
    """Gaussian smoothing along the last axis (lags)."""
    radius = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    k /= k.sum()
    return np.apply_along_axis(lambda v: np.convolve(v, k, mode="same"), -1, c)


def support(n_left, n_right, scale=500.0):
    """How far an estimate from ``n_left`` and ``n_right`` events can be trusted on count alone, in [0, 1)."""
    return float(1.0 - np.exp(-min(n_left, n_right) / scale))


def fft_len(n):
    """The smallest even length >= n whose only prime factors are 2, 3 and 5 (pocketfft is fast there, and
    such lengths lie much closer above n than the next power of two)."""
    n = max(2, int(n))
    best = 1 << int(np.ceil(np.log2(n)))
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35 * 2
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def clip01(v):
    """``v`` clipped to [0, 1], as a float."""
    return float(min(1.0, max(0.0, v)))
