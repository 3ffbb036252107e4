"""Dynamic frames: rolling, decaying per-pixel memories of recent events (thesis 3.4, eq. 3.8-3.9 and 4.1).

Every event matcher (event-time, event-area, event-vector) keeps one dynamic frame per camera (or one per
camera and polarity) that changes with every event:

* an event at (x, y) with sign s (+1 ON, -1 OFF) adds ``gain * s * G`` centred on (x, y), where G is the
  ``kernel_size`` x ``kernel_size`` Gaussian of ``kernel_sigma`` from :func:`cv2.getGaussianKernel` (the
  thesis' 3x3, sigma 1: corner 0.0751, edge 0.1238, centre 0.2042, gain 2), clipped at the sensor border;
  with ``gaussian=False`` it adds s at (x, y) only (eq. 4.1);
* on the absolute clock, at every t = k * ``decay_period_us`` (k = 1, 2, ...), all values are multiplied
  by ``decay`` (0.99 every 250 us). A tick at exactly the time of an event is applied *before* that event;
* ON and OFF events share one frame, or use one each, or only one polarity is kept (``polarity``; the frame
  slot of each polarity is that of :mod:`cvstereo.model.polarity`: with separate frames, slot = p).

Decay is lazy: a frame is stored as ``S`` with one scale factor ``c`` per camera, the value being ``S * c``.
A tick multiplies ``c`` only; an update adds ``w / c``; when ``c`` falls below :data:`RENORM` the frames are
renormalised (``S *= c; c = 1``). A gap of more than :data:`FORGET_TICKS` ticks (250 s) clears the frames:
their values would be below 1e-4000 of what they were, i.e. zero in float64. A frame that never received an
event skips its ticks (it is zero anyway), so that a stream starting at t = 10^12 us costs nothing.

This module is the fast path: :class:`FrameBank` with numba kernels (:func:`advance_due` behind the cheap test
of :func:`advance`, :func:`splat`, :func:`process_events`) that the fast matchers call from their own kernels.
The variants that keep derived state with the frames for one matcher's search (block bounds of |stored| for
event-vector, column sums of a patch's rows for event-area) live with the matchers, in
:mod:`cvstereo.matchers._shared.frame_bounds`. Its reference twin, which
does exactly the same float64 operations in the same order so that both agree bit for bit, is plain Python:
:class:`cvstereo.matchers._shared.reference_frames.DynamicFrames`.

>>> bank = FrameBank(1, DynamicFrameParams())
>>> from cvstereo.model.events import make_events
>>> _ = bank.process(0, make_events([0], [5], [5], [1]))
>>> round(float(bank.values(0)[0, 5, 5]), 4), round(float(bank.values(0)[0, 4, 4]), 4)
(0.4084, 0.1502)
"""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
from numba import njit

from cvstereo.frames.accumulate import polarity_sign
from cvstereo.frames.dynamic_limits import FORGET_TICKS, RENORM
from cvstereo.frames.dynamic_params import DynamicFrameParams
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.polarity import slot_of_p

__all__ = ["FORGET_TICKS", "NEXT_TICK", "RENORM", "TOUCHED", "DynamicFrameParams", "FrameBank", "advance",
           "advance_due", "dynamic_unit", "event_columns", "event_matrix", "process_events", "splat", "tick_due",
           "update_kernel"]


def update_kernel(params: DynamicFrameParams) -> np.ndarray:
    """The weights an ON event adds around its pixel.

    Returns
    -------
    (k, k) float64 ndarray
        ``gaussian_gain * G`` (G the outer product of :func:`cv2.getGaussianKernel`), or ``[[1.0]]``.

    Examples
    --------
    >>> np.round(update_kernel(DynamicFrameParams()) / 2, 4)[1].tolist()
    [0.1238, 0.2042, 0.1238]
    """
    if not params.gaussian:
        return np.ones((1, 1))
    g = cv2.getGaussianKernel(params.kernel_size, params.kernel_sigma, ktype=cv2.CV_64F)
    return np.ascontiguousarray(params.gaussian_gain * (g @ g.T))


