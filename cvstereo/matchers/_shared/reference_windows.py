"""The windows of a whole stream, for the reference frame matchers: ``[k*W, (k+1)*W)`` on the absolute clock."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np


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
