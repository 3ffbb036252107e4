"""Remove a rig's row and time offset between the packet source and any matcher: :class:`RigCorrection`.

The stage shifts the RIGHT camera's events: rows by ``+row_offset`` (rounded: matchers work on whole rows)
and times by ``-time_offset_us``; the left camera is the reference and passes unchanged. Matches anchored
on the right camera are mapped back (``y - row_offset``, ``t + time_offset_us``) so that they point at real
events (or, for window anchors, real windows) of the recording as it was recorded.

Conventions (the same as :class:`cvstereo.rigcheck.RigReport`):

- ``row_offset``: ``y_left ~ y_right + row_offset`` for the same scene point;
- ``time_offset_us``: ``t_right ~ t_left + time_offset_us`` for the same scene change (the right camera late).

Dropped events: a right-camera event whose shifted row leaves the sensor, or whose shifted time would be
negative (matchers keep windows and decay periods on the absolute clock from t = 0), is dropped and counted
(:attr:`CorrectedStream.dropped_rows`, :attr:`CorrectedStream.dropped_times`).

Re-slicing: a packet ``until = W`` promises later events have ``t >= W``; after the shift, later right events
have ``t >= W - time_offset_us``, so the corrected stream is complete up to ``min(W, W - time_offset_us)``.
Events of the leading camera beyond that are held back until the next packet, so every corrected packet is
again a time slice of both cameras, whatever the input packets were.

>>> import numpy as np
>>> from cvstereo.model.events import make_events, StereoPacket
>>> left = make_events([100, 900], [5, 5], [10, 10], [1, 1])
>>> right = make_events([400, 1200], [3, 3], [8, 8], [1, 1])       # 2 rows up and 300 us late
>>> stream = RigCorrection(2, 300).stream([StereoPacket(left, right, 2000)])
>>> [(p.right["t"].tolist(), p.right["y"].tolist(), p.until) for p in stream]
[([100, 900], [10, 10], 1700)]
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from cvstereo.model.events import DEFAULT_RESOLUTION, StereoPacket, count_before, empty_events
from cvstereo.model.matches import MATCH_DTYPE

__all__ = ["CorrectedStream", "RigCorrection"]


@dataclass(frozen=True)
class RigCorrection:
    """Row and time offset of the right camera, removed on the fly.

    Parameters
    ----------
    row_offset : float
        Rows added to the right camera's y (rounded to whole rows).
    time_offset_us : int
        Microseconds subtracted from the right camera's t.
    resolution : (width, height)
        Sensor size: events shifted beyond it are dropped.
    """

    row_offset: float = 0
    time_offset_us: int = 0
    resolution: tuple[int, int] = DEFAULT_RESOLUTION

    @property
    def rows(self) -> int:
        """The whole-row shift applied."""
        return round(float(self.row_offset))

    @property
    def is_identity(self) -> bool:
        """True when the stage changes nothing."""
        return self.rows == 0 and int(self.time_offset_us) == 0

    def correct_right(self, events: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shift right-camera events; return ``(corrected, kept)``.

        Parameters
        ----------
        events : (N,) ndarray of EVENT_DTYPE

        Returns
        -------
        corrected : (M,) ndarray of EVENT_DTYPE
            The kept events, shifted; still time-ordered.
        kept : (N,) bool ndarray
            Which input events survived (False: shifted off the sensor or before t = 0).
        """
        y = events["y"].astype(np.int64) + self.rows
        t = events["t"] - int(self.time_offset_us)
        kept = (y >= 0) & (y < int(self.resolution[1])) & (t >= 0)
        out = events[kept].copy()
        out["y"] = y[kept]
        out["t"] = t[kept]
        return out, kept

    def stream(self, packets: Iterable[StereoPacket]) -> CorrectedStream:
        """Wrap a packet source; iterate the result to get corrected packets (see :class:`CorrectedStream`)."""
        return CorrectedStream(self, packets)

    def restore(self, matches: np.ndarray, *, anchor: str = "event") -> np.ndarray:
        """Map matches back to the recording's own coordinates.

        Matches anchored on the right camera (``camera == 1``) get ``y - rows`` and, anchored on an event,
        ``t + time_offset_us`` (the event's own time); left-anchored matches are unchanged. A window-anchored
        match keeps its ``t``: the end of its window on the clock both cameras were matched on (the left
        camera's, the recording's), which stays on the window grid (docs/formats.md). The result is a new array,
        no longer time-ordered across cameras: sort it (:func:`cvstereo.model.matches.sort_matches`) before
        writing.

        Parameters
        ----------
        matches : (N,) ndarray of MATCH_DTYPE
        anchor : {"event", "window"}, keyword-only
            The matcher's anchor.

        Returns
        -------
        (N,) ndarray of MATCH_DTYPE
        """
        if matches.dtype != MATCH_DTYPE:
            raise ValueError(f"restore: dtype {matches.dtype} is not MATCH_DTYPE; pass a matcher's output.")
        out = matches.copy()
        right = out["camera"] == 1
        out["y"][right] -= self.rows
        if anchor == "event":
            out["t"][right] += int(self.time_offset_us)
        return out

    def describe(self) -> dict:
        """The matches-file meta entry ``rig_correction``."""
        return {"row_offset": self.rows, "time_offset_us": int(self.time_offset_us)}


