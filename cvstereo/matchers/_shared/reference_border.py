"""Reference border rule: the rule of :mod:`cvstereo.matchers._shared.border`, one match at a time in plain Python.

No answer near the image's edge where the matcher's own recent answers further inward put the partner outside
the other camera's image. Restated here from its definition (the border module's docstring), so that the
references of the matchers that follow it (every thesis matcher under the ``adaptive`` set) give the fast
matchers' output without calling the compiled rule:

- the matches are decided in time order, and at one time inward first (the most room first, then in their
  order); ``room`` is the distance to the edge on the side of the partner (``x`` for a left-anchored match,
  ``W - 1 - x`` for a right-anchored one);
- a match with no more room than the largest disparity accepted so far (for its anchor camera) looks at the
  rows ``y, y+1, y-1, y+2, y-2, ...`` up to ``border_rows`` away: in each, the nearest pixel inward whose last
  accepted match is at most ``border_horizon_us`` old votes "above" if that disparity exceeds the room, else
  "within"; the first :data:`~cvstereo.matchers._shared.consistency.BORDER_VOTES` rows with a vote count;
- more "above" than "within" refuses it; otherwise it is accepted, and becomes the evidence of its pixel.

>>> from cvstereo.model.matches import make_matches
>>> plane = make_matches(t=[10, 10, 10], x=[20, 12, 5], y=[1, 1, 1], p=[1, 1, 1], camera=[0, 0, 0],
...                      disparity=[8.0, 8.0, 4.0])
>>> border_filter(plane, horizon_us=1000, rows=0, resolution=(32, 4))["x"].tolist()   # x = 5 lies in the strip
[20, 12]
"""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.consistency import BORDER_OFF, BORDER_VOTES

__all__ = ["border_filter", "border_rule_of"]


def border_filter(matches: np.ndarray, *, horizon_us: int, rows: int, resolution: tuple[int, int]) -> np.ndarray:
    """The matches (MATCH_DTYPE, time-ordered: a whole stream's) the border rule keeps, in their order."""
    width, height = (int(v) for v in resolution)
    # Per anchor camera, row and column: the time and disparity of the last match accepted there.
    seen = np.zeros((2, height, width), bool)
    last_t = np.zeros((2, height, width), np.int64)
    last_d = np.zeros((2, height, width))
    largest = [0.0, 0.0]
    keep = np.ones(matches.size, bool)
    room = [int(m["x"]) if m["camera"] == 0 else width - 1 - int(m["x"]) for m in matches]
    for i in sorted(range(matches.size), key=lambda i: (int(matches["t"][i]), -room[i], i)):
        m = matches[i]
        cam, x, y, t, d = int(m["camera"]), int(m["x"]), int(m["y"]), int(m["t"]), float(m["disparity"])
        if cam > 1:
            continue
        votes = []
        if room[i] < largest[cam]:  # else no evidence can exceed the room
            for k in range(2 * rows + 1):
                row = y + (k + 1) // 2 if k % 2 else y - k // 2
                if not 0 <= row < height:
                    continue
                # The row's columns inward of x, nearest first, and which of them hold recent evidence.
                inward = np.arange(x + 1, width) if cam == 0 else np.arange(x - 1, -1, -1)
                recent = inward[seen[cam, row, inward] & (last_t[cam, row, inward] >= t - horizon_us)]
                if recent.size:
                    votes.append(last_d[cam, row, recent[0]] > room[i])
                if len(votes) == BORDER_VOTES:
                    break
        if sum(votes) > len(votes) - sum(votes):
            keep[i] = False
        else:
            seen[cam, y, x], last_t[cam, y, x], last_d[cam, y, x] = True, t, d
            largest[cam] = max(largest[cam], d)
    return matches[keep]


def border_rule_of(matches: np.ndarray, params, resolution: tuple[int, int]) -> np.ndarray:
    """``matches`` after the border rule of ``params`` (its ``border_horizon_us`` and ``border_rows``); all of them
    where the rule is off or the parameters have none."""
    horizon = getattr(params, "border_horizon_us", BORDER_OFF)
    if horizon == BORDER_OFF:
        return matches
    return border_filter(matches, horizon_us=int(horizon), rows=int(params.border_rows), resolution=resolution)
