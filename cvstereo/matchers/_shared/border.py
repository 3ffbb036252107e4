"""The border rule: no answer where the matcher's own evidence says the true partner lies outside the other image.

A left pixel at column ``x`` whose true disparity ``D`` exceeds ``x`` has its partner at ``x - D < 0``, outside
the right camera's image (and a right pixel at ``x`` with ``x + D > W - 1`` outside the left one's). Every
matcher still answers there: it finds the best look-alike among the candidates it has, all of them at
disparities ``<= x``, so each such answer is wrong, and the strip is ``D`` columns wide (a quarter of the image
at a quarter-width disparity). A blanket "no answer at ``x < max_disparity``" would cost that quarter of the
image everywhere, also where the scene is far.

What a matcher can know about the true disparity at a border pixel is what it answered nearby, just inward of
it, where the partner is inside the other image: the strip's look-alikes all lie at ``d <= x``, while the
surface continuing inward carries its true disparity. So the rule refuses a match anchored on the left camera at
``(x, y)`` when, in any of the rows ``y - border_rows ... y + border_rows``, the nearest earlier *accepted* match
to its right (anchored on the same camera, not older than ``border_horizon_us``) has a disparity larger than
``x``; and mirrored for the right camera (the nearest accepted match to its left has a disparity larger than
``W - 1 - x``). Only accepted matches are evidence: a refused look-alike says nothing of the surface, and
keeping refused ones would let the strip's small disparities vouch for their neighbours. Far from the border
(``x >=`` every recent disparity) nothing is refused, so the rule costs coverage only where a nearer surface
lies beside a farther one at the image's edge.

The rule sees matches in the order a matcher returns them (time order), so its decisions depend only on that
sequence: streaming, deterministic, independent of how the stream was cut into packets.

>>> import numpy as np
>>> from cvstereo.model.matches import make_matches
>>> rule = BorderRule((32, 4), horizon_us=1000, rows=0)
>>> plane = make_matches(t=[10, 10, 10], x=[20, 12, 5], y=[1, 1, 1], p=[1, 1, 1], camera=[0, 0, 0],
...                      disparity=[8.0, 8.0, 4.0])
>>> rule(plane)["x"].tolist()     # x = 5 answers 4 px, but the surface beside it is 8 px away: refused
[20, 12]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from cvstereo.matchers._shared.consistency import BORDER_OFF as OFF
from cvstereo.matchers._shared.consistency import BORDER_VOTES as VOTES
from cvstereo.matchers.constraints import DeclaredParams, param

#: Time before the first match: no evidence yet.
_NEVER = np.iinfo(np.int64).min // 2


@dataclass(frozen=True, kw_only=True)
class BorderParams(metaclass=DeclaredParams):
    """The border rule's fields, shared by every matcher that has it (:mod:`cvstereo.matchers._shared.border`).

    Attributes
    ----------
    border_horizon_us : int
        How long an accepted match stays evidence of the surface beside it, us; 0 (the thesis): the rule is off.
    border_rows : int
        Rows above and below a match whose evidence counts (a surface spans rows; a rig's rows may be 1-2 apart).
    """

    border_horizon_us: int = param(OFF, ge=0, note="0: no border rule")
    border_rows: int = param(1, ge=0)


def border_rule_for(params, resolution) -> BorderRule | None:
    """The rule a matcher with ``params`` applies to its matches, or None where it has no rule or it is off."""
    horizon = getattr(params, "border_horizon_us", OFF)
    if horizon == OFF:
        return None
    return BorderRule(resolution, horizon_us=horizon, rows=params.border_rows)


class BorderRule:
    """Streaming filter of matches: refuses those the border rule refuses (module docstring), keeps the rest.

    Parameters
    ----------
    resolution : (width, height)
    horizon_us : int
        How long an accepted match stays evidence, us (> 0).
    rows : int
        Row radius of the evidence.
    """

    def __init__(self, resolution, *, horizon_us: int, rows: int):
        width, height = (int(v) for v in resolution)
        if horizon_us <= 0 or rows < 0:
            raise ValueError(f"BorderRule: horizon_us must be > 0 and rows >= 0, got {horizon_us} and {rows}.")
        self.horizon_us = int(horizon_us)
        self.rows = int(rows)
        #: Per anchor camera, row and column: the disparity of the last accepted match there, and its time.
        self._disparity = np.zeros((2, height, width), np.float32)
        self._time = np.full((2, height, width), _NEVER, np.int64)
        #: Per anchor camera, the largest disparity ever accepted: a match with more room than that is kept
        #: without looking for evidence.
        self._largest = np.zeros(2, np.float32)

    def __call__(self, matches: np.ndarray) -> np.ndarray:
        """The matches the rule keeps, in their order; the accepted ones become evidence for later matches."""
        if not matches.size:
            return matches
        # Matches of one time (a window's) are decided inward first, so that the window's own answers away
        # from the border are evidence for its answers near it, whatever order the matcher lists them in.
        width = self._disparity.shape[2]
        order = np.empty(matches.size, np.int64)
        if not _inward_order(matches["t"], matches["x"], matches["camera"], width, order):
            # Not in time order (the matchers' contract; a caller's own matches may not be): a full sort.
            x = matches["x"].astype(np.int64)
            order = np.lexsort((-np.where(matches["camera"] == 0, x, width - 1 - x), matches["t"]))
        keep = _border_keep(order, matches["t"], matches["x"], matches["y"], matches["camera"],
                            matches["disparity"], self._disparity, self._time, self._largest, self.horizon_us,
                            self.rows)
        return matches if keep.all() else matches[keep]


#: Runs of equal times up to this long are ordered by an insertion sort (no allocation), longer ones by a counting
#: sort (:func:`_counting_order`).
_SHORT_RUN = 32


@njit(cache=True, nogil=True, inline="always")
def _room(x, camera, k, width):
    """Match ``k``'s room: the columns between its pixel and the image's edge on the side where its partner lies."""
    return np.int64(x[k]) if camera[k] == 0 else width - 1 - np.int64(x[k])


@njit(cache=True, nogil=True)
def _inward_order(t, x, camera, width, order):
    """Write into ``order`` the order in which the rule decides time-ordered matches: by time, at equal times by
    room (:meth:`BorderRule.__call__`) largest first, ties in their given order (``np.lexsort((-room, t))``, which
    a stable sort of each run of equal times gives without sorting the whole); False if ``t`` is not in order."""
    n = t.size
    i = 0
    while i < n:
        j = i + 1
        while j < n and t[j] == t[i]:
            j += 1
        if j < n and t[j] < t[i]:
            return False
        if j - i <= _SHORT_RUN:  # a stable insertion sort by room, largest first
            for k in range(i, j):
                room = _room(x, camera, k, width)
                m = k
                while m > i:
                    prev = order[m - 1]
                    if _room(x, camera, prev, width) >= room:
                        break
                    order[m] = prev
                    m -= 1
                order[m] = k
        else:  # a stable counting sort by room, largest first: rooms are columns, 0 .. width - 1
            _counting_order(x, camera, width, i, j, order)
        i = j
    return True


@njit(cache=True, nogil=True)
def _counting_order(x, camera, width, first, stop, order):
    """:func:`_inward_order` of the run ``first .. stop - 1`` (one time): ``order[first:stop]`` by room, largest
    first, ties in their given order. A counting sort over the ``width`` possible rooms (one pass to count, one to
    place) where a comparison sort of a dense window's thousands of matches cost more than the rule itself; a
    room off the sensor (a caller's own matches) falls back to a merge sort."""
    count = np.zeros(width, np.int64)  # count[width - 1 - room], then where that room's matches start
    for k in range(first, stop):
        room = _room(x, camera, k, width)
        if room < 0 or room >= width:
            key = np.empty(stop - first, np.int64)
            for kk in range(first, stop):
                key[kk - first] = -_room(x, camera, kk, width)
            sub = np.argsort(key, kind="mergesort")
            for kk in range(stop - first):
                order[first + kk] = first + sub[kk]
            return
        count[width - 1 - room] += 1
    start = first
    for r in range(width):
        n = count[r]
        count[r] = start
        start += n
    for k in range(first, stop):
        r = width - 1 - _room(x, camera, k, width)
        order[count[r]] = k
        count[r] += 1


@njit(cache=True, nogil=True)
def _border_keep(order, t, x, y, camera, disparity, last_d, last_t, largest, horizon, rows):
    """Keep-mask of the border rule over matches taken in ``order`` (time, then inward first); records each
    accepted match as evidence."""
    height, width = last_d.shape[1], last_d.shape[2]
    keep = np.ones(t.size, np.bool_)
    for i in order:
        cam = camera[i]
        if cam > 1:
            continue
        xi, yi = int(x[i]), int(y[i])
        oldest = t[i] - horizon
        # Room between the pixel and the image's edge on the side where its partner lies.
        room = xi if cam == 0 else width - 1 - xi
        step = 1 if cam == 0 else -1
        # The rows vote, nearest first: each row's nearest accepted match on the inward side says whether the
        # surface there lies nearer than the room allows; a majority of the first VOTES rows that hold one
        # refuses (a lone outlier does not), and a sparse matcher looks further for them.
        above = 0
        within = 0
        reach = rows if room < largest[cam] else -1  # no evidence can exceed the room: nothing to look at
        for k in range(2 * reach + 1):
            yy = yi + (k + 1) // 2 if k % 2 else yi - k // 2
            if yy < 0 or yy >= height:
                continue
            xx = xi + step
            while 0 <= xx < width:
                if last_t[cam, yy, xx] >= oldest:
                    if last_d[cam, yy, xx] > room:
                        above += 1
                    else:
                        within += 1
                    break
                xx += step
            if above + within == VOTES:
                break
        if above > within:
            keep[i] = False
        else:
            last_d[cam, yi, xi] = disparity[i]
            last_t[cam, yi, xi] = t[i]
            largest[cam] = max(largest[cam], disparity[i])
    return keep