class CorrectedStream(Iterator[StereoPacket]):
    """Iterator of corrected packets over a packet source (made by :meth:`RigCorrection.stream`).

    Attributes
    ----------
    dropped_rows, dropped_times : int
        Right-camera events dropped so far because the row shift took them off the sensor, or the time
        shift before t = 0.
    """

    def __init__(self, correction: RigCorrection, packets: Iterable[StereoPacket]):
        self.correction = correction
        self._source = iter(packets)
        self._held = [empty_events(), empty_events()]
        self._truth: list[np.ndarray | None] = [None, None]
        self._until: int | None = None
        self._done = False
        self.dropped_rows = 0
        self.dropped_times = 0

    def __iter__(self) -> CorrectedStream:
        return self

    def __next__(self) -> StereoPacket:
        if self._done:
            raise StopIteration
        try:
            packet = next(self._source)
        except StopIteration:
            self._done = True
            if not any(h.size for h in self._held):
                raise
            # End of stream: everything held back is complete now.
            last = [int(h["t"][-1]) + 1 for h in self._held if h.size]
            return self._emit(max([*last, self._until or 0]))
        right, kept = self.correction.correct_right(packet.right)
        if not kept.all():
            off = ~kept
            t_bad = (packet.right["t"] - int(self.correction.time_offset_us)) < 0
            self.dropped_times += int((off & t_bad).sum())
            self.dropped_rows += int((off & ~t_bad).sum())
        rtruth = None if packet.right_disparity is None else packet.right_disparity[kept]
        self._hold(0, packet.left, packet.left_disparity)
        self._hold(1, right, rtruth)
        until = int(packet.until)
        # Later left events have t >= until, later corrected right events t >= until - time_offset.
        return self._emit(min(until, until - int(self.correction.time_offset_us)))

    def _hold(self, cam: int, events: np.ndarray, truth: np.ndarray | None) -> None:
        if truth is not None or self._truth[cam] is not None:
            old = self._truth[cam] if self._truth[cam] is not None else np.full(self._held[cam].size, np.nan,
                                                                                 np.float32)
            new = truth if truth is not None else np.full(events.size, np.nan, np.float32)
            self._truth[cam] = np.concatenate([old, np.asarray(new, np.float32)])
        self._held[cam] = np.concatenate([self._held[cam], events]) if self._held[cam].size else events

    def _emit(self, until: int) -> StereoPacket:
        # The watermark never goes back, even if a source packet had an earlier `until` than the last.
        until = until if self._until is None else max(until, self._until)
        self._until = until
        out, truth = [], []
        for cam in (0, 1):
            n = count_before(self._held[cam]["t"], until)
            out.append(self._held[cam][:n])
            self._held[cam] = self._held[cam][n:]
            tr = self._truth[cam]
            truth.append(None if tr is None else tr[:n])
            if tr is not None:
                self._truth[cam] = tr[n:]
        return StereoPacket(out[0], out[1], until, truth[0], truth[1])
