"""When the decoder's bytes arrived, and how many timestamp wraps that shows a pause hid.

A 16-bit timestamp (E2) wraps every 65.536 ms, so a pause of about a wrap or more hides whole wraps: only the
host's arrival time of the bytes tells how many passed (docs/formats.md). This module keeps the pieces of bytes the
decoder holds with what the reader knew of their arrival (:class:`Pieces`), and decides each event's wraps
from them (:class:`WrapClock`).

The model. The *reading* of an event is the host time at which a reader waiting at the port had its first
byte. ``d = reading - device time`` is the clock offset plus the link's latency and the host's jitter, so the
readings of a stream lie within ``2 * jitter_us`` of each other in ``d``. The readings seen (the last event of
each piece that came to a waiting reader) form a band ``[lo, hi]`` of ``d``; a new event's ``d`` may lie
anywhere within ``2 * jitter_us`` of both edges. Of the wrap counts (each moves ``d`` by a wrap) those whose
``d`` can lie there are *possible*; the fewest possible is taken (too few wraps are made up at the next event
whose count is decided; too many never are, as time does not run back). Where exactly one is possible the
count is decided. With the host's arrival times within ``jitter_us`` of the truth, a reading
lies within ``2 * jitter_us`` of the band's far edge while the next count's lies a wrap (65.5 ms for E2) away,
so once the band holds the truth (the epoch of the board's clock is known, or readings from both sides of it
were seen) the count is decided and right.

Two more facts narrow it. A reading is exact only for a piece that came to a waiting reader (*fresh*); a
reader that ran late only knows that the bytes came after its last look at an empty buffer (``after_t``) and
before its read. And an event cannot be read before it happened: an event's count is at most that of any
later event, whose upper bound therefore binds the earlier ones too (a sender that stalled sends late events
in a burst, and the burst's last events are timely again). Such a burst also shows in the readings
themselves where a later event was read as early, relative to its device time, as an earlier one by more than
the readings' spread: the earlier one (and the bytes queued behind it) came late, and its reading bounds its
count from above only. An event whose count is left open, or whose own
reading contradicts the counts around it, is *undecided*: the decoder lists it (``StreamDecoder.ambiguous``)
instead of guessing silently, and does not learn the clock offset from it.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ARRIVAL_JITTER_US", "ARRIVAL_SLACK_US", "OFFSET_LEAK", "Arrivals", "Pieces", "WrapClock", "Wraps"]

#: Largest error of the host's arrival times, us: a waiting reader's time of an event's bytes is within this
#: of the event's device time plus a constant offset (thread scheduling, the USB adapter's latency timer: 16 ms
#: by default on FTDI chips).
ARRIVAL_JITTER_US = 20_000

#: Slack on the spread of readings before a wrap count is impossible, us (the link time of a piece, rounding).
ARRIVAL_SLACK_US = 2_000

#: How fast the band of clock offsets narrows without new readings, per us: clocks drift (crystals, about
#: 1e-4 apart at most), so a reading seen long ago says less about today's offset.
OFFSET_LEAK = 1e-4


@dataclass
class Arrivals:
    """What the host knew of each event's arrival (host us).

    ``hi``: latest time at which its first byte can have been read; ``lo``: earliest (``hi`` when the reading is
    exact, ``-inf`` when unknown); ``seen``: the reading is exact and ends its piece, so it measures the clock
    offset; ``waited``: the event begins a piece that came to a waiting reader (the bytes before it were all
    read).
    """

    hi: np.ndarray
    lo: np.ndarray
    seen: np.ndarray
    waited: np.ndarray

    def head(self, n: int) -> Arrivals:
        return Arrivals(self.hi[:n], self.lo[:n], self.seen[:n], self.waited[:n])


class Pieces:
    """The pieces of bytes a decoder holds, each with its reader's host time, freshness and last empty look."""

    def __init__(self):
        # (end offset in the decoder's buffer, host us of the read or NaN, fresh, host us of the last empty look
        # or -inf) per piece, as floats: one array per call
        self._segs: list[tuple[float, float, float, float]] = []

    def add(self, end: int, host_t: int | None, fresh: bool, after_t: int | None) -> None:
        """A piece read at ``host_t`` now ends the buffer at ``end``."""
        self._segs.append((end, np.nan if host_t is None else host_t, float(fresh),
                           -np.inf if after_t is None else after_t))

    def drop(self, pos: int) -> None:
        """The first ``pos`` bytes of the buffer are gone."""
        self._segs = [(e - pos, h, f, a) for e, h, f, a in self._segs if e > pos]

    @property
    def timed(self) -> bool:
        """Every piece held came with a host time."""
        return bool(self._segs) and not any(math.isnan(h) for _, h, _, _ in self._segs)

    def arrivals(self, starts: np.ndarray, ends: np.ndarray, byte_rate: float) -> Arrivals | None:
        """The arrival of the events at byte offsets ``starts``..``ends`` (sorted), or None when a piece holding
        them came without a host time."""
        if not self.timed:
            return None
        seg_end, seg_t, seg_fresh, seg_after = np.array(self._segs).T
        idx = np.minimum(np.searchsorted(seg_end, starts, side="right"), seg_end.size - 1)
        end, fresh, after = seg_end[idx], seg_fresh[idx] > 0, seg_after[idx]
        # The bytes read after an event's first byte took at least this long to come over the link.
        hi = seg_t[idx] - (end - starts) * (1e6 / byte_rate)
        # Bytes read by a waiting reader came after its last look at an empty buffer (if known, else at the read);
        # a late reader knows only that look. The last event of a piece read promptly measures the offset.
        lo = np.minimum(np.where(fresh & (after == -np.inf), hi, after), hi)
        seen = fresh & (ends >= end) & (hi - lo <= ARRIVAL_JITTER_US)
        waited = fresh.copy()
        waited[1:] &= idx[1:] != idx[:-1]
        return Arrivals(hi, lo, seen, waited)


