"""Reference implementations of the event matchers: plain Python that follows ``algorithms.md`` line by line.

They are slow (use them on short inputs) and exist so that tests can check the fast numba matchers against
them: same anchors, same disparities, bit for bit. Each takes the whole stream at once and returns a
time-ordered matches array. In relative threshold mode they feed the same signal-level estimator
(:class:`cvstereo.signal_level.SignalLevel`) with the values they compute, window by window, one event at a time.
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


class LevelByWindow:
    """The thresholds of a :class:`~cvstereo.signal_level.SignalLevel` for events met one at a time, in time order.

    :meth:`at` returns the thresholds in force for the event's absolute window; :meth:`seen` records the value the
    event read (per camera), handed to the estimator when its window is complete.
    """

    def __init__(self, params, *, value_name: str = "dynamic-frame value"):
        from calibration_free._event_common import dynamic_unit
        from cvstereo.signal_level import SignalLevel

        self.level = SignalLevel(params, absolute=params.threshold, unit=dynamic_unit(params), value_name=value_name)
        self.window_us = int(params.level_window_us)
        self.current: int | None = None
        self.values: tuple[list[float], list[float]] = ([], [])
        self.thresholds = None

    def at(self, t: int):
        """The (2,) thresholds in force at time ``t``."""
        k = int(t) // self.window_us
        if k != self.current:
            self.close()
            self.current = k
            self.thresholds = self.level.thresholds(k)
        return self.thresholds

    def seen(self, cam: int, value: float) -> None:
        self.values[cam].append(abs(value))

    def close(self) -> None:
        if self.current is not None:
            for cam in (0, 1):
                self.level.add(self.current, cam, np.array(self.values[cam]))
        self.values = ([], [])


def sign(value: float) -> int:
    """-1, 0 or +1."""
    return 1 if value > 0 else (-1 if value < 0 else 0)
