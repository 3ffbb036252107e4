"""A streaming decoder of eDVS128 event bytes: one mechanism, parameterised by the event format.

Bytes arrive in arbitrary pieces; :meth:`StreamDecoder.decode` keeps the bytes of incomplete events
between calls and returns time-ordered events of :data:`~cvstereo.model.events.EVENT_DTYPE`.

Corrupt bytes and pauses (:mod:`cvstereo.sensors.resync`): events are cut at the current alignment until an
event's sync bit is wrong or its timestamp steps further than ``max_gap_us``; from there the decoder finds
where the stream resumes, skipping garbage (counted in :attr:`StreamDecoder.corrupt_bytes`) or keeping a
pause (whose steps, up to a wrap and beyond, the arrival times decide). The last ``confirm - 1`` events of a
call are held back until more bytes confirm them (or :meth:`StreamDecoder.flush` releases them), so garbage
cannot slip out before it is recognised.

Hidden wraps (docs/formats.md): a pause longer than one wrap of the timestamp (65.536 ms for E2) looks like a
short step. When the host's arrival time of the bytes is given (``host_t``, and ``after_t``, the reader's last
look at an empty buffer), :class:`~cvstereo.sensors.arrival.WrapClock` counts the wraps a pause hid: from the
offset between arrival and device time seen so far, each event's count is the one its arrival allows. With
arrival times within ``ARRIVAL_JITTER_US`` (20 ms) of the truth the count is decided and exact for any pause.
A reader that ran late by more than that cannot know how many wraps passed; such events are counted in
:attr:`StreamDecoder.ambiguous_wraps` and listed in :attr:`StreamDecoder.ambiguous` (the fewest possible
wraps are taken, as if the stream had run on without a pause).
Recovery: times before a listed event are exact; from it on, through the run of events whose wraps were left
open (a late read may hide further pauses inside it), they may be off by whole wraps, until an event whose
wraps the arrival times decide again: that one is exact (relative to the events before the first listed one;
on the board's clock when its epoch is known), and so are those after it up to the next listed event. So cut
the recording at a listed event, or realign it on a known event.
Streams that must stay exact under load should use a 24- or 32-bit format (``E3``/``E4``: a wrap every
16.8 s / 71.6 min), which no scheduling delay hides.

Examples
--------
>>> from cvstereo.model.events import make_events
>>> from cvstereo.sensors.protocol import ProtocolSettings, encode_events
>>> s = ProtocolSettings(event_format="E2")
>>> ev = make_events([10, 20, 60_000], [1, 2, 3], [4, 5, 6], [1, 0, 1])
>>> dec = StreamDecoder(s)
>>> out = np.concatenate([dec.decode(encode_events(ev, s)), dec.flush()])
>>> out["t"].tolist(), out["x"].tolist(), out["p"].tolist()
([10, 20, 60000], [1, 2, 3], [1, 0, 1])
"""

from __future__ import annotations

import functools

import numpy as np

from cvstereo.model.events import EVENT_DTYPE, empty_events
from cvstereo.sensors import _scan
from cvstereo.sensors._scan import Scan
from cvstereo.sensors.arrival import Pieces, WrapClock, Wraps
from cvstereo.sensors.protocol import BITS_PER_BYTE, DEFAULT_BAUD, MAX_DELTA_BYTES, ProtocolSettings
from cvstereo.sensors.resync import DEFAULT_RESYNC_EVENTS, RESYNC_WINDOW, Resync

__all__ = ["DEFAULT_CONFIRM", "DEFAULT_MAX_GAP_US", "DEFAULT_RESYNC_EVENTS", "MAX_AMBIGUOUS_LISTED",
           "MAX_GAP_WITNESSES", "RESYNC_WINDOW", "StreamDecoder", "warm_up"]

#: Events that must agree before the decoder trusts an alignment (and events held back per call).
DEFAULT_CONFIRM = 4

#: Largest timestamp step accepted without confirmation, us. Real streams carry noise events every few
#: ms; a longer pause only takes the confirmation path (no event is lost), while garbage fails it.
DEFAULT_MAX_GAP_US = 16_384

#: Most events held while the arrival times leave their wraps undecided, waiting for a later event that
#: decides them: a sender that stalled sends a catch-up burst of late events, and only the first event that
#: comes to a waiting reader again is timely enough to bound the burst's wraps.
MAX_GAP_WITNESSES = 4096

#: Gaps with ambiguous wraps listed in :attr:`StreamDecoder.ambiguous` (the count goes on).
MAX_AMBIGUOUS_LISTED = 1000


