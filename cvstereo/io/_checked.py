"""Validation of one camera's stream chunk by chunk, naming the file position of the first bad event.

Every reader converts its raw columns to :data:`~cvstereo.events.EVENT_DTYPE` through one
:class:`ChunkChecker` per camera, so that the contract of formats.md (integer fields, polarity, range,
time order across chunk boundaries) is enforced in one place and errors name where in the *file* the
offending event is (a text line, a byte offset), not only its index in the camera's stream.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.events import as_events, validate_events


class ChunkChecker:
    """Convert and validate consecutive chunks of one camera's event stream.

    Parameters
    ----------
    resolution : (width, height) or None, keyword-only
        Coordinates must lie inside; None skips the range check.
    source : str, keyword-only
        Named in error messages, e.g. ``"rec.dat [retina 1]"``.

    Examples
    --------
    >>> from cvstereo.events import make_events
    >>> check = ChunkChecker(resolution=(128, 128), source="demo")
    >>> check(make_events([0, 5], [1, 2], [3, 4], [1, -1]))["p"].tolist()
    [1, 0]
    >>> check(make_events([4], [1], [1], [1]))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    cvstereo.errors.EventFormatError: demo: field 't' at index 2 is 4, earlier than the preceding event (5); ...
    """

    def __init__(self, *, resolution: tuple[int, int] | None, source: str):
        self.resolution = resolution
        self.source = source
        #: Events accepted so far (the stream index of the next chunk's first event).
        self.count = 0
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
        self.count += events.size
        if events.size:
            self._t_last = int(events["t"][-1])
        return events

    def _check(self, raw: np.ndarray) -> np.ndarray:
        events = as_events(raw, resolution=self.resolution, source=self.source, index_offset=self.count)
        if events.size and self._t_last is not None:
            validate_events(events[:1], resolution=None, source=self.source, index_offset=self.count,
                            t_floor=self._t_last)
        return events

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
