"""Signed event frames of busy windows, the input of the row and disparity stages."""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import cv2
import numpy as np

from cvstereo.frames.accumulate import signed_frame

__all__ = ["WindowFrames", "window_frames"]


class WindowFrames(NamedTuple):
    """One window busy in both cameras."""

    left: np.ndarray
    """(H, W) float32 Gaussian-smoothed signed frame of the left camera."""
    right: np.ndarray
    """The same of the right camera."""
    left_events: np.ndarray
    """(H, W) bool: pixels where the left camera had events."""


def window_frames(left, right, *, resolution, window_us, max_windows, min_events, blur_px) -> Iterator[WindowFrames]:
    """Yield :class:`WindowFrames` for windows of ``window_us`` with at least ``min_events`` events in each camera.

    At most ``max_windows`` windows, evenly spread over the recording; frames smoothed by a 3x3 Gaussian of sigma
    ``blur_px``.
    """
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    t1 = max(int(left["t"][-1]), int(right["t"][-1])) + 1
    starts = np.arange(t0 - t0 % window_us, t1, window_us)
    edges = np.append(starts, starts[-1] + window_us)
    idx = [np.searchsorted(ev["t"], edges) for ev in (left, right)]
    busy = np.flatnonzero((np.diff(idx[0]) >= min_events) & (np.diff(idx[1]) >= min_events))
    if busy.size > max_windows:
        busy = busy[np.linspace(0, busy.size - 1, max_windows).round().astype(int)]
    for k in busy:
        frames = [signed_frame(ev[i[k]:i[k + 1]], resolution=resolution)
                  for ev, i in ((left, idx[0]), (right, idx[1]))]
        # A little smoothing so that events one pixel apart still overlay (jitter, distortion).
        gl, gr = (cv2.GaussianBlur(f, (3, 3), blur_px, borderType=cv2.BORDER_CONSTANT) for f in frames)
        yield WindowFrames(gl, gr, frames[0] != 0)
