"""Fused's segment test (design part 11 of :mod:`cvstereo.matchers.fused.matcher`): which consistent answers of a
window lie in a small segment of like disparity (:func:`small_segments`), and the least size at a sensor's width
(:func:`segment_min_for`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cvstereo.matchers.fused._constants import SEGMENT_RADIUS, SEGMENT_STEP_PX, SEGMENT_WIDTH_PX
from cvstereo.matchers.fused.params import FusedParams

__all__ = ["segment_min_for", "small_segments"]


def segment_min_for(params: FusedParams, width: int) -> int:
    """The segment test's least answers at a sensor ``width`` px wide: ``segment_min_answers`` scaled from 128 px,
    rounded (0: off)."""
    return round(params.segment_min_answers * width / SEGMENT_WIDTH_PX)


@njit(cache=True, nogil=True)
def small_segments(x, y, disparity, judged, grid, min_answers):
    """The segment test (``segment_min_answers``): which of the ``judged`` answers lie in a segment of fewer than
    ``min_answers`` judged answers.

    A segment: judged answers joined, one to the next, by lying within :data:`SEGMENT_RADIUS` px (Chebyshev) of
    each other with disparities at most :data:`SEGMENT_STEP_PX` apart.

    Parameters
    ----------
    x, y : (M,) int ndarrays
        The answers' pixels (one answer per pixel).
    disparity : (M,) float64 ndarray
    judged : (M,) bool ndarray
    grid : (H, W) int64 ndarray
        All -1 (scratch; left so).
    min_answers : int

    Returns
    -------
    (M,) bool ndarray
    """
    m = x.size
    h, w = grid.shape
    small = np.zeros(m, np.bool_)
    for i in range(m):
        if judged[i]:
            grid[y[i], x[i]] = i
    seen = np.zeros(m, np.bool_)
    members = np.empty(m, np.int64)
    for i in range(m):
        if not judged[i] or seen[i]:
            continue
        seen[i] = True
        members[0] = i
        n, k = 1, 0
        while k < n:  # breadth first: members[k] is the next answer whose neighbours are looked at
            j = members[k]
            k += 1
            for yy in range(max(y[j] - SEGMENT_RADIUS, 0), min(y[j] + SEGMENT_RADIUS + 1, h)):
                for xx in range(max(x[j] - SEGMENT_RADIUS, 0), min(x[j] + SEGMENT_RADIUS + 1, w)):
                    q = grid[yy, xx]
                    if q >= 0 and not seen[q] and abs(disparity[q] - disparity[j]) <= SEGMENT_STEP_PX:
                        seen[q] = True
                        members[n] = q
                        n += 1
        if n < min_answers:
            for k in range(n):
                small[members[k]] = True
    for i in range(m):
        if judged[i]:
            grid[y[i], x[i]] = -1
    return small