@dataclass
class Wraps:
    """The wraps :meth:`WrapClock.decide` found for a run of events (counts relative to the times given).

    ``added``: wraps added up to each event; ``decided``: exactly one count was possible for it; ``fits``: its
    own reading allows the count taken; ``fewest``/``most``: the counts that were possible (for the listing).
    """

    added: np.ndarray
    decided: np.ndarray
    fits: np.ndarray
    fewest: np.ndarray
    most: np.ndarray

    def head(self, n: int) -> Wraps:
        return Wraps(self.added[:n], self.decided[:n], self.fits[:n], self.fewest[:n], self.most[:n])


class WrapClock:
    """The band of clock offsets seen, and the wraps of new events it decides (see the module docstring).

    Parameters
    ----------
    wrap : int
        Period of the timestamp, us (0: the format has none, nothing to decide).
    jitter_us : float, keyword-only
        Largest error of a waiting reader's arrival time (:data:`ARRIVAL_JITTER_US`).
    """

    def __init__(self, wrap: int, *, jitter_us: float = ARRIVAL_JITTER_US):
        self.wrap = int(wrap)
        self.spread = 2.0 * float(jitter_us)
        self.reset()

    def reset(self, epoch_us: float | None = None) -> None:
        """Forget the offsets seen; ``epoch_us``: host time at which the board's clock read 0, if known."""
        self.lo = self.hi = self.at = None if epoch_us is None else float(epoch_us)
        self.undecided = False  # the last event taken was undecided

    def copy(self) -> WrapClock:
        """An independent copy (to try a reading of the bytes without committing to it)."""
        return copy.copy(self)

    def _band(self, now: float) -> tuple[float, float]:
        lo, hi = self.lo, self.hi
        shrink = min(OFFSET_LEAK * max(0.0, now - self.at), (hi - lo) / 2)
        return lo + shrink, hi - shrink

    def decide(self, t: np.ndarray, arr: Arrivals) -> Wraps | None:
        """The wraps of events at device times ``t`` (already unwrapped by their steps) that arrived as ``arr``;
        None while no offset is known (the first events of a stream whose epoch is unknown)."""
        if self.lo is None or not self.wrap or not t.size:
            return None
        w = float(self.wrap)
        lo_d, hi_d = self._band(float(arr.hi[0]))
        reach_lo = hi_d - self.spread - ARRIVAL_SLACK_US  # the smallest d a reading can have
        reach_hi = lo_d + self.spread + ARRIVAL_SLACK_US  # the largest
        x_hi = arr.hi - t  # d + count * wrap, for the latest and the earliest reading
        x_lo = arr.lo - t
        if x_hi.min() >= reach_lo and x_hi.max() < reach_lo + w and not x_lo.max() > reach_hi:
            # Every reading allows no wrap and none more (a stream read as it comes): nothing to add.
            none, yes = np.zeros(t.size, np.int64), np.ones(t.size, bool)
            return Wraps(none, yes, yes, none, none)
        known = np.isfinite(arr.lo) & ~_caught_up(t, arr, self.spread + ARRIVAL_SLACK_US)
        most = np.floor((x_hi - reach_lo) / w)  # hard: no reading comes before its event happened
        least = np.where(known, np.ceil((np.where(known, x_lo, 0.0) - reach_hi) / w), -np.inf)  # soft: late deliveries
        # No event has more wraps than a later one can have; none has fewer than the one before. The fewest
        # possible is taken: too few wraps are made up at the next event whose count is decided, too many never
        # are (time does not run back).
        most_after = np.minimum.accumulate(most[::-1])[::-1]
        added = np.maximum.accumulate(np.maximum(np.minimum(least, most_after), 0.0))
        before = np.concatenate([[0.0], added[:-1]])
        fewest = np.where(least > most_after, before, np.maximum(before, least))
        decided = (fewest == most_after) & (added == most_after)
        fits = (added >= least) & (added <= most)
        return Wraps(added.astype(np.int64), decided, fits, fewest.astype(np.int64),
                     np.maximum(most_after, before).astype(np.int64))

    def allows(self, t: np.ndarray, arr: Arrivals) -> np.ndarray:
        """Whether some number of wraps (fewer than none included: the times before may be late) puts each
        event at a time its own arrival allows; all True while no offset is known."""
        if self.lo is None or not self.wrap:
            return np.ones(t.size, bool)
        w = float(self.wrap)
        lo_d, hi_d = self._band(float(arr.hi[0]))
        most = np.floor((arr.hi - t - (hi_d - self.spread - ARRIVAL_SLACK_US)) / w)
        known = np.isfinite(arr.lo)
        least = np.ceil((np.where(known, arr.lo, 0.0) - t - (lo_d + self.spread + ARRIVAL_SLACK_US)) / w)
        return ~known | (least <= most)

    def observe(self, t: np.ndarray, arr: Arrivals, wraps: Wraps | None) -> None:
        """Take the events at final device times ``t`` (as decided by ``wraps``): learn the clock offset from
        the exact readings among them whose count was decided and fits."""
        now = float(arr.hi[-1]) if arr.hi.size else None
        ok = arr.seen if wraps is None else arr.seen & wraps.decided & wraps.fits
        if wraps is not None and wraps.decided.size:
            self.undecided = not bool(wraps.decided[-1])
        if now is None:
            return
        if self.lo is not None:
            self.lo, self.hi = self._band(now)
            self.at = now
        if not ok.any():
            return
        d = arr.hi[ok] - t[ok]
        latest = float(d[-1])
        lo = float(d.min()) if self.lo is None else min(self.lo, float(d.min()))
        hi = float(d.max()) if self.hi is None else max(self.hi, float(d.max()))
        # Readings further apart than the spread: the offset moved (drift, a host clock step); the latest wins.
        lo, hi = max(lo, latest - self.spread), min(hi, latest + self.spread)
        if hi - lo > self.spread:
            lo, hi = (hi - self.spread, hi) if latest - lo > hi - latest else (lo, lo + self.spread)
        self.lo, self.hi, self.at = lo, hi, now


def _caught_up(t: np.ndarray, arr: Arrivals, spread: float) -> np.ndarray:
    """Events that came late, in a burst behind a stalled sender: a later event was read as early, relative to
    its device time, by more than the readings' spread (events between them only make that gap larger), and
    the bytes queued behind a late event were late too until the reader waits again. Their readings bound
    their wraps from above only."""
    u = t - arr.hi  # device time minus reading: the larger, the more timely
    late = np.maximum.accumulate(u[::-1])[::-1] - u > spread
    if late.any():
        last_late = np.maximum.accumulate(np.where(late, np.arange(t.size), -1))
        burst = np.cumsum(arr.waited)
        late = (last_late >= 0) & (burst[np.maximum(last_late, 0)] == burst)
    return late
