"""Validation of one camera's stream chunk by chunk, naming the file position of the first bad event.

Every reader converts its raw columns to :data:`~cvstereo.model.events.EVENT_DTYPE` through one
:class:`ChunkChecker` per camera, so that the contract of docs/formats.md (integer fields, polarity, range,
time order across chunk boundaries) is enforced in one place and errors name where in the *file* the
offending event is (a text line, a byte offset), not only its index in the camera's stream.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.model.columns import check_polarity, labelled
from cvstereo.model.events import as_events, events_from_columns, validate_events


class ChunkChecker:
    """Convert and validate consecutive chunks of one camera's event stream.

    Parameters
    ----------
    resolution : (width, height) or None, keyword-only
        Coordinates must lie inside; None skips the range check.
    source : str, keyword-only
        Named in error messages, e.g. ``"rec.dat [retina 1]"``.
    labels : dict, optional, keyword-only
        How the file names each field, e.g. ``{"t": "/events/t"}`` (see
        :func:`cvstereo.model.events.events_from_columns`).
    start : int, keyword-only
        Stream index of the first event checked (a reader that starts mid-file names file positions).

    Examples
    --------
    >>> from cvstereo.model.events import make_events
    >>> check = ChunkChecker(resolution=(128, 128), source="demo")
    >>> check(make_events([0, 5], [1, 2], [3, 4], [1, -1]))["p"].tolist()
    [1, 0]
    >>> check(make_events([4], [1], [1], [1]))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    cvstereo.errors.EventFormatError: demo: field 't' at index 2 is 4, earlier than the preceding event (5); ...
    """

    def __init__(self, *, resolution: tuple[int, int] | None, source: str, labels: dict[str, str] | None = None,
                 start: int = 0):
        self.resolution = resolution
        self.source = source
        self.labels = labels
        #: The stream index of the next chunk's first event (events accepted so far, plus ``start``).
        self.count = start
        self._t_last: int | None = None

    def __call__(self, raw: np.ndarray, locate: Callable[[int], str] | None = None) -> np.ndarray:
        """Validate the next chunk and return it as EVENT_DTYPE.

        Parameters
        ----------
        raw : (N,) structured ndarray
            Fields t, x, y, p (any integer widths; p as 1/0, +1/-1 or bool).
        locate : callable, optional
            ``locate(i)`` describes where row ``i`` of this chunk sits in the file ("line 12: '...'");
            appended to error messages.

        Raises
        ------
        EventFormatError
            Naming the source, field, stream index and (with ``locate``) the file position.
        """
        try:
            events = self._check(raw)
        except EventFormatError:
            if locate is None:
                raise
            # The whole-chunk message names the first failing *check*, which need not be the first bad
            # row; find the first bad row (prefix validity is monotone) and report that one.
            i = self._first_bad_row(raw)
            try:
                self._check(raw[: i + 1])
            except EventFormatError as first:
                exc = first
            raise EventFormatError(f"{exc} [{locate(i)}]") from None
        return self._accepted(events)

    def columns(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray, *, t_offset: int = 0) -> np.ndarray:
        """Validate the next chunk given as four raw columns (as a file stores them) and return it as EVENT_DTYPE.

        Every value is checked in its stored dtype before the cast (:func:`cvstereo.model.events.events_from_columns`);
        ``t_offset`` is added to the times.
        """
        floor = None if self._t_last is None else self._t_last - t_offset
        return self._accepted(events_from_columns(t, x, y, p, resolution=self.resolution, source=self.source,
                                                  index_offset=self.count, labels=self.labels, t_offset=t_offset,
                                                  t_floor=floor))

    def adopt(self, events: np.ndarray) -> np.ndarray:
        """Validate the next chunk, an array of EVENT_DTYPE that the caller owns, in place, and return it.

        For readers whose decoder already wrote the event dtype's layout (a buffer of its own): the values are
        checked as :func:`cvstereo.model.events.events_from_columns` checks them, without a copy; polarities -1 become
        0.
        """
        check_polarity(events["p"], source=self.source, label=labelled(self.labels)["p"], index_offset=self.count)
        validate_events(events, resolution=self.resolution, source=self.source, index_offset=self.count,
                        t_floor=self._t_last, labels=self.labels)
        if events.size and events["p"].min() < 0:
            events["p"] = events["p"] > 0
        return self._accepted(events)

    def _accepted(self, events: np.ndarray) -> np.ndarray:
        self.count += events.size
        if events.size:
            self._t_last = int(events["t"][-1])
        return events

    def _check(self, raw: np.ndarray) -> np.ndarray:
        return as_events(raw, resolution=self.resolution, source=self.source, index_offset=self.count,
                         t_floor=self._t_last)

    def _first_bad_row(self, raw: np.ndarray) -> int:
        lo, hi = 0, len(raw) - 1
        while lo < hi:
            mid = (lo + hi) // 2
            try:
                self._check(raw[: mid + 1])
            except EventFormatError:
                hi = mid
            else:
                lo = mid + 1
        return lo
