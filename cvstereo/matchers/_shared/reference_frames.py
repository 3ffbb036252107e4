"""Reference dynamic frames of one camera: plain Python, one operation at a time.

The twin of :class:`cvstereo.frames.dynamic.FrameBank` (the numba state the fast matchers use): the same
float64 operations in the same order (see :mod:`cvstereo.frames.dynamic` for the rules: lazy decay with one
scale factor, renormalisation, forgetting after a long gap). It shares no code with it: the update kernel is
built here from its formula (:func:`update_kernel`: the same weights as OpenCV's for the thesis' 3x3, sigma 1,
so the values agree bit for bit there; within a unit in the last place for other sizes), the two cameras'
events are merged here by sorting (:func:`merged_events`), and only the parameters and the limits of the lazy
decay (:mod:`cvstereo.frames.dynamic_limits`) are common.

>>> frames = DynamicFrames()
>>> frames.add_event(t=0, x=5, y=5, p=1)
>>> round(frames.value(0, 5, 5), 4), round(frames.value(0, 4, 4), 4)
(0.4084, 0.1502)
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from cvstereo.frames.dynamic_limits import FORGET_TICKS, RENORM
from cvstereo.frames.dynamic_params import DynamicFrameParams
from cvstereo.matchers._shared.frame_gains import FrameGains
from cvstereo.matchers._shared.reference_border import border_rule_of
from cvstereo.matchers._shared.reference_windows import gaussian_kernel
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import ON, slot_of_p


def update_kernel(params) -> np.ndarray:
    """(k, k) float64 weights an ON event adds around its pixel: ``gaussian_gain`` times the outer product of the
    Gaussian's axis (:func:`~cvstereo.matchers._shared.reference_windows.gaussian_kernel`, eq. 3.8-3.9), or
    ``[[1.0]]`` for the single-pixel update (eq. 4.1). ``params`` has the fields of the dynamic frames."""
    if not params.gaussian:
        return np.ones((1, 1))
    g = gaussian_kernel(params.kernel_size, params.kernel_sigma)
    return params.gaussian_gain * np.outer(g, g)


def dynamic_unit(params) -> float:
    """|D| at the pixel of one isolated event just after it (the update kernel's centre weight): the unit of a
    relative threshold's floor."""
    kernel = update_kernel(params)
    return float(kernel[kernel.shape[0] // 2, kernel.shape[1] // 2])


def merged_events(left: np.ndarray, right: np.ndarray) -> Iterator[tuple[int, int, np.void]]:
    """Both cameras' events in the one order the event matchers see them: by time, at equal times the left
    camera's first, each camera's in its array order (a stable sort on (t, camera)).

    Yields
    ------
    (camera, index, event)
        camera 0 = left, 1 = right; index into that camera's array.
    """
    t = np.concatenate([left["t"], right["t"]])
    cams = np.concatenate([np.zeros(left.size, np.int64), np.ones(right.size, np.int64)])
    index = np.concatenate([np.arange(left.size), np.arange(right.size)])
    for i in np.lexsort((index, cams, t)).tolist():
        yield int(cams[i]), int(index[i]), (left, right)[cams[i]][index[i]]


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
        r = self.kernel.shape[0] // 2
        _, height, width = self.stored.shape
        # The kernel's window on the sensor, and the part of the kernel that falls inside it.
        y0, y1, x0, x1 = max(y - r, 0), min(y + r + 1, height), max(x - r, 0), min(x + r + 1, width)
        weights = self.kernel[y0 - (y - r): y1 - (y - r), x0 - (x - r): x1 - (x - r)]
        # sign * w / scale per pixel, then added: the operations of the numba splat, in its order.
        self.stored[slot, y0:y1, x0:x1] += sign * weights / self.scale
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


class LevelByWindow:
    """The thresholds of a :class:`~cvstereo.matchers._shared.signal_level.SignalLevel` for events met one at a time,
    in time order.

    :meth:`at` returns the thresholds in force for the event's absolute window; :meth:`seen` records the value the
    event read (per camera), handed to the estimator when its window is complete.
    """

    def __init__(self, params, *, value_name: str = "dynamic-frame value", n_frames: int = 1,
                 value_units: str = "own"):
        #: The gains between the cameras in ``value_units`` (``n_frames`` frames per camera).
        self.frame_gains = FrameGains(params, n_frames=n_frames, unit=dynamic_unit(params), units=value_units)
        self.level = SignalLevel(params, absolute=params.threshold, unit=dynamic_unit(params), value_name=value_name,
                                 n_parts=self.frame_gains.parts)
        self.window_us = int(params.level_window_us)
        self.current: int | None = None
        self.values: tuple[list[float], list[float]] = ([], [])
        self.slots: tuple[list[int], list[int]] = ([], [])
        self.thresholds = None
        self.gains = None

    def at(self, t: int) -> np.ndarray:
        """The (2,) thresholds in force at time ``t`` (and :attr:`gains`, the frames' gains in force)."""
        k = int(t) // self.window_us
        if k != self.current:
            self.close()
            self.current = k
            self.thresholds = self.level.thresholds(k)
            self.gains = self.frame_gains.gains(k, self.thresholds, self.level)
        return self.thresholds

    def seen(self, cam: int, value: float, slot: int = 0) -> None:
        """Record the value an event of camera ``cam`` read in frame ``slot`` (for the windows after this one)."""
        self.values[cam].append(abs(value))
        self.slots[cam].append(slot)

    def close(self) -> None:
        """Hand the current window's values to the estimator."""
        if self.current is not None:
            for cam in (0, 1):
                self.frame_gains.add(self.level, self.current, cam, np.array(self.values[cam]),
                                     np.array(self.slots[cam], np.int64))
        self.values = ([], [])
        self.slots = ([], [])


#: ``match_event(own, other, slot, cam, x, y, thresholds) -> disparity or None``: one event's search, on its own
#: camera's frames and the other camera's, as they stand at its time before it updates its own; ``thresholds``
#: (per camera) are those in force for the event's window (:class:`LevelByWindow`; the absolute ``threshold``
#: unless ``threshold_mode="relative"``). With :func:`match_merged`'s ``value_units`` it also gets the gains in
#: force, a (2, frames) array (:class:`~cvstereo.matchers._shared.frame_gains.FrameGains`).
EventSearch = Callable[["DynamicFrames", "DynamicFrames", int, int, int, int, np.ndarray], "int | None"]


def match_merged(left: np.ndarray, right: np.ndarray, params: DynamicFrameParams, match_event: EventSearch, *,
                 resolution: tuple[int, int] = DEFAULT_RESOLUTION, value_units: str | None = None) -> np.ndarray:
    """Both cameras' events one at a time in the merged order, each searched, then added to its own frame.

    The frame of each camera is decayed to the event's time first; events of a dropped polarity are skipped.
    The value each event reads at its own pixel before its update feeds the signal level (:class:`LevelByWindow`),
    and with ``value_units`` (one of :data:`~cvstereo.matchers._shared.frame_gains.VALUE_UNITS`; None: a search
    that takes no gains) the gains between the cameras (:class:`~cvstereo.matchers._shared.frame_gains.FrameGains`),
    which ``match_event`` then gets as its last argument.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        One row per event ``match_event`` found a disparity for, in processing order (time-ordered).
    """
    frames = [DynamicFrames(params.frame_params(), resolution=resolution) for _ in range(2)]
    level = LevelByWindow(params, n_frames=frames[0].n_frames, value_units=value_units or "own")
    gains = value_units is not None
    rows = []
    for cam, _, e in merged_events(left, right):
        t, x, y, p = int(e["t"]), int(e["x"]), int(e["y"]), int(e["p"])
        thresholds = level.at(t)
        own, other = frames[cam], frames[1 - cam]
        slot = own.slot(p)
        if slot < 0:
            continue
        own.advance(t)
        other.advance(t)
        level.seen(cam, own.value(slot, x, y), slot)
        disparity = match_event(own, other, slot, cam, x, y, thresholds, *((level.gains,) if gains else ()))
        if disparity is not None:
            rows.append((t, x, y, p, cam, float(disparity)))
        own.add(slot, x, y, 1.0 if p else -1.0)
    # The border rule (adaptive set) decides on the whole output, in its order.
    return border_rule_of(make_matches(*zip(*rows, strict=True)) if rows else empty_matches(), params, resolution)
