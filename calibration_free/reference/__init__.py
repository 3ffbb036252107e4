"""Reference implementations of the event matchers: plain Python that follows ``algorithms.md`` line by line.

They are slow (use them on short inputs) and exist so that tests can check the fast numba matchers against
them: same anchors, same disparities, bit for bit. Each takes the whole stream at once and returns a
time-ordered matches array.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np


def merged_events(left: np.ndarray, right: np.ndarray) -> Iterator[tuple[int, int, np.void]]:
    """Both cameras' events in the one order the event matchers use: by time, left first at equal times.

    Yields
    ------
    (camera, index, event)
    """
    i = j = 0
    while i < left.size or j < right.size:
        if j >= right.size or (i < left.size and left["t"][i] <= right["t"][j]):
            yield 0, i, left[i]
            i += 1
        else:
            yield 1, j, right[j]
            j += 1


def sign(value: float) -> int:
    """-1, 0 or +1."""
    return 1 if value > 0 else (-1 if value < 0 else 0)
