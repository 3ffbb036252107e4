"""Compiled byte scanners of the eDVS decoder: cut events at one alignment, and find where events agree.

Every function looks at each byte a bounded number of times (at most ``limit`` events from a position), so
decoding stays linear in the number of bytes however much garbage arrives. One set of kernels serves every
format; the format is given by ``size`` (shortest event), ``ts_bytes`` (absolute timestamp bytes), ``delta``
(E1's variable-length delta) and ``wrap`` (period of the absolute timestamp).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np


@dataclass
class Scan:
    """Events cut from a buffer: byte offsets, raw timestamps and where the cut stopped."""

    starts: np.ndarray
    ends: np.ndarray
    ts: np.ndarray  # raw timestamp (absolute formats) or delta (E1); zeros for E0
    stop: int
    failed: bool

    def __len__(self) -> int:
        return self.starts.size

    def head(self, k: int) -> Scan:
        stop = int(self.starts[k]) if k < len(self) else self.stop
        return Scan(self.starts[:k], self.ends[:k], self.ts[:k], stop, False)


#: Return codes of :func:`event_at`.
OK, BAD, SHORT = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def event_at(buf, i, size, ts_bytes, delta, max_groups, sync):  # pragma: no cover - compiled
    """(code, end, ts) of the event starting at byte ``i``: ts is the raw timestamp or E1 delta."""
    n = buf.shape[0]
    if i >= n:
        return SHORT, i, 0
    if (buf[i] & 0x80) != sync:
        return BAD, i, 0
    if delta:
        j = i + 2
        d = 0
        while j < n and j < i + 2 + max_groups:
            b = buf[j]
            d = (d << 7) | (b & 0x7F)
            j += 1
            if b & 0x80:
                return OK, j, d
        if j >= n and j < i + 2 + max_groups:
            return SHORT, i, 0
        return BAD, i, 0
    if i + size > n:
        return SHORT, i, 0
    ts = 0
    for k in range(ts_bytes):
        ts = (ts << 8) | buf[i + 2 + k]
    return OK, i + size, ts


@numba.njit(cache=True, nogil=True)
def cut(buf, pos, limit, size, ts_bytes, delta, max_groups, wrap, sync, max_gap, prev_raw, has_prev,
        trust):  # pragma: no cover - compiled
    """Cut up to ``limit`` events from ``pos`` until a bad sync bit, bad delta or implausible time step.

    The first event's step is not checked when ``trust`` (a confirmed resynchronisation) or when there is
    no previous timestamp. Returns (starts, ends, ts, stop, failed).
    """
    n = buf.shape[0]
    cap = min(limit, (n - pos) // size + 1) if n > pos else 0
    starts = np.empty(cap, np.int64)
    ends = np.empty(cap, np.int64)
    tss = np.empty(cap, np.int64)
    k = 0
    i = pos
    failed = False
    timed = delta or ts_bytes > 0
    prev = prev_raw
    hp = has_prev
    while k < cap:
        code, end, ts = event_at(buf, i, size, ts_bytes, delta, max_groups, sync)
        if code == SHORT:
            break
        if code == BAD:
            failed = True
            break
        if timed and not (k == 0 and (trust or (not delta and not hp))):
            step = ts if delta else (ts - prev) % wrap
            if step > max_gap:
                failed = True
                break
        starts[k] = i
        ends[k] = end
        tss[k] = ts
        prev = ts
        hp = True
        k += 1
        i = end
    return starts[:k], ends[:k], tss[:k], i, failed


@numba.njit(cache=True, nogil=True)
def first_agreeing(buf, lo, hi, need, size, ts_bytes, delta, max_groups, wrap, sync, max_gap, prev_raw,
                   has_prev, lenient, settle):  # pragma: no cover - compiled
    """The first byte in [lo, hi) from which ``need`` events agree (continuing ``prev_raw`` if ``has_prev``).

    Returns (q, undecided): q >= 0 found; else undecided >= 0 is the first position that more bytes could
    still confirm (every position before it is definitely not an event start), or -1 when none is left.
    ``settle`` 1 (the stream paused) or 2 (it ended): decide with the bytes there are; then with
    ``lenient`` fewer events that run without a fault to the last byte also count, and with 2 a position
    whose events are cut off by the end is given up.
    """
    for q in range(lo, hi):
        if (buf[q] & 0x80) != sync:
            continue
        starts, _ends, _ts, _stop, failed = cut(buf, q, need, size, ts_bytes, delta, max_groups, wrap, sync,
                                                max_gap, prev_raw, has_prev, not has_prev)
        k = starts.shape[0]
        if k >= need:
            return q, -1
        if failed:
            continue
        if lenient and settle and k > 0:
            return q, -1
        if settle == 2:
            continue
        return -1, q
    return -1, -1
