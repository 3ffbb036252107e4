"""Where an eDVS byte stream resumes after a bad step: garbage to skip, or a pause to keep.

How corrupt bytes are handled (the protocol has only one sync bit per event, so a single check would
let garbage through about half of the time):

1. Events are cut at the current alignment until the first event whose sync bit is wrong or whose
   timestamp is implausible (more than ``max_gap_us`` after the previous one, modulo the wrap).
2. From there the decoder looks for the first byte position at which ``resync_events`` consecutive events
   parse with correct sync bits and plausible timestamps between them; the bytes skipped are counted in
   ``StreamDecoder.corrupt_bytes``. It first tries positions (within ``RESYNC_WINDOW`` bytes) where
   time runs on plausibly from the last event before the bad bytes (or, if that one may be garbage that
   parsed by chance, from the one before it, ...), which also decides which of those events were real.
   Otherwise (a long pause, or garbage only) it searches onwards; positions that can no longer become an
   event start are counted as corrupt at once, so garbage costs linear time and is reported as it comes.

Pauses. A step longer than ``max_gap_us`` is also what a pause looks like, and a pause just under a wrap
looks like a tiny step back (the next timestamp a little below the last one). So where the bytes after a bad
step keep the alignment, the decoder asks whether the stream simply resumes there after a pause:
``resync_events`` events with correct sync bits, in runs of plausible steps, each run's first event at a time
its arrival allows. Time running on from an event before the bad step (skipping bytes as garbage) wins over
that only where the arrival times show it hides no wrap: a continuation that needs a wrap is the stream after a
pause, seen from the far side of the wrap, and skipping would drop real events up to it. Without arrival times
the continuation wins (a pause just under a wrap then costs the events before time seems to run on).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cvstereo.sensors import _scan
from cvstereo.sensors._scan import Scan
from cvstereo.sensors.arrival import WrapClock
from cvstereo.sensors.protocol import MAX_DELTA_BYTES

__all__ = ["DEFAULT_RESYNC_EVENTS", "RESYNC_WINDOW", "Resync"]

#: Events that must agree before the decoder trusts a new alignment found after corrupt bytes. Garbage
#: passes one event's checks with a probability of about 1/8 (E2), so eight in a row is ~1e-7.
DEFAULT_RESYNC_EVENTS = 8

#: Bytes after a corruption searched first for an alignment that also continues the time of the last
#: good event (the common case: garbage in an otherwise continuous stream).
RESYNC_WINDOW = 512


@dataclass
class _Trial:
    """The clock as it would be after the events cut so far in this call and those before a bad step (their raw
    timestamps and times; ``offset`` of them come before the bad step's scan), and the event emitted before."""

    clock: WrapClock
    raws: np.ndarray
    times: np.ndarray
    offset: int
    raw0: int | None
    t0: int

    def before(self, keep: int) -> tuple[int | None, int]:
        """(raw timestamp, time) of the event time runs on from when the first ``keep`` events of the scan are
        kept."""
        i = self.offset + keep
        return (int(self.raws[i - 1]), int(self.times[i - 1])) if i else (self.raw0, self.t0)

    def last(self) -> tuple[int | None, int]:
        """(raw timestamp, time) of the last event."""
        return self.before(len(self.raws) - self.offset)


class Resync:
    """The decoder's search for where its stream resumes: a base of
    :class:`~cvstereo.sensors.decoder.StreamDecoder`, which provides the cutting (``_cut``), the wrap clock,
    the pieces' arrival times and the last event emitted."""

    def _first_agreeing(self, buf: np.ndarray, lo: int, hi: int, prev_raw: int | None, settle: int):
        # A continuation of `prev_raw` needs all `resync_events`; the search after a pause or garbage may
        # settle for fewer at a pause or the end of the stream (the real alignment comes first there).
        q, undecided = _scan.first_agreeing(buf, lo, hi, self.resync_events, *self._kargs,
                                            prev_raw or 0, prev_raw is not None, prev_raw is None, settle)
        return int(q), int(undecided)

    def _continuation(self, buf: np.ndarray, sc: Scan, settle: int) -> tuple[int, int] | None:
        """After bad bytes at ``sc.stop``: (position where time runs on, events of ``sc`` to keep), or
        (-1, len(sc)) when nothing continues (search onwards), or None when more bytes are needed."""
        m = len(sc)
        p = sc.stop
        # Time runs on from the last real event before the garbage; which of the events just before it are
        # themselves garbage (parsed by chance) is decided by trying to continue from each of them.
        lo = max(0, m - (self.confirm - 1))
        prevs = [(j + 1, int(sc.ts[j])) for j in range(m - 1, lo - 1, -1)]
        if lo == 0 and self._prev_raw is not None:
            prevs.append((0, self._prev_raw))
        short = p + RESYNC_WINDOW > buf.size and not settle
        best = None
        for keep, prev in prevs:
            # The earliest resumption wins: from a garbage "event", time only seems to run on once the real
            # stream has caught up with its random timestamp, many events later.
            hi = min(buf.size, p + RESYNC_WINDOW, best[0] if best else buf.size)
            q, undecided = self._first_agreeing(buf, p, hi, prev, settle)
            if q >= 0:
                best = (q, keep)
            elif (undecided >= 0 and not settle) or (short and best is None):
                return None
        return best if best is not None else (-1, m)

    def _resync(self, buf: np.ndarray, sc: Scan, settle: int) -> tuple[int, int] | None:
        """After a bad step at ``sc.stop``: (position where the stream resumes, events of ``sc`` to keep), or
        (-1, len(sc)) when nothing resumes nearby (search onwards), or None when more bytes are needed."""
        m = len(sc)
        if not self.fmt.ts_bytes:
            return -1, m
        p = sc.stop
        trial = self._trial(sc)
        pause = False if trial is None else self._resumes(buf, p, trial, settle)
        found = self._continuation(buf, sc, settle)
        runs_on = found is not None and found[0] >= 0
        if runs_on and (trial is None or not self._hides_a_wrap(buf, found, trial)):
            return found  # time runs on from an event before the bad step: the bytes between were garbage
        if pause:
            return p, m
        if pause is None:
            return None
        if runs_on:
            # The continuation needs a wrap: the stream more likely resumed after a pause, behind garbage.
            for r in range(p + 1, found[0] + 1):
                if (buf[r] & 0x80) == self._sync and self._resumes(buf, r, trial, settle):
                    return r, m
        return found

    def _trial(self, sc: Scan) -> _Trial | None:
        """The clock after the events cut so far and ``sc``'s, tried without committing; None without arrival
        times or a clock offset."""
        if not self._pieces.timed:
            return None
        joined = self._joined(sc)
        clock = self.clock.copy()
        times = np.empty(0, np.int64)
        if len(joined):
            times, arr, wraps = self._times(joined, clock)
            if arr is None:
                return None
            clock.observe(times, arr, wraps)
        if clock.lo is None or (not len(joined) and self._last_raw is None):
            return None
        return _Trial(clock, joined.ts, times, len(joined) - len(sc), self._last_raw, self._last_t)

    def _next_event(self, buf: np.ndarray, pos: int, raw: int, t: int):
        """(device time before wraps, arrival) of the event at byte ``pos`` if it followed an event (``raw``,
        ``t``); the arrival is None when unknown."""
        _, _, ts = _scan.event_at(buf, pos, self.fmt.size, self.fmt.ts_bytes, self.fmt.delta, MAX_DELTA_BYTES,
                                  self._sync)
        arr = self._pieces.arrivals(np.array([pos]), np.array([pos + self.fmt.size]), self.byte_rate)
        return np.array([t + (int(ts) - raw) % self._wrap], np.int64), arr

    def _may_start(self, buf: np.ndarray, q: int) -> bool:
        """Whether the search may resume at byte ``q``: ``resync_events`` agree there, or (fewer, at a pause or
        the end) the first event's time fits its arrival."""
        run = self._cut(buf, q, limit=self.resync_events, prev_raw=None, trust=True)
        if len(run) >= self.resync_events or not self.fmt.ts_bytes:
            return True
        trial = self._trial(run.head(0))
        if trial is None:
            return True
        raw, t = trial.last()
        if raw is None:
            raw = t = int(run.ts[0])
        base, arr = self._next_event(buf, q, raw, t)
        return arr is None or bool(trial.clock.allows(base, arr)[0])

    def _hides_a_wrap(self, buf: np.ndarray, found: tuple[int, int], trial: _Trial) -> bool:
        """Whether the arrival times allow a wrap between the event time would run on from and the event at
        the continuation ``found``."""
        q, keep = found
        raw, t = trial.before(keep)
        if raw is None:
            return False
        base, arr = self._next_event(buf, q, raw, t)
        wraps = None if arr is None else trial.clock.decide(base, arr)
        return wraps is not None and int(wraps.most[0]) >= 1

    def _resumes(self, buf: np.ndarray, p: int, trial: _Trial, settle: int) -> bool | None:
        """Whether the stream resumes at byte ``p`` after a pause: ``resync_events`` events at its alignment,
        in runs of plausible steps, each run's first event at a time its arrival allows. None: the bytes end
        before that is decided (and the stream has not paused)."""
        (raw, t), count = trial.last(), 0
        while count < self.resync_events:
            run = self._cut(buf, p, limit=self.resync_events - count, prev_raw=raw, trust=True)
            if not len(run):
                return (count > 0 if settle else None) if not run.failed else False
            base, arr = self._next_event(buf, p, raw, t)
            if arr is not None and not trial.clock.allows(base, arr)[0]:
                return False
            wraps = None if arr is None else trial.clock.decide(base, arr)
            t = int(base[0]) + (int(wraps.added[0]) * self._wrap if wraps is not None else 0)
            t += int((np.diff(run.ts) % self._wrap).sum())
            raw, p, count = int(run.ts[-1]), run.stop, count + len(run)
            if not run.failed and count < self.resync_events:
                return True if settle else None
        return True
