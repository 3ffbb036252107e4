"""What the event matchers share: the streaming of both cameras in one merged order through their frames.

Event-area and event-vector compare an event's own dynamic frame with the other camera's frame as it stands
at the event's time, so both cameras' events must be processed in one global order
(:mod:`cvstereo.matchers._shared.merge_order`: by time, and at equal times the left camera's events first).
Events at the current watermark are held back until the next packet (or flush), because the other camera
may still deliver events with the same timestamp that come first in that order; this makes the result
independent of how the stream was cut into packets.

The kernels run once per absolute window of the signal level (:mod:`cvstereo.matchers._shared.signal_level`) with the
thresholds in force for that window, and return the |D| each event read at its own pixel before its update,
which then feeds the level.
"""

from __future__ import annotations

import abc

import numpy as np
from numba import njit

from cvstereo.frames.dynamic import FrameBank, dynamic_unit
from cvstereo.matchers._shared.frame_gains import FrameGains
from cvstereo.matchers._shared.merge_order import ROW_CAM, ROW_INDEX, ROW_Y, STREAM_ROWS, merged_stream
from cvstereo.matchers._shared.row_bands import gather_band_values, merge_band_matches
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import count_before, empty_events, paired_window_segments
from cvstereo.model.matches import MATCH_DTYPE, concat_matches, empty_matches


def matches_at(events: tuple[np.ndarray, np.ndarray], stream: np.ndarray, pos: np.ndarray,
               disparity: np.ndarray) -> np.ndarray:
    """Matches anchored at the merged stream's events ``pos[k]``, in the given order.

    Parameters
    ----------
    events : (left, right) ndarrays of EVENT_DTYPE
        Each camera's events.
    stream : (STREAM_ROWS, N) int64 ndarray
        Their merged stream (:func:`cvstereo.matchers._shared.merge_order.merged_stream`): camera and index into
        its events of each.
    pos : (M,) int64 ndarray
        Positions in the stream of the matched events.
    disparity : (M,) float64 ndarray

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
    """
    out = np.empty(pos.size, dtype=MATCH_DTYPE)  # every field of every row is written: no zero fill first
    if pos.size:
        _fill_matches(out, events[0], events[1], stream[ROW_CAM], stream[ROW_INDEX], pos, disparity)
    return out


@njit(cache=True)
def _fill_matches(out, left, right, cam, index, pos, disparity):  # pragma: no cover - compiled
    """Write match ``n`` from the event of stream position ``pos[n]`` (event ``index`` of camera ``cam`` there),
    one pass.

    Numpy's way (a mask per camera, then a fancy-indexed copy of each structured field) cost a visible share of
    event-vector's time per match (bench/results/docstring-figures.md).
    """
    for n in range(pos.shape[0]):
        k = pos[n]
        ev = left[index[k]] if cam[k] == 0 else right[index[k]]
        row = out[n]
        row.t, row.x, row.y, row.p = ev.t, ev.x, ev.y, ev.p
        row.camera = cam[k]
        row.disparity = disparity[n]


def _fields(events: np.ndarray) -> tuple[np.ndarray, ...]:
    """The fields t, x, y, p of an event array (views)."""
    return events["t"], events["x"], events["y"], events["p"]


class Scratch:
    """Named 1-D buffers reused from window to window, grown (doubled) when a window needs more.

    The event matchers run their kernel once per 40 ms window; fresh output, value and stream arrays for every
    window cost allocations and page faults that a reused buffer does not. Whatever a caller keeps beyond the
    window must be copied out of these views (:func:`matches_at` and :meth:`SignalLevel.add` do).
    """

    def __init__(self):
        self._buffers: dict[str, np.ndarray] = {}

    def take(self, name: str, n: int, dtype) -> np.ndarray:
        """The first ``n`` elements of buffer ``name`` (contiguous, contents undefined)."""
        buf = self._buffers.get(name)
        if buf is None or buf.size < n or buf.dtype != dtype:
            buf = self._buffers[name] = np.empty(max(n, 2 * (0 if buf is None else buf.size)), dtype)
        return buf[:n]


