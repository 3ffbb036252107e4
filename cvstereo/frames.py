"""Events accumulated into frames on the absolute clock, the thesis' Gaussian filter, and window streaming.

The frame matchers (thesis 3.3 and 3.5.1, and the OpenCV baselines) all cut time into windows
``[k*W, (k+1)*W)`` on the absolute clock (W = 40 ms), turn each camera's events of a window into a signed
frame (the sum of the signs of the events at each pixel: 10 OFF + 2 ON give -8), filter it with a 5x5
Gaussian of sigma 1, and report at the window's end time ``(k+1)*W``. This module holds those pieces:

- :func:`signed_frame` / :func:`polarity_frames`: accumulation, per polarity handling;
- :func:`stacked_frames`: the same frames of both cameras, one above the other, in one numba pass (the
  cluster matcher filters them with one call);
- :func:`gaussian_filter`: ``cv2.GaussianBlur`` with zero padding (as Matlab's filters pad);
- :class:`WindowAccumulator`: streaming, emits complete windows once the stream has passed their end;
- :class:`FrameMatcher`: the :class:`~cvstereo.matcher.StreamMatcher` base of every frame matcher, which
  only has to say what to do with one complete window.

>>> from cvstereo.events import make_events
>>> ev = make_events([0] * 12, [3] * 12, [4] * 12, [0] * 10 + [1] * 2)   # 10 OFF + 2 ON at (3, 4)
>>> float(signed_frame(ev, resolution=(8, 8))[4, 3])
-8.0
"""

from __future__ import annotations

import abc
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import cv2
import numba
import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.events import DEFAULT_RESOLUTION, distinct_sorted, empty_events
from cvstereo.matcher import StreamMatcher
from cvstereo.matches import concat_matches, empty_matches

#: Per polarity handling of the frame matchers (formats.md's variant names of ``frame``).
Polarity = Literal["shared", "separate", "on", "off"]
POLARITIES: tuple[str, ...] = ("shared", "separate", "on", "off")

#: Which event signs enter each frame of a polarity mode: +1 = ON events, -1 = OFF events.
_CHANNELS: dict[str, tuple[tuple[int, ...], ...]] = {
    "shared": ((1, -1),),
    "separate": ((1,), (-1,)),
    "on": ((1,),),
    "off": ((-1,),),
}


def _shape(resolution: tuple[int, int]) -> tuple[int, int]:
    """(height, width) of a frame for a sensor of (width, height)."""
    return int(resolution[1]), int(resolution[0])


