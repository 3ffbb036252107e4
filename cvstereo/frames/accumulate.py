"""Events of a window accumulated into frames, per polarity mode, and the thesis' Gaussian filter.

The frame matchers (thesis 3.3 and 3.5.1, and the OpenCV baselines) turn each camera's events of a window
(:mod:`cvstereo.frames.windows`) into a signed frame (the sum of the signs of the events at each pixel: 10 OFF + 2 ON
give -8) and filter it with a 5x5 Gaussian of sigma 1. This module holds those pieces:

- :func:`polarity_counts`, :func:`signed_frame` / :func:`polarity_frames`: accumulation, per polarity mode
  (:mod:`cvstereo.model.polarity`: arrays over polarity are indexed by ``p``, OFF = 0 and ON = 1);
- :func:`stacked_frames`: the same frames of both cameras, one above the other, in one numba pass (the
  cluster matcher filters them with one call);
- :func:`gaussian_filter`: ``cv2.GaussianBlur`` with zero padding (as Matlab's filters pad).

>>> from cvstereo.model.events import make_events
>>> ev = make_events([0] * 12, [3] * 12, [4] * 12, [0] * 10 + [1] * 2)   # 10 OFF + 2 ON at (3, 4)
>>> float(signed_frame(ev, resolution=(8, 8))[4, 3])
-8.0
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numba
import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.polarity import OFF, ON, Polarity, frame_signs, sign, slot_of_p

__all__ = ["OFF_SENSOR", "check_filter_params", "event_channel", "event_mask", "filtered_unit", "frame_shape",
           "gaussian_filter", "polarity_counts", "polarity_frames", "polarity_sign", "signed_frame", "stacked_frames"]


def frame_shape(resolution: tuple[int, int]) -> tuple[int, int]:
    """(height, width) of a frame for a sensor of (width, height): the array shape of every frame."""
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
        Indexed by ``p``: ``[OFF]`` = ``[0]`` OFF counts, ``[ON]`` = ``[1]`` ON counts.
    """
    h, w = frame_shape(resolution)
    # One bincount over (polarity plane, y, x) is the vectorised scatter-add (faster than np.add.at).
    idx = events["p"].astype(np.intp) * (h * w) + events["y"].astype(np.intp) * w + events["x"]
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
    >>> from cvstereo.model.events import make_events
    >>> ev = make_events([0, 1, 2], [1, 1, 0], [0, 0, 0], [1, 0, 0])
    >>> signed_frame(ev, resolution=(2, 1)).tolist(), signed_frame(ev, resolution=(2, 1), signs=(1,)).tolist()
    ([[-1.0, 0.0]], [[0.0, 1.0]])
    """
    return _frame_of(polarity_counts(events, resolution=resolution), signs)


def _frame_of(counts: np.ndarray, signs: tuple[int, ...]) -> np.ndarray:
    if 1 in signs and -1 in signs:
        frame = counts[ON] - counts[OFF]
    else:
        frame = counts[ON] if 1 in signs else -counts[OFF]
    return frame.astype(np.float32)


def polarity_frames(counts: np.ndarray, *, polarity: Polarity = "shared") -> list[tuple[int, np.ndarray]]:
    """The signed frames of one camera's window under a per polarity handling.

    Parameters
    ----------
    counts : (2, height, width) int ndarray
        OFF and ON counts (:func:`polarity_counts`).
    polarity : {"shared", "separate", "on", "off"}, keyword-only
        ``shared``: one frame, sum of signs; ``separate``: an OFF frame (<= 0) and an ON frame (>= 0), in
        slot order (:mod:`cvstereo.model.polarity`); ``on`` / ``off``: only the events of that polarity.

    Returns
    -------
    list of (channel, (height, width) float32 ndarray)
        In slot order; ``channel`` is 0 for a frame of both polarities, +1 for the ON frame, -1 for the OFF frame.
    """
    return [(_channel_id(signs), _frame_of(counts, signs)) for signs in frame_signs(polarity)]


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
    >>> from cvstereo.model.events import make_events
    >>> ev = make_events([0, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0])      # 2 ON at x=1, 1 OFF at x=0
    >>> stack, seen = stacked_frames([ev], polarity="separate", resolution=(2, 1), gap=1)   # OFF frame, then ON
    >>> stack.tolist(), seen.tolist()
    ([[-1.0, 0.0], [0.0, 0.0], [0.0, 2.0], [0.0, 0.0]], [[True, False], [False, True]])
    """
    h, w = frame_shape(resolution)
    n_frames, channel_of = slot_of_p(polarity)
    stack = np.zeros((len(cameras) * n_frames * (h + gap), w), dtype=np.float32)
    seen = np.zeros((n_frames * h, w), dtype=np.bool_)
    for cam, ev in enumerate(cameras):
        bad = _stack_events(ev["x"], ev["y"], ev["p"], channel_of, cam * n_frames, h + gap, h, w, stack,
                            seen, cam == seen_camera)
        if bad >= 0:
            raise EventFormatError(f"camera {cam}: event {bad} at (x={int(ev['x'][bad])}, y={int(ev['y'][bad])}) "
                                   f"lies outside the {w}x{h} sensor.")
    return stack, seen


