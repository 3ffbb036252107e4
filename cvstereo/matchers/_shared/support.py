"""Consistency checks of matches that the thesis does not make: neighbour support and the left-right check.

**Neighbour support**: how many other matches of the same window nearby agree on the disparity.

A correct match on an edge has neighbours on that edge with (nearly) the same disparity; a wrong one (two
unrelated clusters that happen to look alike, a noise event) mostly stands alone. Counting, for each match,
the other matches of its window within :data:`SUPPORT_RADIUS_PX` pixels (in x and in y) whose disparity lies
within :data:`SUPPORT_TOLERANCE_PX` of its own, and keeping only matches with enough such support, removes
most isolated errors at little cost to coverage (on the robustness suite the frame matcher's errors > 2 px fell
from 3 in 10,000 matches to none on most recordings, keeping 94 % of the matches).

Both constants are geometry (pixels of the sensor, pixels of disparity), not signal: they stay absolute.
The count is a pure function of one window's matches, so a streaming matcher and its whole-stream reference
give the same result when both apply it per window.

**Left-right check** (:func:`lr_consistent`): a disparity found scanning one camera's frame stands only where
scanning the other camera's frame finds (nearly) the same disparity at the pixel it names. Its tolerance
(:data:`~cvstereo.matchers._shared.consistency.LR_TOLERANCE_PX`, 1 px) is geometry too. The references count
and check on their own (:mod:`cvstereo.matchers._shared.reference_checks`), plainly, from the same constants.

>>> import numpy as np
>>> x = np.array([10, 11, 12, 40]); y = np.array([5, 5, 6, 5]); d = np.array([3.0, 3.0, 3.5, 3.0])
>>> support_counts(x, y, d, width=64).tolist()     # the last match has no neighbour within 2 px
[2, 2, 2, 0]
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cvstereo.matchers._shared.consistency import LR_TOLERANCE_PX, SUPPORT_RADIUS_PX, SUPPORT_TOLERANCE_PX


@njit(cache=True, nogil=True)
def _count_support(keys, d, radius, pitch, tolerance, counts):  # pragma: no cover - compiled
    """The loop of :func:`support_counts`, compiled, on the matches sorted by pixel key (``keys`` ascending).

    The lowest key of each row of a match's square grows with the match's key, so one pointer per row of the
    square only moves forward: a pass over the matches, without a binary search per match and row.
    """
    n = keys.size
    first = np.zeros(2 * radius + 1, np.int64)  # per row of the square: the first match not below it
    for i in range(n):
        for row in range(2 * radius + 1):
            # Padded rows keep the pixels of one row of the square at consecutive keys.
            low = keys[i] + (row - radius) * pitch - radius
            u = first[row]
            while u < n and keys[u] < low:
                u += 1
            first[row] = u
            while u < n and keys[u] <= low + 2 * radius:
                if u != i and abs(d[u] - d[i]) <= tolerance:
                    counts[i] += 1
                u += 1


def support_counts(x: np.ndarray, y: np.ndarray, disparity: np.ndarray, *, width: int,
                   radius: int = SUPPORT_RADIUS_PX, tolerance: float = SUPPORT_TOLERANCE_PX) -> np.ndarray:
    """For each match of one window, the other matches nearby that agree on its disparity.

    Parameters
    ----------
    x, y : (N,) int ndarray
        Pixel of each match (several matches may share a pixel, e.g. an ON and an OFF one).
    disparity : (N,) float ndarray
    width : int, keyword-only
        Sensor width, px.
    radius : int, keyword-only
        Neighbours lie within ``radius`` px in x and in y.
    tolerance : float, keyword-only
        Largest disparity difference of a supporting neighbour, px.

    Returns
    -------
    (N,) int64 ndarray
        The number of other matches (not the match itself) with ``|dx| <= radius``, ``|dy| <= radius`` and
        ``|disparity difference| <= tolerance``.
    """
    x = np.asarray(x, dtype=np.int64)
    y = np.asarray(y, dtype=np.int64)
    d = np.asarray(disparity, dtype=np.float64)
    n = x.size
    counts = np.zeros(n, dtype=np.int64)
    if n < 2:
        return counts
    pitch = int(width) + 2 * radius  # padded rows: an offset of up to radius never wraps into the next row
    key = (y + radius) * pitch + (x + radius)
    order = np.argsort(key, kind="stable")  # the frame matchers' matches come in pixel order: a linear pass
    sorted_counts = np.zeros(n, dtype=np.int64)
    _count_support(key[order], d[order], int(radius), pitch, float(tolerance), sorted_counts)
    counts[order] = sorted_counts
    return counts


def supported(matches: np.ndarray, min_support: int, *, width: int) -> np.ndarray:
    """The matches of one window with at least ``min_support`` agreeing neighbours (all when it is 0).

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        One window's matches.
    min_support : int
        0 keeps every match (the thesis).
    width : int, keyword-only
        Sensor width, px.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        The kept matches, in their order.
    """
    if min_support <= 0 or matches.size == 0:
        return matches
    counts = support_counts(matches["x"], matches["y"], matches["disparity"], width=width)
    return matches[counts >= min_support]


def lr_consistent(disparity: np.ndarray, other_disparity: np.ndarray, *, reference_camera: int = 1,
                  tolerance: float = LR_TOLERANCE_PX) -> np.ndarray:
    """Left-right check: where the other camera's scan agrees with the reference scan.

    Parameters
    ----------
    disparity, other_disparity : (height, width) float ndarray
        The reference camera's and the other camera's disparity maps (NaN: none), each scanned as reference.
    reference_camera : {0, 1}, keyword-only
    tolerance : float, keyword-only
        Largest difference, px.

    Returns
    -------
    (height, width) bool ndarray
        True where the reference pixel ``(y, x)`` has a disparity d and the other map at the pixel d names
        (``x + d`` when the reference is the right camera, ``x - d`` when it is the left one) holds a disparity
        within ``tolerance`` of d.

    Examples
    --------
    >>> nan = np.nan
    >>> right = np.array([[2.0, 2.0, nan, nan]])
    >>> left = np.array([[nan, nan, 2.0, 0.0]])                  # x_left = x_right + 2
    >>> lr_consistent(right, left, reference_camera=1).tolist()
    [[True, False, False, False]]
    """
    h, w = disparity.shape
    y, x = np.nonzero(~np.isnan(disparity))
    d = disparity[y, x]
    xo = x + (np.rint(d).astype(np.int64) if reference_camera == 1 else -np.rint(d).astype(np.int64))
    inside = (xo >= 0) & (xo < w)
    ok = np.zeros((h, w), dtype=bool)
    y, x, d, xo = y[inside], x[inside], d[inside], xo[inside]
    ok[y, x] = np.abs(other_disparity[y, xo] - d) <= tolerance  # NaN (no disparity there) compares False
    return ok
