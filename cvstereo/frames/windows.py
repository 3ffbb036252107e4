"""Window streaming of the frame matchers: windows on the absolute clock and the frame matcher base class.

The frame matchers (thesis 3.3 and 3.5.1, and the OpenCV baselines) all cut time into windows
``[k*W, (k+1)*W)`` on the absolute clock (W = 40 ms), make frames of each camera's events of a window
(:mod:`cvstereo.frames.accumulate`) and report at the window's end time ``(k+1)*W``. This module holds:

- :class:`WindowFrameParams`: the parameters every frame matcher shares (window, Gaussian);
- :class:`WindowAccumulator`: streaming, emits complete windows once the stream has passed their end;
- :class:`FrameMatcher`: the :class:`~cvstereo.matchers.protocol.StreamMatcher` base of every frame matcher, which
  only has to say what to do with one complete window.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from cvstereo.matchers.constraints import DeclaredParams, param
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import DEFAULT_RESOLUTION, count_before, empty_events, paired_window_segments
from cvstereo.model.matches import concat_matches, empty_matches, join_records

__all__ = ["FrameMatcher", "Window", "WindowAccumulator", "WindowFrameParams", "check_window_us"]


def check_window_us(window_us: int, where: str) -> None:
    """Raise ValueError unless ``window_us`` is a positive integer."""
    if int(window_us) != window_us or window_us <= 0:
        raise ValueError(f"{where}: window_us must be a positive whole number of microseconds "
                         f"(the thesis uses 40000), got {window_us}.")


@dataclass(frozen=True, kw_only=True)
class WindowFrameParams(metaclass=DeclaredParams):
    """Parameters every frame matcher shares: the window on the absolute clock and the thesis' Gaussian.

    Matchers' parameter classes extend it with their own fields.

    Attributes
    ----------
    window_us : int
        Window length, us; windows ``[k*W, (k+1)*W)`` on the absolute clock.
    gaussian : bool
        Filter the frames with the Gaussian (eq. 3.6).
    kernel_sigma : float
        Standard deviation of the Gaussian, px (old name: ``sigma``).
    kernel_size : int
        Odd side of the Gaussian kernel.
    """

    aliases: ClassVar[dict] = {"sigma": "kernel_sigma"}

    window_us: int = param(40_000, gt=0, note="the thesis uses 40000")
    gaussian: bool = True
    kernel_sigma: float = param(1.0, gt=0, note="the thesis uses 1.0")
    kernel_size: int = param(5, side=True, note="the thesis uses 5")


class Window(NamedTuple):
    """The events of both cameras in one complete window ``[t_start, t_end)``.

    ``t_end`` is the stamp of the window's results (docs/formats.md).
    """

    index: int
    t_start: int
    t_end: int
    left: np.ndarray
    right: np.ndarray


class WindowAccumulator:
    """Collect streamed events into windows ``[k*W, (k+1)*W)`` on the absolute clock.

    Holds only the events of windows that are still open. :meth:`push` returns every window that the
    stream has passed (``watermark >= (k+1)*W``); windows in which neither camera has an event are
    skipped, since no matcher finds anything in them.

    Parameters
    ----------
    window_us : int
        Window length W, microseconds.

    Examples
    --------
    >>> from cvstereo.model.events import make_events
    >>> acc = WindowAccumulator(40_000)
    >>> ev = make_events([5, 39_999, 40_000, 130_000], [0] * 4, [0] * 4, [1] * 4)
    >>> [(w.t_end, w.left.size) for w in acc.push(ev, ev[:0], watermark=130_000)]
    [(40000, 2), (80000, 1)]
    >>> [(w.t_end, w.left.size) for w in acc.flush()]
    [(160000, 1)]
    """

    def __init__(self, window_us: int):
        check_window_us(window_us, "WindowAccumulator")
        self.window_us = int(window_us)
        self._pending: list[list[np.ndarray]] = [[], []]

    def push(self, left: np.ndarray, right: np.ndarray, *, watermark: int | None) -> list[Window]:
        """Add a time slice of both cameras; return the windows that are now complete, in time order.

        Parameters
        ----------
        left, right : (N,) ndarray of EVENT_DTYPE
            Time-ordered, not earlier than anything pushed before.
        watermark : int or None, keyword-only
            Every event pushed later has ``t >= watermark``.
        """
        for i, ev in enumerate((left, right)):
            if ev.size:
                # Keep chunks in a list: concatenating structured arrays on every packet is slow.
                self._pending[i].append(ev)
        if watermark is None:
            return []
        # Windows that end at or before the watermark can receive no more events.
        return self._take(watermark - watermark % self.window_us)

    def flush(self) -> list[Window]:
        """End of stream: return the windows still open that hold events."""
        return self._take(None)

    def _take(self, t_cut: int | None) -> list[Window]:
        w = self.window_us
        if t_cut is not None and not any(c and c[0]["t"][0] < t_cut for c in self._pending):
            return []  # nothing complete yet: leave the chunks unjoined
        parts = []
        for i in range(2):
            chunks = self._pending[i]
            if not chunks:
                parts.append(empty_events())
                continue
            ev = chunks[0] if len(chunks) == 1 else join_records(chunks)
            n = ev.size if t_cut is None else count_before(ev["t"], t_cut)
            parts.append(ev[:n])
            self._pending[i] = [ev[n:]] if n < ev.size else []
        left, right = parts
        # Each window's events are a contiguous slice of the time-ordered arrays.
        return [Window(k, k * w, (k + 1) * w, left[a:b], right[c:d])
                for k, (a, b), (c, d) in paired_window_segments(left["t"], right["t"], w)]


class FrameMatcher(StreamMatcher):
    """Base of the frame matchers: streams events into windows and matches each complete window.

    Subclasses set ``Params`` (which must have ``window_us``), ``variants`` and ``method``, and implement
    :meth:`match_window`. The result is independent of how the stream is cut into packets, since each
    window is matched once, from all its events.
    """

    anchor = "window"

    def __init__(self, params=None, *, resolution: tuple[int, int] = DEFAULT_RESOLUTION):
        super().__init__(params, resolution=resolution)
        self._windows = WindowAccumulator(self.params.window_us)

    def _feed(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        return self._match_all(self._windows.push(left, right, watermark=self.watermark))

    def _flush(self) -> np.ndarray:
        return self._match_all(self._windows.flush())

    def _match_all(self, windows: list[Window]) -> np.ndarray:
        if not windows:
            return empty_matches()
        return concat_matches([self.match_window(w) for w in windows])

    @abc.abstractmethod
    def match_window(self, window: Window) -> np.ndarray:
        """Matches of one complete window, all stamped ``t = window.t_end``.

        Returns
        -------
        (M,) ndarray of MATCH_DTYPE
        """