#: :func:`event_channel` of an event outside the sensor.
OFF_SENSOR = -2

#: :func:`cvstereo.model.polarity.sign` compiled for the kernels (inlined: an event's sign costs no call).
polarity_sign = numba.njit(cache=True, nogil=True, inline="always")(sign)


@numba.njit(cache=True, nogil=True, inline="always")
def event_channel(x, y, p, i, channel_of, width, height):  # pragma: no cover - compiled
    """The frame channel of event ``i`` (``channel_of[p]``: -1 where the polarity mode drops it), or
    :data:`OFF_SENSOR` where it lies outside the ``width`` x ``height`` sensor."""
    # Compared as int64: numba's code for the int16 fields against the int64 sizes made the callers' loops
    # many times slower.
    xi, yi = np.int64(x[i]), np.int64(y[i])
    if xi < 0 or xi >= width or yi < 0 or yi >= height:
        return OFF_SENSOR
    return channel_of[p[i]]


@numba.njit(cache=True, nogil=True)
def _stack_events(x, y, p, channel_of, first_frame, pitch, height, width, stack, seen,
                  mark_seen):  # pragma: no cover - compiled
    """Add each event's sign into its frame of ``stack``; return the index of the first event off the sensor, or -1."""
    for i in range(x.size):
        c = event_channel(x, y, p, i, channel_of, width, height)
        if c == OFF_SENSOR:
            return i
        if c < 0:
            continue  # a polarity the mode drops
        xi, yi = np.int64(x[i]), np.int64(y[i])
        stack[(first_frame + c) * pitch + yi, xi] += np.float32(polarity_sign(p[i]))
        if mark_seen:
            seen[c * height + yi, xi] = True
    return -1


def event_mask(counts: np.ndarray, *, channel: int = 0) -> np.ndarray:
    """Pixels that saw at least one event (of the channel's polarity: 0 any, +1 ON, -1 OFF).

    Parameters
    ----------
    counts : (2, height, width) int ndarray
        OFF and ON counts (:func:`polarity_counts`).
    channel : {0, 1, -1}, keyword-only

    Returns
    -------
    (height, width) bool ndarray
    """
    if channel > 0:
        return counts[ON] > 0
    if channel < 0:
        return counts[OFF] > 0
    return (counts[ON] + counts[OFF]) > 0


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


def filtered_unit(params) -> float:
    """The (filtered) frame value of one isolated event: the Gaussian's centre weight, or 1 without the filter.

    The unit of a relative threshold's floor (:mod:`cvstereo.matchers._shared.signal_level`); ``params`` has the fields
    of
    :class:`cvstereo.frames.windows.WindowFrameParams` (gaussian, kernel_sigma, kernel_size).
    """
    if not params.gaussian:
        return 1.0
    one = np.zeros((params.kernel_size, params.kernel_size), np.float32)
    one[params.kernel_size // 2, params.kernel_size // 2] = 1.0
    return float(gaussian_filter(one, sigma=params.kernel_sigma, kernel_size=params.kernel_size).max())


def check_filter_params(kernel_sigma: float, kernel_size: int, where: str) -> None:
    """Raise ValueError unless ``kernel_size`` is a positive odd int and ``kernel_sigma`` positive."""
    if kernel_size < 1 or kernel_size % 2 == 0:
        raise ValueError(f"{where}: kernel_size must be a positive odd number (the thesis uses 5 for frames, 3 for "
                         f"dynamic frames), got {kernel_size}.")
    if not kernel_sigma > 0:
        raise ValueError(f"{where}: kernel_sigma must be > 0 (the thesis uses 1.0), got {kernel_sigma}.")
