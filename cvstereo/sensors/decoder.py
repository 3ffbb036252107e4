"""A streaming decoder of eDVS128 event bytes: one mechanism, parameterised by the event format.

Bytes arrive in arbitrary pieces; :meth:`StreamDecoder.decode` keeps the bytes of incomplete events
between calls and returns time-ordered events of :data:`~cvstereo.events.EVENT_DTYPE`.

How corrupt bytes are handled (the protocol has only one sync bit per event, so a single check would
let garbage through about half of the time):

1. Events are cut at the current alignment until the first event whose sync bit is wrong or whose
   timestamp is implausible (more than ``max_gap_us`` after the previous one, modulo the wrap).
2. From there the decoder looks for the first byte position at which ``resync_events`` consecutive events
   parse with correct sync bits and plausible timestamps between them; the bytes skipped are counted in
   :attr:`StreamDecoder.corrupt_bytes`. It first tries positions (within ``RESYNC_WINDOW`` bytes) where
   time runs on plausibly from the last event before the bad bytes (or, if that one may be garbage that
   parsed by chance, from the one before it, ...), which also decides which of those events were real.
   Otherwise (a long pause, or garbage only) it searches onwards; positions that can no longer become an
   event start are counted as corrupt at once, so garbage costs linear time and is reported as it comes.

The last ``confirm - 1`` events of a call are held back until more bytes confirm them (or
:meth:`StreamDecoder.flush` releases them), so garbage cannot slip out before it is recognised.

Hidden wraps (formats.md): a pause longer than one wrap of the timestamp (65.536 ms for E2) looks like a
short step. When the host's arrival time of the bytes is given (``host_t``), the decoder counts the wraps
a pause hid: an event cannot arrive before it happened, so its device time is at most its arrival time
minus the smallest ``arrival - device time`` seen recently (the clock offset); the largest number of
wraps within that bound is taken. This is only done after a gap in arrival times of half a wrap or more,
so a continuous stream is never changed.

That upper bound is only tight if the reader took the bytes as they came. A reader descheduled for more
than a wrap (a loaded machine) reads a burst of bytes that waited in the OS buffer, and its read time no
longer bounds the wraps from below. So the reader also passes ``after_t``, the host time of its last look
that found the OS buffer empty: every byte read since arrived after it, and (device-to-host latency being
under ``ARRIVAL_LATENCY_US``) the event happened no earlier than ``after_t - offset - latency``. Where the
two bounds leave exactly one wrap count, it is taken. Where they leave several, the wraps cannot be known
from the host: the decoder takes the fewest (the stream is taken to have run on without a pause); where they
contradict each other (the OS held bytes back longer than any board does), it keeps the upper bound. Both
are counted in :attr:`StreamDecoder.ambiguous_wraps` and listed in :attr:`StreamDecoder.ambiguous`.
Recovery: events between two listed gaps keep exact relative times; after a listed gap the times may be off
by whole wraps (so cut the recording there, or realign it on a known event). Streams that must stay exact
under load should use a 24- or 32-bit format (``E3``/``E4``: a wrap every 16.8 s / 71.6 min), which no
scheduling delay hides.

Examples
--------
>>> from cvstereo.events import make_events
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
import itertools
import math
from dataclasses import dataclass

import numpy as np

from cvstereo.events import EVENT_DTYPE, empty_events
from cvstereo.sensors import _scan
from cvstereo.sensors.protocol import BITS_PER_BYTE, DEFAULT_BAUD, MAX_DELTA_BYTES, ProtocolSettings

#: Events that must agree before the decoder trusts an alignment (and events held back per call).
DEFAULT_CONFIRM = 4

#: Events that must agree before the decoder trusts a new alignment found after corrupt bytes. Garbage
#: passes one event's checks with a probability of about 1/8 (E2), so eight in a row is ~1e-7.
DEFAULT_RESYNC_EVENTS = 8

#: Bytes after a corruption searched first for an alignment that also continues the time of the last
#: good event (the common case: garbage in an otherwise continuous stream).
RESYNC_WINDOW = 512

#: Largest timestamp step accepted without confirmation, us. Real streams carry noise events every few
#: ms; a longer pause only takes the confirmation path (no event is lost), while garbage fails it.
DEFAULT_MAX_GAP_US = 16_384

#: Slack of the arrival-time bound on device time, us (host scheduling jitter, command transit).
ARRIVAL_SLACK_US = 2_000

#: Most events held after an arrival gap while waiting for a fresh (timely) later event, which decides the
#: gap's wraps: a sender that stalled sends a catch-up burst of late events, and only the first event that
#: comes to a waiting reader again is timely enough to veto a wrap the late ones seem to show.
MAX_GAP_WITNESSES = 4096

#: Longest the bytes of an event take from the board's clock to the host's OS buffer, us (UART FIFO, the USB
#: adapter's latency timer, 16 ms by default on FTDI chips): bounds device time from below (``after_t``).
ARRIVAL_LATENCY_US = 20_000

#: Gaps with ambiguous wraps listed in :attr:`StreamDecoder.ambiguous` (the count goes on).
MAX_AMBIGUOUS_LISTED = 1000

#: How fast the clock-offset estimate may rise without a faster event confirming it (clock drift), per us.
OFFSET_LEAK = 1e-4


@functools.cache
def warm_up() -> None:
    """Load the compiled scanners now (from numba's cache: a fraction of a second, holding the GIL), so that
    a reader thread does not stall every thread at the start of a stream, when arrival times matter."""
    data = bytes([0x81, 0x02, 0x00, 0x10] * 16) + b"\x00\x7f" * 8
    for name in ("E1", "E2"):
        dec = StreamDecoder(ProtocolSettings(event_format=name))
        dec.decode(data)
        dec.flush()


@dataclass
class _Scan:
    """Events cut from a buffer: byte offsets, raw timestamps and where the cut stopped."""

    starts: np.ndarray
    ends: np.ndarray
    ts: np.ndarray  # raw timestamp (absolute formats) or delta (E1); zeros for E0
    stop: int
    failed: bool

    def __len__(self) -> int:
        return self.starts.size

    def head(self, k: int) -> _Scan:
        stop = int(self.starts[k]) if k < len(self) else self.stop
        return _Scan(self.starts[:k], self.ends[:k], self.ts[:k], stop, False)


class StreamDecoder:
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
        Arrival gaps (or late reads) whose wraps the arrival times could not decide: the reader ran late
        by more than a wrap, or the OS held bytes back (see the module docstring for what was taken and
        the recovery).
    ambiguous : list of tuple
        ``(event index, wraps taken, fewest, most)`` per ambiguous gap: from that event on, times may be off
        by whole wraps (the true count lies between the two bounds when the OS delivered the bytes in
        time). The index counts the events returned since the decoder was made (the first
        ``MAX_AMBIGUOUS_LISTED`` gaps).
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
        # [end offset in _buf, host read us, fresh, host us before which none of it had arrived] per piece held
        self._segs: list[list] = []
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
        self._last_raw: int | None = None
        self._last_t = 0
        self._trust = True
        self._last_arrival = None if epoch_us is None else float(epoch_us)
        self._offset = None if epoch_us is None else float(epoch_us)  # min(arrival - device time), us
        self._offset_at = self._last_arrival

    @property
    def pending_bytes(self) -> int:
        """Bytes held for the next call (incomplete or unconfirmed events)."""
        return len(self._buf)

    # -- cutting ----------------------------------------------------------------------------------
    def _kernel_args(self):
        f = self.fmt
        return f.size, f.ts_bytes, f.delta, MAX_DELTA_BYTES, max(f.wrap, 1), self._sync, self.max_gap_us

    def _cut(self, buf: np.ndarray, pos: int) -> _Scan:
        limit = (buf.size - pos) // self.fmt.size + 1
        has_prev = self._last_raw is not None
        starts, ends, ts, stop, failed = _scan.cut(buf, pos, limit, *self._kernel_args(),
                                                   self._last_raw or 0, has_prev, self._trust)
        return _Scan(starts, ends, ts, int(stop), bool(failed))

    def _first_agreeing(self, buf: np.ndarray, lo: int, hi: int, prev_raw: int | None, settle: int):
        # A continuation of `prev_raw` needs all `resync_events`; the search after a pause or garbage may
        # settle for fewer at a pause or the end of the stream (the real alignment comes first there).
        q, undecided = _scan.first_agreeing(buf, lo, hi, self.resync_events, *self._kernel_args(),
                                            prev_raw or 0, prev_raw is not None, prev_raw is None, settle)
        return int(q), int(undecided)

    def _resync(self, buf: np.ndarray, sc: _Scan, settle: int) -> tuple[int, int] | None:
        """After bad bytes at ``sc.stop``: (position where time runs on, events of ``sc`` to keep), or
        (-1, len(sc)) when nothing continues (search onwards), or None when more bytes are needed."""
        m = len(sc)
        p = sc.stop
        if not self.fmt.ts_bytes:
            return -1, m
        # Time runs on from the last real event before the garbage; which of the events just before it are
        # themselves garbage (parsed by chance) is decided by trying to continue from each of them.
        lo = max(0, m - (self.confirm - 1))
        prevs = [(j + 1, int(sc.ts[j])) for j in range(m - 1, lo - 1, -1)]
        if lo == 0 and self._last_raw is not None:
            prevs.append((0, self._last_raw))
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

    # -- output -----------------------------------------------------------------------------------
    def _arrivals(self, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Latest and earliest possible arrival time (host us) of each event's first byte, and whether it
        came to a waiting reader (``fresh``: a precise time); None if arrival times are unknown."""
        if not self._segs or any(h is None for _, h, _, _ in self._segs):
            return None
        seg_end = np.array([e for e, _, _, _ in self._segs], np.int64)
        seg_t = np.array([h for _, h, _, _ in self._segs], np.float64)
        seg_fresh = np.array([f for _, _, f, _ in self._segs], bool)
        seg_lo = np.array([-np.inf if lo is None else lo for _, _, _, lo in self._segs], np.float64)
        idx = np.minimum(np.searchsorted(seg_end, starts, side="right"), seg_end.size - 1)
        # The bytes read after an event's first byte took at least this long to come over the link.
        hi = seg_t[idx] - (seg_end[idx] - starts) / self.byte_rate * 1e6
        # A fresh piece without a known empty look: its read time is taken as the arrival time (as before).
        lo = np.where(np.isneginf(seg_lo[idx]) & seg_fresh[idx], hi, np.minimum(seg_lo[idx], hi))
        return hi, seg_fresh[idx], lo

    def _times(self, sc: _Scan, host_t: int | None) -> np.ndarray:
        fmt = self.fmt
        m = len(sc)
        if fmt.delta:
            return self._last_t + np.cumsum(sc.ts)
        if not fmt.ts_bytes:
            # E0 carries no time: stamp with the host's arrival time, never going backwards.
            return np.full(m, max(self._last_t, 0 if host_t is None else int(host_t)), np.int64)
        raw = sc.ts
        prev = np.empty(m, np.int64)
        prev[0] = raw[0] if self._last_raw is None else self._last_raw
        prev[1:] = raw[:-1]
        step = (raw - prev) % fmt.wrap
        base = raw[0] if self._last_raw is None else self._last_t
        t = base + np.cumsum(step)
        arr = self._arrivals(sc.starts)
        if arr is not None:
            t = self._add_hidden_wraps(t, *arr)
        self._last_raw = int(raw[-1])
        return t

    def _ambiguous(self, i: int, taken: int, fewest: int, most: int) -> None:
        self.ambiguous_wraps += 1
        if len(self.ambiguous) < MAX_AMBIGUOUS_LISTED:
            self.ambiguous.append((self.events_decoded + i, taken, fewest, most))

    def _gap_wraps(self, t: np.ndarray, arr: np.ndarray, arr_lo: np.ndarray, off: float, i: int, nxt: int) -> int:
        """Wraps hidden by the arrival gap before event ``i`` (the events up to ``nxt`` share them)."""
        wrap = self.fmt.wrap
        # Every event up to the next gap bounds the wraps: after a stall of the sender (events sent late in
        # a burst) the burst's last events are timely again and veto a wrap.
        most = int(float((arr[i:nxt] - off + ARRIVAL_SLACK_US - t[i:nxt]).min()) // wrap)
        # ... and from below: each arrived after the reader's last look at an empty buffer.
        early = float((arr_lo[i:nxt] - off - ARRIVAL_LATENCY_US - t[i:nxt]).max())
        fewest = max(0, math.ceil(early / wrap)) if math.isfinite(early) else 0
        if most <= 0 or fewest == most:
            return max(most, 0)
        # fewest < most: the reader was late by more than a wrap, the host cannot tell how many passed; take
        # the fewest. fewest > most: bytes reached the reader later than any board sends them (the OS held
        # them), so neither bound is sure; the hard one (an event cannot arrive before it happened) is kept.
        # Either way the gap is counted, not guessed silently.
        k = min(fewest, most)
        self._ambiguous(i, k, min(fewest, most), max(fewest, most))
        return k

    def _add_hidden_wraps(self, t: np.ndarray, arr: np.ndarray, fresh: np.ndarray, arr_lo: np.ndarray) -> np.ndarray:
        wrap = self.fmt.wrap
        prev_arr = np.empty_like(arr)
        prev_arr[0] = arr[0] if self._last_arrival is None else self._last_arrival
        prev_arr[1:] = arr[:-1]
        # A long quiet spell in arrival times may hide wraps, whether or not the reader was waiting when the bytes
        # came (a reader scheduled late sees a pause's first events as not fresh): the bound below takes the
        # tightest event up to the next gap, so a late read alone never adds a wrap.
        gaps = np.flatnonzero(arr - prev_arr >= wrap / 2)
        if self._offset is not None:
            starts = sorted({0, *gaps.tolist()})
            for i, nxt in itertools.pairwise([*starts, arr.size]):
                off = self._offset + OFFSET_LEAK * (arr[i] - self._offset_at)
                seen = (arr[:i] - t[:i])[fresh[:i]]
                if seen.size:
                    off = min(off, float(seen.min()))
                k = self._gap_wraps(t, arr, arr_lo, off, i, nxt) if i in gaps else 0
                if k > 0:
                    t[i:] += k * wrap
                    self.hidden_wraps += k
                # A pause inside a late read leaves no gap in arrival times: if the run's last event may still
                # be a wrap later than decoded (its read came that late), some wraps in the run are unknown.
                if (not self.ambiguous or self.ambiguous[-1][0] != self.events_decoded + i) and nxt - i > 1:
                    most = int((arr[nxt - 1] - off + ARRIVAL_SLACK_US - t[nxt - 1]) // wrap)
                    if most > 0:
                        self._ambiguous(i + 1, 0, 0, most)
        if fresh.any():
            off_now = float((arr - t)[fresh].min())
            if self._offset is None:
                self._offset = off_now
            else:
                self._offset = min(self._offset + OFFSET_LEAK * (arr[-1] - self._offset_at), off_now)
            self._offset_at = float(arr[-1])
        self._last_arrival = float(arr[-1])
        return t

    def _emit(self, sc: _Scan, host_t: int | None) -> np.ndarray:
        m = len(sc)
        out = np.empty(m, EVENT_DTYPE)
        if m == 0:
            return out
        t = self._times(sc, host_t)
        self._last_t = int(t[-1])
        self._trust = False
        b0 = self._view[sc.starts]
        b1 = self._view[sc.starts + 1]
        out["t"] = t
        out["x"] = b1 & 0x7F
        out["y"] = b0 & 0x7F
        pbit = b1 >> 7
        out["p"] = (pbit == 0) if self.settings.off_bit_set else (pbit != 0)
        self.events_decoded += m
        self.bytes_decoded += int(sc.ends[-1] - sc.starts[0]) if m else 0
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
            ``host_t`` is its arrival time and not just a bound; only fresh bytes reveal pauses.
        after_t : int, optional, keyword-only
            Host time (us) of the reader's last look that found no byte waiting (before ``data`` came): none
            of ``data`` arrived earlier. Without it, fresh bytes are taken to have arrived at ``host_t``
            and others at any time before; with it, a late reader's wraps are decided or counted as
            ambiguous (:attr:`ambiguous_wraps`) instead of guessed.
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
            self._segs.append([len(self._buf), host_t, bool(fresh), after_t])
        buf = self._view = np.frombuffer(bytes(self._buf), np.uint8)
        pos = 0
        parts = []
        hold = 0 if (final or release) else self.confirm - 1
        # At a pause (release) or the end (final) bad bytes are judged with the bytes there are.
        settle = 2 if final else (1 if release else 0)
        while pos < buf.size:
            if self._searching:
                q, undecided = self._first_agreeing(buf, pos, buf.size, None, settle)
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
                head = sc.head(self._undeferred(max(0, m - hold), sc, settle))
                parts.append(self._emit(head, host_t))
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
                parts.append(self._emit(head, host_t))
                pos = head.stop
                break
            q, keep = found
            head = sc.head(keep)
            parts.append(self._emit(head, host_t))
            if q < 0:
                pos = head.stop
                self._searching = True
                continue
            self.corrupt_bytes += q - head.stop
            self._trust = True
            pos = q
        self._drop(pos)
        parts = [p for p in parts if p.size]
        if not parts:
            return empty_events()
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _undeferred(self, k: int, sc: _Scan, settle: int) -> int:
        """How many of the first ``k`` events to emit now: not those from an arrival gap on while no fresh
        event has followed it yet (see ``MAX_GAP_WITNESSES``), unless settling."""
        if settle or k == 0 or not self.fmt.ts_bytes:
            return k
        got = self._arrivals(sc.starts)
        if got is None:
            return k
        arr, fresh, _ = got
        prev = np.empty_like(arr)
        prev[0] = arr[0] if self._last_arrival is None else self._last_arrival
        prev[1:] = arr[:-1]
        gaps = np.flatnonzero(arr - prev >= self.fmt.wrap / 2)
        if gaps.size:
            g = int(gaps[-1])
            # The witness must be emitted with the gap (the last events of a call may be held back).
            if g < k and not fresh[g + 1:k].any() and k - g < MAX_GAP_WITNESSES:
                return min(k, g)
        return k

    def _drop(self, pos: int) -> None:
        del self._buf[:pos]
        self._segs = [[e - pos, h, f, lo] for e, h, f, lo in self._segs if e > pos]

    def flush(self, *, host_t: int | None = None, final: bool = True) -> np.ndarray:
        """Release the events held for confirmation.

        ``final=True`` (end of stream) also counts the bytes of an incomplete last event as corrupt;
        ``final=False`` (a pause in the stream) keeps them for the next call.
        """
        return self.decode(b"", host_t=host_t, final=final, release=not final)