class MergedEventMatcher(StreamMatcher):
    """Base of the matchers that process both cameras' events in one merged order (one numba kernel call
    per packet).

    Subclasses set :attr:`kernels` and ``_bands`` (a :class:`cvstereo.matchers._shared.row_bands.BandedState` of
    their frame state) and implement :meth:`_search`.
    """

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._bank = FrameBank(2, self.params.frame_params(), resolution=self.resolution)
        self._held = (empty_events(), empty_events())
        self._scratch = Scratch()
        self._last_search = (None, None)  # (thresholds' and gains' bytes, the kernel's parameters for them)
        #: The gains between the cameras (:class:`cvstereo.matchers._shared.frame_gains.FrameGains`) in the units
        #: the matcher compares in (:meth:`_value_units`; all 1 for ``"own"``).
        self._gains = FrameGains(self.params, n_frames=self._bank.n_frames, unit=dynamic_unit(self.params),
                                 units=self._value_units())
        self._level = SignalLevel(self.params, absolute=self.params.threshold, unit=dynamic_unit(self.params),
                                  value_name="dynamic-frame value", n_parts=self._gains.parts)

    #: The kernel, serial and parallel (:func:`cvstereo.matchers._shared.row_bands.compile_twice` of a loop over the
    #: row bands): ``kernel(stream, bands, cuts, search, out_pos, out_disparity, counts, values, right_start)``,
    #: ``values`` one buffer per band.
    kernels: tuple

    def _value_units(self) -> str:
        """``"own"`` (the default): the kernel compares each camera's values as they are; ``"camera"`` or
        ``"polarity"``: the other camera's values multiplied by one gain per camera or per frame (``value_units``)."""
        return "own"

    @abc.abstractmethod
    def _search(self, thresholds: np.ndarray, gains: np.ndarray) -> tuple:
        """The kernel's parameters (a NamedTuple) for a level window with each camera's ``thresholds`` and the
        frames' ``gains`` (:meth:`FrameGains.gains <cvstereo.matchers._shared.frame_gains.FrameGains.gains>`)."""

    def _search_for(self, thresholds: np.ndarray, gains: np.ndarray) -> tuple:
        """:meth:`_search`, built once per thresholds and gains in force: they change once per level window, while a
        live stream's small packets each run the kernel (building them again cost as much as a small packet's
        kernel)."""
        key = thresholds.tobytes() + gains.tobytes()
        if self._last_search[0] != key:
            self._last_search = (key, self._search(thresholds.copy(), gains.copy()))
        return self._last_search[1]

    def _run_kernel(self, stream: np.ndarray, thresholds: np.ndarray, out_values: tuple[np.ndarray, int],
                    gains: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Run the merged events (``stream``: :func:`cvstereo.matchers._shared.merge_order.merged_stream`) through the
        kernel with the thresholds of each camera, in one row band per thread
        (:mod:`cvstereo.matchers._shared.row_bands`: the same matches however many); write each event's |D| before
        its update into ``out_values`` = ``(values, right_start)`` (the left camera's i-th event at ``values[i]``,
        the right camera's at ``values[right_start + i]``; NaN where its polarity is dropped) and return the
        matches in the stream's order: their positions in it and their disparities (views of scratch buffers)."""
        bands = self._bands.layout(self._threads, stream[ROW_Y])
        n_bands, n = self._bands.n_bands, max(1, stream.shape[1])
        out_pos = self._scratch.take("band_pos", n_bands * n, np.int64).reshape(n_bands, n)
        out_band = self._scratch.take("band_disparity", n_bands * n, np.float64).reshape(n_bands, n)
        counts = np.zeros(n_bands, np.int64)
        values, right_start = out_values
        cuts = self._bands.cuts
        if n_bands == 1:  # the serial kernel; its matches are in the stream's order already
            self.kernels[0](stream, bands, cuts, self._search_for(thresholds, gains), out_pos, out_band, counts,
                            values[np.newaxis], right_start)
            return out_pos[0, :counts[0]], out_band[0, :counts[0]]
        band_values = self._scratch.take("band_values", n_bands * values.size, np.float64).reshape(n_bands, -1)
        self.kernels[1](stream, bands, cuts, self._search_for(thresholds, gains), out_pos, out_band, counts,
                        band_values, right_start)
        gather_band_values(stream, band_values, values, right_start, cuts)
        pos, disparity = self._scratch.take("pos", n, np.int64), self._scratch.take("disparity", n, np.float64)
        m = merge_band_matches(stream.shape[1], counts, out_pos, out_band, pos, disparity)
        return pos[:m], disparity[:m]

    def _process(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        if left.size + right.size == 0:
            return empty_matches()
        # Each camera's runs of one level window (its events are time-ordered): a few searches per packet
        # rather than a sort of every event's window index.
        parts = [self._process_window(k, left[al:bl], right[ar:br]) for k, (al, bl), (ar, br)
                 in paired_window_segments(left["t"], right["t"], self.params.level_window_us)]
        return parts[0] if len(parts) == 1 else concat_matches(parts)

    def _process_window(self, k: int, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """The events of one level window: the thresholds in force for it, then the kernel, then the level."""
        n = left.size + right.size
        scratch = self._scratch
        values = scratch.take("values", n, np.float64)  # the left camera's events, then the right camera's
        values.fill(np.nan)  # where the kernel writes nothing (a dropped polarity)
        self._level.side_by_side = self._threads > 1  # the cameras' levels at once, on a matcher's threads
        thresholds = self._level.thresholds(k)
        # Merged straight from the events' fields: no int64 copy of the columns first (half the merge's time).
        stream = merged_stream(*_fields(left), *_fields(right), self._bank.slot_of_p,
                               scratch.take("stream", STREAM_ROWS * n, np.int64), pieces=self._threads)
        gains = self._gains.gains(k, thresholds, self._level)
        pos, disparity = self._run_kernel(stream, thresholds, (values, left.size), gains)
        if self._gains.estimates:  # each event's frame, only where the gains need the level split by frame
            slot_of_p = self._bank.slot_of_p
            self._gains.add(self._level, k, 0, values[:left.size], slot_of_p[(left["p"] > 0).astype(np.int64)])
            self._gains.add(self._level, k, 1, values[left.size:], slot_of_p[(right["p"] > 0).astype(np.int64)])
        else:
            self._level.add(k, 0, values[:left.size])
            self._level.add(k, 1, values[left.size:])
        return matches_at((left, right), stream, pos, disparity)

    def _feed(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        ready, held = [], []
        for old, new in zip(self._held, (left, right), strict=True):
            events = np.concatenate([old, new]) if old.size else new
            cut = count_before(events["t"], self.watermark)
            ready.append(events[:cut])
            held.append(events[cut:])
        self._held = (held[0], held[1])
        return self._process(ready[0], ready[1])

    def _flush(self) -> np.ndarray:
        left, right = self._held
        self._held = (empty_events(), empty_events())
        return self._process(left, right)