def dynamic_unit(params) -> float:
    """|D| at the pixel of one isolated event just after it: the update kernel's centre weight.

    The unit of a relative threshold's floor (:mod:`cvstereo.matchers._shared.signal_level`), the same for the fast
    matchers and
    their references.
    """
    kernel = update_kernel(params.frame_params())
    return float(kernel[kernel.shape[0] // 2, kernel.shape[1] // 2])


#: The columns of a :class:`FrameBank`'s ``clock`` (one row per camera): the index k of the camera's next decay
#: tick (at t = k * period), and whether its frames were touched since they were made or forgotten (0 or 1).
NEXT_TICK, TOUCHED = 0, 1


# ----------------------------------------------------------------------------------------------------------
# The same operations as the reference DynamicFrames, on state arrays of several cameras, in numba.
# State of camera ``cam``: stored[cam] (n_frames, H, W), scale[cam], clock[cam, NEXT_TICK], clock[cam, TOUCHED].
# The per-event helpers are inlined into their callers: a numba call with array arguments costs atomic
# reference counting on every array, which made a 9-pixel splat ten times slower. Inlining does not always
# remove it either: numba binds the arrays to new variables and relies on an LLVM pass to drop the
# increments and decrements around them, which gives up when the inlined code holds nested loops or two
# loops in a row (about 20 atomic operations an event in event-vector). Hence the shape
# of the helpers below: the rare work of a decay tick in a function of its own behind a cheap test, and
# :func:`splat_bounded` as one loop.


@njit(cache=True)
def advance_due(stored, scale, clock, cam, t, decay, period):
    """Apply the due decay ticks of camera ``cam`` up to time ``t`` (reference: ``DynamicFrames.advance``).

    Returns whether the stored values were rewritten (a reset after a long gap, or a renormalisation), after
    which whatever a caller keeps derived from them (block bounds, column sums) must be rebuilt. The scale alone
    does not tell: a reset while the scale is still 1.0 (no tick since the last one) leaves it unchanged.
    """
    rewritten = False
    if clock[cam, TOUCHED] != 0 and t // period + 1 - clock[cam, NEXT_TICK] > FORGET_TICKS:
        stored[cam] = 0.0
        scale[cam] = 1.0
        clock[cam, TOUCHED] = 0
        rewritten = True
    if clock[cam, TOUCHED] == 0:
        clock[cam, NEXT_TICK] = t // period + 1
        return rewritten
    k = clock[cam, NEXT_TICK]
    while k * period <= t:
        scale[cam] = scale[cam] * decay
        if scale[cam] < RENORM:
            frames = stored[cam]
            c = scale[cam]
            for f in range(frames.shape[0]):
                for yy in range(frames.shape[1]):
                    for xx in range(frames.shape[2]):
                        frames[f, yy, xx] *= c
            scale[cam] = 1.0
            rewritten = True
        k += 1
    clock[cam, NEXT_TICK] = k
    return rewritten


@njit(cache=True, inline="always")
def tick_due(next_tick, touched, t, period):
    """Whether :func:`advance_due` has anything to do at time ``t``: a decay tick at or before ``t``, or frames
    never touched (``next_tick``, ``touched``: a camera's row of the clock).

    Scalars only: a kernel calls it with ``clock[cam, NEXT_TICK], clock[cam, TOUCHED]``, so that inlining it binds
    no array (an inlined helper taking the arrays kept numba's atomic reference counting around every event).
    """
    return touched == 0 or next_tick * period <= t


@njit(cache=True, inline="always")
def advance(stored, scale, clock, cam, t, decay, period):
    """:func:`advance_due` when it has anything to do: a tick at or before ``t``, or frames never touched.

    Otherwise (most events: a tick every 250 us) the next tick lies after ``t``, so neither a tick nor the
    forgetting of a long gap applies. The work stays in a function of its own, not inlined (see above).
    """
    if tick_due(clock[cam, NEXT_TICK], clock[cam, TOUCHED], t, period):
        advance_due(stored, scale, clock, cam, t, decay, period)


@njit(cache=True, inline="always")
def splat(stored, scale, clock, cam, slot, x, y, sign, kernel):
    """Add ``sign * kernel`` centred on (x, y) to frame ``slot`` of camera ``cam`` (reference: DynamicFrames.add)."""
    k = kernel.shape[0]
    r = k // 2
    height = stored.shape[2]
    width = stored.shape[3]
    c = scale[cam]
    for j in range(k):
        yy = y + j - r
        if yy < 0 or yy >= height:
            continue
        for i in range(k):
            xx = x + i - r
            if xx < 0 or xx >= width:
                continue
            stored[cam, slot, yy, xx] += sign * kernel[j, i] / c
    clock[cam, TOUCHED] = 1


@njit(cache=True)
def process_events(stored, scale, clock, cam, t, x, y, p, slot_of_p, kernel, decay, period, read_after, out):
    """Feed one camera's events through its frames, recording the value at each event's pixel.

    ``out[i]`` is the value of the event's own frame at its pixel before (``read_after`` False) or just after
    its update; NaN for events whose polarity is dropped.
    """
    for i in range(t.shape[0]):
        slot = slot_of_p[1 if p[i] > 0 else 0]
        if slot < 0:
            out[i] = np.nan
            continue
        if tick_due(clock[cam, NEXT_TICK], clock[cam, TOUCHED], t[i], period):
            advance_due(stored, scale, clock, cam, t[i], decay, period)
        if not read_after:
            out[i] = stored[cam, slot, y[i], x[i]] * scale[cam]
        splat(stored, scale, clock, cam, slot, x[i], y[i], polarity_sign(p[i]), kernel)
        if read_after:
            out[i] = stored[cam, slot, y[i], x[i]] * scale[cam]


def event_matrix(events: np.ndarray) -> np.ndarray:
    """The columns t, x, y, p of an event array as the rows of one ``(4, N)`` int64 array.

    Each row is contiguous, as the numba kernels take them.
    """
    out = np.empty((4, events.size), dtype=np.int64)
    for row, name in enumerate(("t", "x", "y", "p")):
        out[row] = events[name]
    return out


def event_columns(events: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Contiguous int64 columns t, x, y, p of an event array, as the numba kernels take them."""
    m = event_matrix(events)
    return m[0], m[1], m[2], m[3]


class FrameBank:
    """Fast dynamic frames of ``n_cameras`` cameras: state arrays for the numba kernels.

    Parameters
    ----------
    n_cameras : int
    params : DynamicFrameParams
    resolution : (width, height), keyword-only

    Attributes
    ----------
    stored : (n_cameras, n_frames, H, W) float64 ndarray
    scale : (n_cameras,) float64 ndarray
    clock : (n_cameras, 2) int64 ndarray
        Per camera: columns :data:`NEXT_TICK` (index of the next decay tick) and :data:`TOUCHED` (1 once touched).
    kernel : (k, k) float64 ndarray
    slot_of_p : (2,) int64 ndarray
    """

    def __init__(self, n_cameras: int, params: DynamicFrameParams, *,
                 resolution: tuple[int, int] = DEFAULT_RESOLUTION):
        self.params = params
        self.n_frames, self.slot_of_p = slot_of_p(params.polarity)
        self.kernel = update_kernel(params)
        width, height = resolution
        self.stored = np.zeros((n_cameras, self.n_frames, height, width))
        self.scale = np.ones(n_cameras)
        self.clock = np.zeros((n_cameras, 2), dtype=np.int64)

    @property
    def decay_args(self) -> tuple[float, int]:
        """(decay, period) as the kernels take them."""
        return float(self.params.decay), int(self.params.decay_period_us)

    def process(self, cam: int, events: np.ndarray, *, read: Literal["before", "after"] = "before") -> np.ndarray:
        """Feed camera ``cam``'s events (time-ordered, after all earlier ones) through its frames.

        Returns
        -------
        (N,) float64 ndarray
            The value of each event's own frame at its pixel, before or just after its own update; NaN for
            dropped polarities.
        """
        return self.process_columns(cam, event_matrix(events), read=read)

    def process_columns(self, cam: int, columns: np.ndarray, *, read: Literal["before", "after"] = "before"
                        ) -> np.ndarray:
        """:meth:`process` on the ``(4, N)`` int64 rows t, x, y, p of :func:`event_matrix`."""
        if read not in ("before", "after"):
            raise ValueError(f"read must be 'before' or 'after', got {read!r}.")
        out = np.empty(columns.shape[1])
        process_events(self.stored, self.scale, self.clock, cam, columns[0], columns[1], columns[2], columns[3],
                       self.slot_of_p, self.kernel, *self.decay_args, read == "after", out)
        return out

    def values(self, cam: int, t: int | None = None) -> np.ndarray:
        """The frame values of camera ``cam`` (decayed to time ``t`` if given), ``(n_frames, H, W)``.

        Reads a copy: the state itself is not advanced.
        """
        stored, scale, clock = self.stored[cam:cam + 1].copy(), self.scale[cam:cam + 1].copy(), \
            self.clock[cam:cam + 1].copy()
        if t is not None:
            advance(stored, scale, clock, 0, int(t), *self.decay_args)
        return stored[0] * scale[0]
