"""The windows of a whole stream and their frames, for the reference frame matchers, written plainly.

The windows are ``[k*W, (k+1)*W)`` on the absolute clock. The frames are made here from their definitions
(docs/algorithms.md, matcher 1): the signed frame is a scatter-add of the events' signs, and the Gaussian a direct
2-D convolution with the kernel built from its formula, zero outside the sensor. The fast path
(:mod:`cvstereo.frames.accumulate`: one compiled pass over the events, then ``cv2.GaussianBlur``) shares none of
this code, so a slip in either is a difference the fast == reference tests see.

>>> np.round(gaussian_kernel(5, 1.0), 4).tolist()   # thesis eq. 3.6, one axis
[0.0545, 0.2442, 0.4026, 0.2442, 0.0545]
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

__all__ = ["filtered_unit", "gaussian_filter", "gaussian_kernel", "signed_frame", "values_at_events",
           "window_events"]


def window_events(left: np.ndarray, right: np.ndarray, window_us: int, *,
                  every: bool = False) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """``(t_end, left events, right events)`` of every window in which both cameras have events, in time order.

    A window in which one camera is silent has no match in any frame matcher (nothing to pair with); with
    ``every`` such windows are yielded too (their values still feed the signal level of relative thresholds).
    """
    ks = np.union1d(left["t"] // window_us, right["t"] // window_us)
    for k in ks.tolist():
        ev_l = left[left["t"] // window_us == k]
        ev_r = right[right["t"] // window_us == k]
        if every or (ev_l.size and ev_r.size):
            yield (k + 1) * window_us, ev_l, ev_r


def values_at_events(frame: np.ndarray, events: np.ndarray) -> np.ndarray:
    """The values of ``frame`` at each distinct pixel of ``events``: what a frame matcher's signal level sees
    (:mod:`cvstereo.matchers._shared.signal_level`)."""
    seen = np.zeros(frame.shape, bool)
    seen[events["y"], events["x"]] = True
    return frame[seen]


def signed_frame(events: np.ndarray, *, resolution: tuple[int, int], signs: tuple[int, ...]) -> np.ndarray:
    """(height, width) float32 sum of the signs of the events at each pixel (ON +1, OFF -1), counting only the
    events whose sign is in ``signs`` (thesis eq. 3.3-3.5: 10 OFF + 2 ON at a pixel give -8)."""
    width, height = resolution
    frame = np.zeros((height, width), np.float32)
    sign = np.where(events["p"] > 0, 1, -1)
    kept = np.isin(sign, signs)
    np.add.at(frame, (events["y"][kept], events["x"][kept]), sign[kept].astype(np.float32))
    return frame


def gaussian_kernel(size: int, sigma: float) -> np.ndarray:
    """(size,) float64 weights ``exp(-(i - c)^2 / (2 sigma^2))``, c the centre, divided by their sum: one axis of
    the rotationally symmetric Gaussian (thesis eq. 3.6 for frames, eq. 3.8 for dynamic frames)."""
    centre = (size - 1) / 2
    weights = [math.exp(-((i - centre) ** 2) / (2 * sigma * sigma)) for i in range(size)]
    total = sum(weights)
    return np.array([w / total for w in weights])


def gaussian_filter(frame: np.ndarray, *, sigma: float, kernel_size: int) -> np.ndarray:
    """The thesis' Gaussian low-pass of one frame, zero outside the sensor: ``out[y, x] = sum of K[i, j] *
    frame[y + i - r, x + j - r]`` with K the outer product of :func:`gaussian_kernel` and r its radius, rounded
    once to float32 (the frames' type).

    The frame values are whole numbers (sums of signs), so the sum is taken weight by weight: the values under
    the offsets that share one weight (the symmetric ones, ``(|i - r|, |j - r|)`` in either order) are added
    exactly, and only those sums are multiplied and added. A configuration that cancels by symmetry then gives
    exactly 0, as the definition does (summed offset by offset, float64 left 3e-17 where +3 and -3 faced each
    other, and the sign of the value decides a match's polarity).
    """
    g = gaussian_kernel(kernel_size, sigma)
    r = kernel_size // 2
    height, width = frame.shape
    padded = np.zeros((height + 2 * r, width + 2 * r))  # zero outside the sensor: there are no events there
    padded[r:r + height, r:r + width] = frame
    by_weight: dict[tuple[int, int], np.ndarray] = {}
    for i in range(kernel_size):
        for j in range(kernel_size):
            key = tuple(sorted((abs(i - r), abs(j - r))))
            by_weight[key] = by_weight.get(key, 0) + padded[i:i + height, j:j + width]
    out = np.zeros((height, width))
    for (a, b), values in sorted(by_weight.items()):
        out += (g[r + a] * g[r + b]) * values
    return out.astype(np.float32)


def filtered_unit(params) -> float:
    """The filtered value of one isolated event (the Gaussian's centre weight, as float32), or 1 without the
    filter: the unit of a relative threshold's floor. ``params`` has gaussian, kernel_sigma and kernel_size."""
    if not params.gaussian:
        return 1.0
    g = gaussian_kernel(params.kernel_size, params.kernel_sigma)
    centre = params.kernel_size // 2
    return float(np.float32(g[centre] * g[centre]))
