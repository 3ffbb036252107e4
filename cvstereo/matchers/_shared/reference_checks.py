"""Reference consistency checks: neighbour support and the left-right check, written plainly from their definitions.

The independent twins of :mod:`cvstereo.matchers._shared.support` (which counts support in one compiled pass over
matches sorted by pixel key, and checks left-right with fancy indexing): here every pair of matches is compared
and every pixel visited, so that a bug in either is a difference the fast == reference tests see. Both read the
constants of :mod:`cvstereo.matchers._shared.consistency`.

>>> x = np.array([10, 11, 12, 40]); y = np.array([5, 5, 6, 5]); d = np.array([3.0, 3.0, 3.5, 3.0])
>>> support_counts(x, y, d).tolist()              # the last match has no neighbour within 2 px
[2, 2, 2, 0]
"""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.consistency import LR_TOLERANCE_PX, SUPPORT_RADIUS_PX, SUPPORT_TOLERANCE_PX

__all__ = ["lr_consistent", "support_counts", "supported"]


def support_counts(x: np.ndarray, y: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """For each match of one window, the number of *other* matches with ``|dx| <= SUPPORT_RADIUS_PX``,
    ``|dy| <= SUPPORT_RADIUS_PX`` and a disparity within ``SUPPORT_TOLERANCE_PX`` of its own.

    Every pair is compared (one row of comparisons per match), so matches sharing a pixel count each other.
    """
    x, y = np.asarray(x, np.int64), np.asarray(y, np.int64)
    d = np.asarray(disparity, np.float64)
    counts = np.zeros(x.size, np.int64)
    for i in range(x.size):
        near = ((np.abs(x - x[i]) <= SUPPORT_RADIUS_PX) & (np.abs(y - y[i]) <= SUPPORT_RADIUS_PX)
                & (np.abs(d - d[i]) <= SUPPORT_TOLERANCE_PX))
        counts[i] = int(near.sum()) - 1  # the match itself is near
    return counts


def supported(matches: np.ndarray, min_support: int) -> np.ndarray:
    """The matches of one window (MATCH_DTYPE) with at least ``min_support`` supporting neighbours, in their order;
    all of them when ``min_support`` is 0 (the thesis)."""
    if min_support <= 0:
        return matches
    return matches[support_counts(matches["x"], matches["y"], matches["disparity"]) >= min_support]


def lr_consistent(disparity: np.ndarray, other_disparity: np.ndarray, *, reference_camera: int) -> np.ndarray:
    """Left-right check, pixel by pixel: True where the reference map holds a disparity d at (y, x) and the other
    camera's map, at the pixel d names on the same row (``x + d`` from the right camera, ``x - d`` from the left;
    d rounded half to even), holds a disparity within ``LR_TOLERANCE_PX`` of d.

    A pixel named outside the sensor, or holding no disparity (NaN), fails the check.
    """
    width = disparity.shape[1]
    ok = np.zeros(disparity.shape, bool)
    direction = 1 if reference_camera == 1 else -1
    for y, x in zip(*np.nonzero(~np.isnan(disparity)), strict=True):
        d = float(disparity[y, x])
        xo = x + direction * round(d)
        if 0 <= xo < width:
            other = float(other_disparity[y, xo])
            ok[y, x] = not np.isnan(other) and abs(other - d) <= LR_TOLERANCE_PX
    return ok
