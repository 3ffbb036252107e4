"""Reference dynamic frames of one camera: plain Python, one operation at a time.

The twin of :class:`cvstereo.dynamic_frames.FrameBank` (the numba state the fast matchers use): the same
float64 operations in the same order, so both agree bit for bit (see :mod:`cvstereo.dynamic_frames` for
the rules: lazy decay with one scale factor, renormalisation, forgetting after a long gap).

>>> frames = DynamicFrames()
>>> frames.add_event(t=0, x=5, y=5, p=1)
>>> round(frames.value(0, 5, 5), 4), round(frames.value(0, 4, 4), 4)
(0.4084, 0.1502)
"""

from __future__ import annotations

import numpy as np

from cvstereo.dynamic_frames import FORGET_TICKS, RENORM, DynamicFrameParams, update_kernel
from cvstereo.events import DEFAULT_RESOLUTION
from cvstereo.polarity import ON, slot_of_p


class DynamicFrames:
    """Reference dynamic frames of one camera: plain Python, one operation at a time.

    Parameters
    ----------
    params : DynamicFrameParams, optional
    resolution : (width, height), keyword-only

    Attributes
    ----------
    stored : (n_frames, H, W) float64 ndarray
        The stored frames S; the values are ``stored * scale``.
    scale : float
        The lazy decay factor c.
    next_tick : int
        Index k of the next decay tick, due at ``k * decay_period_us``.
    touched : bool
        Whether any event has been added since the frames were last clear.
    """

    def __init__(self, params: DynamicFrameParams | None = None, *,
                 resolution: tuple[int, int] = DEFAULT_RESOLUTION):
        self.params = params if params is not None else DynamicFrameParams()
        self.n_frames, self.slot_of_p = slot_of_p(self.params.polarity)
        self.kernel = update_kernel(self.params)
        width, height = resolution
        self.stored = np.zeros((self.n_frames, height, width))
        self.scale = 1.0
        self.next_tick = 0
        self.touched = False

    def slot(self, p: int) -> int:
        """Frame index of polarity ``p`` (1 ON, 0 OFF), -1 if that polarity is dropped."""
        return int(self.slot_of_p[ON if p > 0 else 0])

    def advance(self, t: int) -> None:
        """Apply every decay tick at ``k * period <= t`` not yet applied (call before an event at t)."""
        period = self.params.decay_period_us
        if self.touched and t // period + 1 - self.next_tick > FORGET_TICKS:
            self.stored[...] = 0.0
            self.scale = 1.0
            self.touched = False
        if not self.touched:
            # The frames are zero: skip the ticks.
            self.next_tick = t // period + 1
            return
        while self.next_tick * period <= t:
            self.scale = self.scale * self.params.decay
            if self.scale < RENORM:
                self.stored *= self.scale
                self.scale = 1.0
            self.next_tick += 1

    def add(self, slot: int, x: int, y: int, sign: float) -> None:
        """Add ``sign * kernel`` centred on (x, y) to frame ``slot``, clipped at the border."""
        k = self.kernel.shape[0]
        r = k // 2
        _, height, width = self.stored.shape
        for j in range(k):
            yy = y + j - r
            if yy < 0 or yy >= height:
                continue
            for i in range(k):
                xx = x + i - r
                if xx < 0 or xx >= width:
                    continue
                self.stored[slot, yy, xx] += sign * self.kernel[j, i] / self.scale
        self.touched = True

    def value(self, slot: int, x: int, y: int) -> float:
        """Current value of frame ``slot`` at (x, y)."""
        return float(self.stored[slot, y, x] * self.scale)

    def add_event(self, *, t: int, x: int, y: int, p: int) -> None:
        """Advance to t and add one event (dropped if its polarity is not kept)."""
        slot = self.slot(p)
        if slot < 0:
            return
        self.advance(t)
        self.add(slot, x, y, 1.0 if p > 0 else -1.0)

    def process(self, events: np.ndarray, *, after: bool) -> list[float | None]:
        """Add events one by one; the value of each event's own frame at its pixel, read before its update or
        just after it (None: its polarity is dropped)."""
        values: list[float | None] = []
        for e in events:
            t, x, y, p = int(e["t"]), int(e["x"]), int(e["y"]), int(e["p"])
            slot = self.slot(p)
            if slot < 0:
                values.append(None)
                continue
            self.advance(t)
            if not after:
                values.append(self.value(slot, x, y))
            self.add(slot, x, y, 1.0 if p else -1.0)
            if after:
                values.append(self.value(slot, x, y))
        return values

    def values(self) -> np.ndarray:
        """The current frame values, ``(n_frames, H, W)`` float64."""
        return self.stored * self.scale