def polarity_counts(events: np.ndarray, *, resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Number of ON and of OFF events at each pixel: everything the frames of a window are made of.

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        The events of one camera in one window.
    resolution : (width, height), keyword-only

    Returns
    -------
    (2, height, width) int64 ndarray
        ``[0]`` ON counts, ``[1]`` OFF counts.
    """
    h, w = _shape(resolution)
    # One bincount over (polarity plane, y, x) is the vectorised scatter-add (faster than np.add.at).
    idx = (1 - events["p"].astype(np.intp)) * (h * w) + events["y"].astype(np.intp) * w + events["x"]
    return np.bincount(idx, minlength=2 * h * w).reshape(2, h, w)


def signed_frame(events: np.ndarray, *, resolution: tuple[int, int] = DEFAULT_RESOLUTION,
                 signs: tuple[int, ...] = (1, -1)) -> np.ndarray:
    """Sum of the signs of the events at each pixel (thesis eq. 3.3-3.5).

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        The events of one camera in one window.
    resolution : (width, height), keyword-only
    signs : tuple of {1, -1}, keyword-only
        Which events count: ``(1, -1)`` both (ON adds +1, OFF adds -1), ``(1,)`` ON only, ``(-1,)`` OFF only.

    Returns
    -------
    (height, width) float32 ndarray

    Examples
    --------
    >>> from cvstereo.events import make_events
    >>> ev = make_events([0, 1, 2], [1, 1, 0], [0, 0, 0], [1, 0, 0])
    >>> signed_frame(ev, resolution=(2, 1)).tolist(), signed_frame(ev, resolution=(2, 1), signs=(1,)).tolist()
    ([[-1.0, 0.0]], [[0.0, 1.0]])
    """
    return _frame_of(polarity_counts(events, resolution=resolution), signs)


def _frame_of(counts: np.ndarray, signs: tuple[int, ...]) -> np.ndarray:
    if 1 in signs and -1 in signs:
        frame = counts[0] - counts[1]
    else:
        frame = counts[0] if 1 in signs else -counts[1]
    return frame.astype(np.float32)


def polarity_frames(counts: np.ndarray, *, polarity: Polarity = "shared") -> list[tuple[int, np.ndarray]]:
    """The signed frames of one camera's window under a per polarity handling.

    Parameters
    ----------
    counts : (2, height, width) int ndarray
        ON and OFF counts (:func:`polarity_counts`).
    polarity : {"shared", "separate", "on", "off"}, keyword-only
        ``shared``: one frame, sum of signs; ``separate``: an ON frame (>= 0) and an OFF frame (<= 0);
        ``on`` / ``off``: only the events of that polarity (OFF frames are <= 0).

    Returns
    -------
    list of (channel, (height, width) float32 ndarray)
        ``channel`` is 0 for a frame of both polarities, +1 for the ON frame, -1 for the OFF frame.
    """
    return [(_channel_id(signs), _frame_of(counts, signs)) for signs in _channels(polarity)]


def _channels(polarity: str) -> tuple[tuple[int, ...], ...]:
    try:
        return _CHANNELS[polarity]
    except KeyError:
        raise ValueError(f"polarity '{polarity}' is not one of: {', '.join(POLARITIES)}.") from None


def _channel_id(signs: tuple[int, ...]) -> int:
    return signs[0] if len(signs) == 1 else 0


def stacked_frames(cameras: Sequence[np.ndarray], *, polarity: Polarity = "shared",
                   resolution: tuple[int, int] = DEFAULT_RESOLUTION, gap: int = 0,
                   seen_camera: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The signed frames of several cameras' windows, one above the other, in one pass over the events.

    The same frames as :func:`polarity_frames` of each camera's :func:`polarity_counts`, laid out camera by
    camera, frame by frame (the order of :func:`polarity_frames`), each followed by ``gap`` zero rows: a
    filter of radius ``gap`` with a zero border then sees each frame as if it were filtered on its own.

    Parameters
    ----------
    cameras : sequence of (N,) ndarray of EVENT_DTYPE
        The events of each camera in the window.
    polarity : {"shared", "separate", "on", "off"}, keyword-only
    resolution : (width, height), keyword-only
    gap : int, keyword-only
        Zero rows after each frame.
    seen_camera : int, keyword-only
        The camera whose pixels with events are marked in ``seen``.

    Returns
    -------
    stack : (cameras * frames * (height + gap), width) float32 ndarray
    seen : (frames * height, width) bool ndarray
        Pixels of frame ``c`` (rows ``c * height + y``) where camera ``seen_camera`` has events of that frame.

    Raises
    ------
    EventFormatError
        An event lies outside the sensor.

    Examples
    --------
    >>> from cvstereo.events import make_events
    >>> ev = make_events([0, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0])      # 2 ON at x=1, 1 OFF at x=0
    >>> stack, seen = stacked_frames([ev], polarity="separate", resolution=(2, 1), gap=1)
    >>> stack.tolist(), seen.tolist()
    ([[0.0, 2.0], [0.0, 0.0], [-1.0, 0.0], [0.0, 0.0]], [[False, True], [True, False]])
    """
    h, w = _shape(resolution)
    channel_of = _channel_of(polarity)
    n_frames = int(channel_of.max()) + 1
    stack = np.zeros((len(cameras) * n_frames * (h + gap), w), dtype=np.float32)
    seen = np.zeros((n_frames * h, w), dtype=np.bool_)
    for cam, ev in enumerate(cameras):
        bad = _stack_events(ev["x"], ev["y"], ev["p"], channel_of, cam * n_frames, h + gap, h, w, stack,
                            seen, cam == seen_camera)
        if bad >= 0:
            raise EventFormatError(f"camera {cam}: event {bad} at (x={int(ev['x'][bad])}, y={int(ev['y'][bad])}) "
                                   f"lies outside the {w}x{h} sensor.")
    return stack, seen


def _channel_of(polarity: str) -> np.ndarray:
    """Frame index of each event polarity ``[OFF, ON]`` (-1: left out), frames in the order of _CHANNELS."""
    channel_of = np.full(2, -1, dtype=np.int64)
    for frame, signs in enumerate(_channels(polarity)):
        for s in signs:
            channel_of[1 if s > 0 else 0] = frame
    return channel_of


@numba.njit(cache=True, nogil=True)
def _stack_events(x, y, p, channel_of, first_frame, pitch, height, width, stack, seen,
                  mark_seen):  # pragma: no cover - compiled
    """Add each event's sign into its frame of ``stack``; return the index of the first event off the sensor, or -1."""
    for i in range(x.size):
        if x[i] < 0 or x[i] >= width or y[i] < 0 or y[i] >= height:
            return i
        c = channel_of[p[i]]
        if c < 0:
            continue
        stack[(first_frame + c) * pitch + y[i], x[i]] += np.float32(1.0) if p[i] else np.float32(-1.0)
        if mark_seen:
            seen[c * height + y[i], x[i]] = True
    return -1


def event_mask(counts: np.ndarray, *, channel: int = 0) -> np.ndarray:
    """Pixels that saw at least one event (of the channel's polarity: 0 any, +1 ON, -1 OFF).

    Parameters
    ----------
    counts : (2, height, width) int ndarray
        ON and OFF counts (:func:`polarity_counts`).
    channel : {0, 1, -1}, keyword-only

    Returns
    -------
    (height, width) bool ndarray
    """
    if channel > 0:
        return counts[0] > 0
    if channel < 0:
        return counts[1] > 0
    return (counts[0] + counts[1]) > 0


def gaussian_filter(frame: np.ndarray, *, sigma: float = 1.0, kernel_size: int = 5) -> np.ndarray:
    """The thesis' rotationally symmetric Gaussian low-pass (eq. 3.6), zero outside the sensor.

    Parameters
    ----------
    frame : (height, width) float ndarray
    sigma : float, keyword-only
        Standard deviation, px.
    kernel_size : int, keyword-only
        Odd side of the square kernel.

    Returns
    -------
    (height, width) float32 ndarray

    Examples
    --------
    >>> f = np.zeros((5, 5), np.float32); f[2, 2] = 1
    >>> round(float(gaussian_filter(f)[2, 2]), 4)      # the centre of eq. 3.6
    0.1621
    """
    # BORDER_CONSTANT: Matlab's imfilter pads with zeros, and beyond the sensor there are no events.
    return cv2.GaussianBlur(np.asarray(frame, dtype=np.float32), (kernel_size, kernel_size), sigmaX=sigma,
                            sigmaY=sigma, borderType=cv2.BORDER_CONSTANT)


def check_filter_params(sigma: float, kernel_size: int, where: str) -> None:
    """Raise ValueError unless ``kernel_size`` is a positive odd int and ``sigma`` positive."""
    if kernel_size < 1 or kernel_size % 2 == 0:
        raise ValueError(f"{where}: kernel_size must be a positive odd number (e.g. 5), got {kernel_size}.")
    if not sigma > 0:
        raise ValueError(f"{where}: sigma must be > 0 (the thesis uses 1.0), got {sigma}.")


def check_window_us(window_us: int, where: str) -> None:
    """Raise ValueError unless ``window_us`` is a positive integer."""
    if int(window_us) != window_us or window_us <= 0:
        raise ValueError(f"{where}: window_us must be a positive whole number of microseconds "
                         f"(the thesis uses 40000), got {window_us}.")


@dataclass(frozen=True, kw_only=True)
class WindowFrameParams:
    """Parameters every frame matcher shares: the window on the absolute clock and the thesis' Gaussian.

    Matchers' parameter classes extend it with their own fields.

    Attributes
    ----------
    window_us : int
        Window length, us; windows ``[k*W, (k+1)*W)`` on the absolute clock.
    gaussian : bool
        Filter the frames with the Gaussian (eq. 3.6).
    sigma : float
        Standard deviation of the Gaussian, px.
    kernel_size : int
        Odd side of the Gaussian kernel.
    """

    window_us: int = 40_000
    gaussian: bool = True
    sigma: float = 1.0
    kernel_size: int = 5

    def __post_init__(self):
        where = type(self).__name__
        check_window_us(self.window_us, where)
        check_filter_params(self.sigma, self.kernel_size, where)


class Window(NamedTuple):
    """The events of both cameras in one complete window ``[t_start, t_end)``.

    ``t_end`` is the stamp of the window's results (formats.md).
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
    >>> from cvstereo.events import make_events
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
        parts, ks = [], []
        for i in range(2):
            chunks = self._pending[i]
            if not chunks:
                parts.append(empty_events())
                continue
            ev = chunks[0] if len(chunks) == 1 else _join(chunks)
            t = ev["t"]
            if t_cut is None or t[-1] < t_cut:
                n = ev.size
            else:
                n = 0 if t[0] >= t_cut else int(np.searchsorted(t, t_cut, side="left"))
            parts.append(ev[:n])
            self._pending[i] = [ev[n:]] if n < ev.size else []
            if n:
                k0, k1 = int(t[0]) // w, int(t[n - 1]) // w
                # Usually one window closes at a time: skip the unique for that case.
                ks.append(np.array([k0]) if k0 == k1 else distinct_sorted(t[:n] // w))
        left, right = parts
        if not ks:
            return []
        ks = ks[0] if len(ks) == 1 or np.array_equal(ks[0], ks[1]) else np.union1d(ks[0], ks[1])
        if ks.size == 1:
            k = int(ks[0])
            return [Window(k, k * w, (k + 1) * w, left, right)]
        bounds = ks * w
        # Each window's events are a contiguous slice of the time-ordered arrays.
        lo_l = np.searchsorted(left["t"], bounds, side="left")
        hi_l = np.searchsorted(left["t"], bounds + w, side="left")
        lo_r = np.searchsorted(right["t"], bounds, side="left")
        hi_r = np.searchsorted(right["t"], bounds + w, side="left")
        return [
            Window(int(k), int(k) * w, (int(k) + 1) * w, left[a:b], right[c:d])
            for k, a, b, c, d in zip(ks, lo_l, hi_l, lo_r, hi_r, strict=True)
        ]


def _join(chunks: list[np.ndarray]) -> np.ndarray:
    """np.concatenate for event arrays, without its per-call structured-dtype promotion (slow for small chunks)."""
    out = np.empty(sum(c.size for c in chunks), dtype=chunks[0].dtype)
    i = 0
    for c in chunks:
        out[i: i + c.size] = c
        i += c.size
    return out



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

    def iter_windows(self, left: np.ndarray, right: np.ndarray) -> Iterator[Window]:
        """The windows of two whole streams (a convenience for tests and notebooks; no state is kept)."""
        acc = WindowAccumulator(self.params.window_us)
        yield from acc.push(left, right, watermark=None)
        yield from acc.flush()

    @abc.abstractmethod
    def match_window(self, window: Window) -> np.ndarray:
        """Matches of one complete window, all stamped ``t = window.t_end``.

        Returns
        -------
        (M,) ndarray of MATCH_DTYPE
        """