@functools.cache
def warm_up() -> None:
    """Load the compiled scanners now (from numba's cache: a fraction of a second, holding the GIL), so that
    a reader thread does not stall every thread at the start of a stream, when arrival times matter."""
    data = bytes([0x81, 0x02, 0x00, 0x10] * 16) + b"\x00\x7f" * 8
    for name in ("E1", "E2"):
        dec = StreamDecoder(ProtocolSettings(event_format=name))
        dec.decode(data)
        dec.flush()


class StreamDecoder(Resync):
    """Decode one board's byte stream into events, across calls.

    Parameters
    ----------
    settings : ProtocolSettings
        Event format, sync-bit polarity, polarity sense.
    confirm : int, keyword-only
        Events held back per call until the next ones confirm them (``confirm - 1`` held; >= 2).
    resync_events : int, keyword-only
        Consecutive events that must agree before a new alignment after corrupt bytes is trusted.
    max_gap_us : int, keyword-only
        Largest timestamp step taken without confirmation.
    byte_rate : float, keyword-only
        Bytes per second of the link (``baud / 10``); bytes read together cannot all have arrived at the
        read time, which tightens the arrival time of the earlier ones.

    Attributes
    ----------
    corrupt_bytes : int
        Bytes skipped as not part of any event.
    events_decoded : int
        Events returned so far.
    bytes_decoded : int
        Bytes of the events returned so far.
    hidden_wraps : int
        Timestamp wraps added from arrival times (pauses longer than a wrap).
    ambiguous_wraps : int
        Events whose wraps the arrival times left undecided, one per run of them: the reader ran late by more
        than its jitter, or the OS held bytes back (see the module docstring for what was taken and the
        recovery).
    ambiguous : list of tuple
        ``(event index, wraps taken, fewest, most)`` per such run (and per wrap taken within one): from that
        event on, times may be off by whole wraps until the arrival times decide an event's wraps again (the
        true count at the listed event lies between the two bounds when the OS delivered the bytes in time).
        The index counts the events returned since the decoder was made (the first ``MAX_AMBIGUOUS_LISTED``).
    """

    def __init__(self, settings: ProtocolSettings | None = None, *, confirm: int = DEFAULT_CONFIRM,
                 resync_events: int = DEFAULT_RESYNC_EVENTS, max_gap_us: int = DEFAULT_MAX_GAP_US,
                 byte_rate: float = DEFAULT_BAUD / BITS_PER_BYTE):
        self.settings = settings or ProtocolSettings()
        if confirm < 2:
            raise ValueError(f"confirm must be at least 2 events, got {confirm}.")
        if not byte_rate > 0:
            raise ValueError(f"byte_rate must be positive, got {byte_rate}.")
        self.fmt = self.settings.format
        self.confirm = int(confirm)
        self.resync_events = max(int(resync_events), self.confirm)
        self.max_gap_us = int(max_gap_us)
        self.byte_rate = float(byte_rate)
        self._sync = 0x80 if self.settings.sync_bit_set else 0
        self._buf = bytearray()
        self._pieces = Pieces()
        self._wrap = self.fmt.wrap
        # The compiled scanners' arguments for this format.
        self._kargs = (self.fmt.size, self.fmt.ts_bytes, self.fmt.delta, MAX_DELTA_BYTES, max(self._wrap, 1),
                       self._sync, self.max_gap_us)
        self.clock = WrapClock(self._wrap)
        self._searching = False
        self.corrupt_bytes = 0
        self.events_decoded = 0
        self.bytes_decoded = 0
        self.hidden_wraps = 0
        self.ambiguous_wraps = 0
        self.ambiguous: list[tuple[int, int, int, int]] = []
        self.tail_bytes = 0  # bytes of an incomplete last event at the end of the stream
        self.reset_time()

    def reset_time(self, epoch_us: int | None = None) -> None:
        """Forget the timestamp history (after ``!ET0``): the next event starts a new unwrap.

        ``epoch_us`` is the host time (as ``host_t``) at which the device clock read zero, if known: the
        first event's wraps are then counted from its arrival too.
        """
        self._last_raw: int | None = None  # the last event emitted: where times go on from
        self._last_t = 0
        self._prev_raw: int | None = None  # the last event cut: where the next cut's first step is checked from
        self._trust = True  # the next cut's first step is not checked (a new alignment, confirmed)
        self._pending: list[tuple[Scan, bool]] = []  # events cut in this call, not emitted yet (and their trust)
        self._deferred: int | None = None  # where this call's held-back events start (cut again next call)
        self.clock.reset(epoch_us)

    @property
    def pending_bytes(self) -> int:
        """Bytes held for the next call (incomplete or unconfirmed events)."""
        return len(self._buf)

    # -- cutting ----------------------------------------------------------------------------------
    def _cut(self, buf: np.ndarray, pos: int, *, limit: int | None = None, prev_raw: int | None = None,
             trust: bool | None = None) -> Scan:
        """Events from ``pos`` at its alignment (by default: continuing the last event cut)."""
        if limit is None:
            limit = (buf.size - pos) // self.fmt.size + 1
        if trust is None:
            prev_raw, trust = self._prev_raw, self._trust
        starts, ends, ts, stop, failed = _scan.cut(buf, pos, limit, *self._kargs, prev_raw or 0,
                                                   prev_raw is not None, trust)
        return Scan(starts, ends, ts, int(stop), bool(failed))

    # -- output -----------------------------------------------------------------------------------
    def _times(self, sc: Scan, clock: WrapClock):
        """Device times of ``sc``'s events (an absolute format), their arrivals, and the wraps ``clock`` takes
        from those (None when the arrival times or the clock offset are unknown)."""
        raw = sc.ts
        prev = np.empty(len(sc), np.int64)
        prev[0] = raw[0] if self._last_raw is None else self._last_raw
        prev[1:] = raw[:-1]
        base = raw[0] if self._last_raw is None else self._last_t
        t = base + np.cumsum((raw - prev) % self._wrap)
        arr = self._pieces.arrivals(sc.starts, sc.ends, self.byte_rate)
        wraps = None if arr is None else clock.decide(t, arr)
        if wraps is not None:
            t = t + wraps.added * self._wrap
        return t, arr, wraps

    def _record(self, wraps: Wraps) -> None:
        """Count the wraps added and list the runs of events whose wraps were left undecided."""
        self.hidden_wraps += int(wraps.added[-1])
        if wraps.decided.all():
            return
        undecided = ~wraps.decided
        before = np.concatenate([[0], wraps.added[:-1]])
        after_decided = np.concatenate([[not self.clock.undecided], wraps.decided[:-1]])
        for i in np.flatnonzero(undecided & (after_decided | (wraps.added != before))).tolist():
            self.ambiguous_wraps += 1
            if len(self.ambiguous) < MAX_AMBIGUOUS_LISTED:
                lo, hi = sorted((max(0, int(wraps.fewest[i] - before[i])), max(0, int(wraps.most[i] - before[i]))))
                self.ambiguous.append((self.events_decoded + i, int(wraps.added[i] - before[i]), lo, hi))

    def _take(self, sc: Scan) -> None:
        """Cut events to emit at the end of the call (with the others, so that their wraps are decided together:
        a burst behind a stalled sender shows only in its later events)."""
        if len(sc):
            self._pending.append((sc, self._trust))
            self._prev_raw, self._trust = int(sc.ts[-1]), False

    def _joined(self, sc: Scan | None = None) -> Scan:
        """The events taken in this call (and ``sc``'s) as one scan."""
        parts = [p for p, _ in self._pending] + ([sc] if sc is not None and len(sc) else [])
        if len(parts) == 1:
            return parts[0]
        cat = [np.concatenate([getattr(p, f) for p in parts] or [np.empty(0, np.int64)])
               for f in ("starts", "ends", "ts")]
        return Scan(*cat, parts[-1].stop if parts else 0, False)

    def _emit(self, host_t: int | None, *, defer: bool) -> np.ndarray:
        """The events taken in this call; with ``defer``, not the run at the end of the last piece cut whose wraps
        the arrival times leave undecided while a later event may still decide them (cut again next call)."""
        sc = self._joined()
        m = len(sc)
        if m == 0:
            return empty_events()
        fmt = self.fmt
        if fmt.delta:
            t = self._last_t + np.cumsum(sc.ts)
        elif not fmt.ts_bytes:
            # E0 carries no time: stamp with the host's arrival time, never going backwards.
            t = np.full(m, max(self._last_t, 0 if host_t is None else int(host_t)), np.int64)
        else:
            t, arr, wraps = self._times(sc, self.clock)
            last, trusted = self._pending[-1]
            if wraps is not None and defer and not wraps.decided[-1]:
                n = max(int(np.flatnonzero(np.concatenate([[True], wraps.decided]))[-1]), m - len(last))
                if m - n < MAX_GAP_WITNESSES:
                    # Cut again from there next call, from the last event emitted.
                    self._prev_raw = int(sc.ts[n - 1]) if n else self._last_raw
                    self._trust = trusted and n == m - len(last)
                    self._deferred = int(sc.starts[n])
                    sc, t, arr, wraps, m = sc.head(n), t[:n], arr.head(n), wraps.head(n), n
                    if m == 0:
                        return empty_events()
            if wraps is not None:
                self._record(wraps)
            if arr is not None:
                self.clock.observe(t, arr, wraps)
            self._last_raw = int(sc.ts[-1])
        self._last_t = int(t[-1])
        out = np.empty(m, EVENT_DTYPE)
        b0 = self._view[sc.starts]
        b1 = self._view[sc.starts + 1]
        out["t"] = t
        out["x"] = b1 & 0x7F
        out["y"] = b0 & 0x7F
        pbit = b1 >> 7
        out["p"] = (pbit == 0) if self.settings.off_bit_set else (pbit != 0)
        self.events_decoded += m
        # The events of one cut lie back to back; between cuts lie the bytes skipped.
        one_cut = len(self._pending) == 1
        self.bytes_decoded += int(sc.ends[-1] - sc.starts[0]) if one_cut else int((sc.ends - sc.starts).sum())
        return out

    def decode(self, data: bytes, *, host_t: int | None = None, fresh: bool = True, after_t: int | None = None,
               final: bool = False, release: bool = False) -> np.ndarray:
        """Decode the next bytes of the stream.

        Parameters
        ----------
        data : bytes
            The bytes, in any pieces.
        host_t : int, optional, keyword-only
            Host time (us) at which ``data`` was read: stamps events of format E0 (which carries no time)
            and lets the decoder count the timestamp wraps a long pause hides.
        fresh : bool, keyword-only
            The reader was waiting when ``data`` came (nothing was left unread before the read), so
            ``host_t`` is the arrival of its last bytes and not just a bound; only such readings measure the
            offset between host and board clock that decides the wraps of later pauses.
        after_t : int, optional, keyword-only
            Host time (us) of the reader's last look that found no byte waiting (before ``data`` came): none
            of ``data`` arrived earlier. Without it, fresh bytes are taken to have arrived at ``host_t``
            and others at any time before; with it, a late reader's wraps are decided or counted as
            ambiguous (:attr:`ambiguous_wraps`) instead of guessed, and a reading more than the host's jitter
            after it is not taken as a measure of the clock offset.
        final : bool, keyword-only
            No more bytes will come: release held events and count trailing bytes as corrupt.
        release : bool, keyword-only
            Release the events held for confirmation (the stream paused), keep incomplete bytes.

        Returns
        -------
        (N,) ndarray of EVENT_DTYPE
            Time-ordered events.
        """
        if data:
            self._buf += data
            self._pieces.add(len(self._buf), host_t, fresh, after_t)
        buf = self._view = np.frombuffer(bytes(self._buf), np.uint8)
        pos = 0
        self._pending, self._deferred = [], None
        hold = 0 if (final or release) else self.confirm - 1
        # At a pause (release) or the end (final) bad bytes are judged with the bytes there are.
        settle = 2 if final else (1 if release else 0)
        while pos < buf.size:
            if self._searching:
                q, undecided = self._first_agreeing(buf, pos, buf.size, None, settle)
                while q >= 0 and not self._may_start(buf, q):
                    q, undecided = self._first_agreeing(buf, q + 1, buf.size, None, settle)
                if q < 0:
                    stop = undecided if undecided >= 0 else buf.size
                    self.corrupt_bytes += stop - pos
                    pos = stop
                    break
                self.corrupt_bytes += q - pos
                pos = q
                self._searching = False
                self._trust = True
            sc = self._cut(buf, pos)
            m = len(sc)
            if not sc.failed:
                head = sc.head(max(0, m - hold))
                self._take(head)
                pos = head.stop
                if final and pos < buf.size:
                    self.corrupt_bytes += buf.size - pos  # an incomplete event at the very end
                    self.tail_bytes = buf.size - pos
                    pos = buf.size
                break
            found = self._resync(buf, sc, settle)
            if found is None:
                # Not enough bytes after the bad spot to decide: wait (a bounded number of bytes).
                head = sc.head(max(0, m - hold))
                self._take(head)
                pos = head.stop
                break
            q, keep = found
            head = sc.head(keep)
            self._take(head)
            if q < 0:
                pos = head.stop
                self._searching = True
                continue
            self.corrupt_bytes += q - head.stop
            self._trust = True
            pos = q
        # Events held back for the next call may only be those at the end (no bytes were counted after them).
        defer = not settle and bool(self._pending) and pos == self._pending[-1][0].stop
        out = self._emit(host_t, defer=defer)
        if self._deferred is not None:
            pos = self._deferred
        self._pending = []
        self._drop(pos)
        return out

    def _drop(self, pos: int) -> None:
        del self._buf[:pos]
        self._pieces.drop(pos)

    def flush(self, *, host_t: int | None = None, final: bool = True) -> np.ndarray:
        """Release the events held for confirmation.

        ``final=True`` (end of stream) also counts the bytes of an incomplete last event as corrupt;
        ``final=False`` (a pause in the stream) keeps them for the next call.
        """
        return self.decode(b"", host_t=host_t, final=final, release=not final)
