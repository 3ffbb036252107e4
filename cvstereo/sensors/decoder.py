"""A streaming decoder of eDVS128 event bytes: one mechanism, parameterised by the event format.

Bytes arrive in arbitrary pieces; :meth:`StreamDecoder.decode` keeps the bytes of incomplete events
between calls and returns time-ordered events of :data:`~cvstereo.events.EVENT_DTYPE`.

How corrupt bytes are handled (the protocol has only one sync bit per event, so a single check would
let garbage through about half of the time):

1. Events are cut at the current alignment (vectorised for the fixed-size formats) until the first
   event whose sync bit is wrong or whose timestamp is implausible (more than ``max_gap_us`` after the
   previous one, modulo the wrap).
2. From there the decoder looks for the first byte position at which ``confirm`` consecutive events
   parse with correct sync bits and plausible timestamps between them; the bytes skipped are counted in
   :attr:`StreamDecoder.corrupt_bytes`. A genuine long pause passes this test at once, costing nothing.
   The search first tries positions where time runs on plausibly from the last event before the bad
   bytes (or, if that one may be garbage that parsed by chance, from the one before it, ...), which
   also decides which of those last events were real.

The last ``confirm - 1`` events of a call are held back until more bytes confirm them (or
:meth:`StreamDecoder.flush` releases them), so garbage cannot slip out before it is recognised.

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

from dataclasses import dataclass

import numba
import numpy as np

from cvstereo.events import EVENT_DTYPE, empty_events
from cvstereo.sensors.protocol import MAX_DELTA_BYTES, ProtocolSettings

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


@dataclass
class _Scan:
    """Events cut from a buffer: byte offsets, fields and where the cut stopped."""

    starts: np.ndarray  # byte offset of each event
    y: np.ndarray
    x: np.ndarray
    pbit: np.ndarray
    ts: np.ndarray  # raw timestamp (absolute formats) or delta (E1); zeros for E0
    stop: int  # byte offset after the last event returned
    failed: bool  # stopped at bad bytes (True) or at the end of the data (False)

    def __len__(self) -> int:
        return self.starts.size

    def head(self, k: int) -> _Scan:
        stop = int(self.starts[k]) if k < len(self) else self.stop
        return _Scan(self.starts[:k], self.y[:k], self.x[:k], self.pbit[:k], self.ts[:k], stop, False)


@numba.njit(cache=True, nogil=True)
def _cut_delta(buf, pos, sync, max_groups):  # pragma: no cover - compiled
    # E1: [sync|y] [p|x] then 1..max_groups bytes of 7-bit delta, bit 7 set on the last one only.
    n = buf.shape[0]
    cap = (n - pos) // 3 + 1
    starts = np.empty(cap, np.int64)
    ys = np.empty(cap, np.uint8)
    xs = np.empty(cap, np.uint8)
    ps = np.empty(cap, np.uint8)
    ds = np.empty(cap, np.int64)
    k = 0
    i = pos
    failed = False
    while i + 2 < n:
        b0 = buf[i]
        if (b0 & 0x80) != sync:
            failed = True
            break
        j = i + 2
        delta = 0
        done = False
        while j < n and j < i + 2 + max_groups:
            b = buf[j]
            delta = (delta << 7) | (b & 0x7F)
            j += 1
            if b & 0x80:
                done = True
                break
        if not done:
            if j >= n and j < i + 2 + max_groups:
                break  # incomplete: wait for more bytes
            failed = True
            break
        starts[k] = i
        ys[k] = b0 & 0x7F
        xs[k] = buf[i + 1] & 0x7F
        ps[k] = buf[i + 1] >> 7
        ds[k] = delta
        k += 1
        i = j
    return starts[:k], ys[:k], xs[:k], ps[:k], ds[:k], i, failed


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

    Attributes
    ----------
    corrupt_bytes : int
        Bytes skipped as not part of any event.
    events_decoded : int
        Events returned so far.
    """

    def __init__(self, settings: ProtocolSettings | None = None, *, confirm: int = DEFAULT_CONFIRM,
                 resync_events: int = DEFAULT_RESYNC_EVENTS, max_gap_us: int = DEFAULT_MAX_GAP_US):
        self.settings = settings or ProtocolSettings()
        if confirm < 2:
            raise ValueError(f"confirm must be at least 2 events, got {confirm}.")
        self.fmt = self.settings.format
        self.confirm = int(confirm)
        self.resync_events = max(int(resync_events), self.confirm)
        self.max_gap_us = int(max_gap_us)
        self._sync = 0x80 if self.settings.sync_bit_set else 0
        self._buf = bytearray()
        self.corrupt_bytes = 0
        self.events_decoded = 0
        self.reset_time()

    def reset_time(self) -> None:
        """Forget the timestamp history (after ``!ET0``): the next event starts a new unwrap."""
        self._last_raw: int | None = None
        self._wraps = 0
        self._last_t = 0
        self._trust = True

    @property
    def pending_bytes(self) -> int:
        """Bytes held for the next call (incomplete or unconfirmed events)."""
        return len(self._buf)

    # -- cutting ----------------------------------------------------------------------------------
    def _cut(self, buf: np.ndarray, pos: int, prev_raw: int | None, trust: bool) -> _Scan:
        """Cut events from ``pos`` at this alignment; stop at a bad sync bit or implausible timestamp."""
        fmt = self.fmt
        if fmt.delta:
            starts, y, x, p, ts, stop, failed = _cut_delta(buf, pos, self._sync, MAX_DELTA_BYTES)
            sc = _Scan(starts, y, x, p, ts, int(stop), bool(failed))
        else:
            s = fmt.size
            n = (buf.size - pos) // s
            rows = buf[pos:pos + n * s].reshape(n, s)
            bad = np.flatnonzero((rows[:, 0] & 0x80) != self._sync)
            failed = bad.size > 0
            m = int(bad[0]) if failed else n
            rows = rows[:m]
            ts = np.zeros(m, np.int64)
            for k in range(fmt.ts_bytes):
                ts = (ts << 8) | rows[:, 2 + k]
            sc = _Scan(pos + s * np.arange(m, dtype=np.int64), rows[:, 0] & 0x7F, rows[:, 1] & 0x7F,
                       rows[:, 1] >> 7, ts, pos + m * s, failed)
        if not fmt.has_time or len(sc) == 0:
            return sc
        # Plausibility of each timestamp step (why: one sync bit alone lets half of all garbage through).
        if fmt.delta:
            step = sc.ts
        else:
            prev = np.empty(len(sc), np.int64)
            prev[0] = sc.ts[0] if prev_raw is None else prev_raw
            prev[1:] = sc.ts[:-1]
            step = (sc.ts - prev) % fmt.wrap
        ok = step <= self.max_gap_us
        if trust or (prev_raw is None and not fmt.delta):
            ok[0] = True
        bad = np.flatnonzero(~ok)
        if bad.size:
            cut = sc.head(int(bad[0]))
            cut.failed = True
            return cut
        return sc

    def _consistent_at(self, buf: np.ndarray, q: int, final: bool, prev_raw: int | None = None) -> bool | None:
        """Whether ``resync_events`` events agree from byte ``q`` (and continue ``prev_raw`` if given);
        None when more bytes are needed to tell."""
        end = min(buf.size, q + self.resync_events * self.fmt.max_size)
        sc = self._cut(buf[:end], q, prev_raw, prev_raw is None)
        if len(sc) >= self.resync_events:
            return True
        if sc.failed:
            return False
        if end < buf.size or final:
            # Enough bytes were there but fewer events: or the stream ends here (final).
            return final and len(sc) > 0 and sc.stop == buf.size
        return None

    def _continuation(self, buf: np.ndarray, p: int, prev_raw: int, final: bool) -> int | None:
        """First byte within RESYNC_WINDOW of ``p`` where agreeing events continue time from ``prev_raw``.

        Returns -1 when there is none, None when more bytes are needed to tell.
        """
        fmt = self.fmt
        short = p + RESYNC_WINDOW > buf.size and not final
        stop = min(buf.size - fmt.size + 1, p + RESYNC_WINDOW)
        if stop <= p:
            return None if short else -1
        # Prefilter all candidate positions at once: sync bit and the first timestamp step.
        qs = np.arange(p, stop)
        ts = np.zeros(qs.size, np.int64)
        for k in range(fmt.ts_bytes):
            ts = (ts << 8) | buf[qs + 2 + k]
        ok = ((buf[qs] & 0x80) == self._sync) & ((ts - prev_raw) % fmt.wrap <= self.max_gap_us)
        for q in qs[ok].tolist():
            verdict = self._consistent_at(buf, q, final, prev_raw)
            if verdict is None:
                return None
            if verdict:
                return q
        return None if short else -1

    def _resync(self, buf: np.ndarray, sc: _Scan, final: bool) -> tuple[int, int] | None:
        """Where good events resume after the bad bytes at ``sc.stop``, and how many events of ``sc`` to keep.

        Returns None when more bytes are needed to tell.
        """
        m = len(sc)
        p = sc.stop
        lo = max(0, m - (self.confirm - 1))
        if self.fmt.ts_bytes:
            # The usual case: garbage inside a continuous stream. Time then runs on from the last real
            # event before the garbage; which of the events just before it are themselves garbage (parsed
            # by chance) is decided by trying to continue from each of them.
            prevs = [(j + 1, int(sc.ts[j])) for j in range(m - 1, lo - 1, -1)]
            if lo == 0 and self._last_raw is not None:
                prevs.append((0, self._last_raw))
            best = None
            for keep, prev in prevs:
                q = self._continuation(buf, p, prev, final)
                if q is None:
                    return None
                # The earliest resumption wins: from a garbage "event", time only seems to run on once
                # the real stream has caught up with its random timestamp, many events later.
                if q >= 0 and (best is None or q < best[0]):
                    best = (q, keep)
            if best is not None:
                return best
        # A long pause (or no time to go by): the first position where enough events agree.
        for q in range(p, buf.size):
            verdict = self._consistent_at(buf, q, final)
            if verdict is None:
                return None
            if verdict:
                return q, m
        return (buf.size, m) if final else None

    # -- output -----------------------------------------------------------------------------------
    def _emit(self, sc: _Scan, host_t: int | None) -> np.ndarray:
        m = len(sc)
        out = np.empty(m, EVENT_DTYPE)
        if m == 0:
            return out
        fmt = self.fmt
        if fmt.delta:
            t = self._last_t + np.cumsum(sc.ts)
        elif fmt.ts_bytes:
            raw = sc.ts
            prev = np.empty(m, np.int64)
            prev[0] = raw[0] if self._last_raw is None else self._last_raw
            prev[1:] = raw[:-1]
            wraps = self._wraps + np.cumsum(raw < prev)
            t = raw + fmt.wrap * wraps
            self._wraps = int(wraps[-1])
            self._last_raw = int(raw[-1])
        else:
            # E0 carries no time: stamp with the host's arrival time, never going backwards.
            t = np.full(m, max(self._last_t, 0 if host_t is None else int(host_t)), np.int64)
        self._last_t = int(t[-1])
        self._trust = False
        out["t"] = t
        out["x"] = sc.x
        out["y"] = sc.y
        out["p"] = (sc.pbit == 0) if self.settings.off_bit_set else (sc.pbit != 0)
        self.events_decoded += m
        return out

    def decode(self, data: bytes, *, host_t: int | None = None, final: bool = False,
               release: bool = False) -> np.ndarray:
        """Decode the next bytes of the stream.

        Parameters
        ----------
        data : bytes
            The bytes, in any pieces.
        host_t : int, optional, keyword-only
            Host time (us) stamped on events of format E0, which carries no time.
        final : bool, keyword-only
            No more bytes will come: release held events and count trailing bytes as corrupt.
        release : bool, keyword-only
            Release the events held for confirmation (the stream paused), keep incomplete bytes.

        Returns
        -------
        (N,) ndarray of EVENT_DTYPE
            Time-ordered events.
        """
        self._buf += data
        buf = np.frombuffer(bytes(self._buf), np.uint8)
        pos = 0
        parts = []
        hold = 0 if (final or release) else self.confirm - 1
        while pos < buf.size:
            sc = self._cut(buf, pos, self._last_raw, self._trust)
            m = len(sc)
            if not sc.failed:
                keep = max(0, m - hold)
                parts.append(self._emit(sc.head(keep), host_t))
                pos = sc.head(keep).stop
                if final and pos < buf.size:
                    self.corrupt_bytes += buf.size - pos  # an incomplete event at the very end
                    pos = buf.size
                break
            found = self._resync(buf, sc, final)
            if found is None:
                # Not enough bytes after the bad spot to find the next good event: wait.
                keep = max(0, m - hold)
                parts.append(self._emit(sc.head(keep), host_t))
                pos = sc.head(keep).stop
                break
            q, keep = found
            head = sc.head(keep)
            parts.append(self._emit(head, host_t))
            self.corrupt_bytes += q - head.stop
            self._trust = True
            pos = q
        del self._buf[:pos]
        parts = [p for p in parts if p.size]
        if not parts:
            return empty_events()
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def flush(self, *, host_t: int | None = None, final: bool = True) -> np.ndarray:
        """Release the events held for confirmation.

        ``final=True`` (end of stream) also counts the bytes of an incomplete last event as corrupt;
        ``final=False`` (a pause in the stream) keeps them for the next call.
        """
        return self.decode(b"", host_t=host_t, final=final, release=not final)
