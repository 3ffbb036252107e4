"""A virtual clock for the E2 decoder: events with pauses, the bytes' arrival at the host, a reader's pieces.

The board's clock reads 0 at host time ``EPOCH``; event i's bytes leave the board at its device time and reach
the host's OS buffer ``LINK_US`` later, no faster than the link carries them (``BYTE_US`` per byte). A waiting
reader looks at the buffer every ``READ_US`` or so (at random) and takes what came since its last look: pieces
cut at random byte positions, as UART reads are. Each piece's host time is the look's time plus a jitter drawn
within +-``jitter_us`` (the host's arrival times are known only to that), so the decoder sees arrival times
within ``jitter_us + READ_US`` of the truth. After ``RELEASE_US`` without a byte the reader releases the
events held for confirmation, as :class:`cvstereo.sensors.edvs.EDVS` does.

The expectation is independent of the decoder: the events that were encoded. Every event carries a unique
(x, y), so a dropped or an invented event is found by its address, not by its position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cvstereo.model.events import make_events
from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.protocol import ProtocolSettings, encode_events

WRAP = 1 << 16
EPOCH = 7_000_000  # host us at which the board's clock read 0
LINK_US = 500  # board to the host's OS buffer
BYTE_US = 2.5  # 4 Mbaud, 8N1: 400,000 bytes/s
READ_US = 3_000  # a waiting reader looks at least this often
RELEASE_US = 20_000  # the reader releases held events after this long without a byte
E2 = ProtocolSettings(event_format="E2")

#: Pauses around one wrap and its multiples, and the ones seen to fail (us).
WRAP_PAUSES = sorted({1_000, 16_384, 16_385, 30_000, 60_000, 65_000, 65_535, 65_536, 65_537, 70_000, 131_000,
                      196_000, *(k * WRAP + d for k in (1, 2, 3, 7, 15, 30) for d in (-1, 0, 1))})


def unique_addresses(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of ``n`` events, all different (at most 128 * 128), in a random order."""
    if n > 128 * 128:
        raise ValueError(f"at most {128 * 128} events have unique addresses, asked for {n}")
    cell = rng.permutation(128 * 128)[:n]
    return cell % 128, cell // 128


def paced_events(pauses, *, burst=5, step_us=(0, 3000), rng=None, start_us=1000) -> np.ndarray:
    """Bursts of ``burst`` events (an int, or one per burst) at random steps in ``step_us``, with ``pauses``
    (us) between the bursts; device times from ``start_us``."""
    rng = rng or np.random.default_rng(0)
    sizes = [burst] * (len(pauses) + 1) if np.isscalar(burst) else list(burst)
    t, now = [], start_us
    for k, size in enumerate(sizes):
        if k:
            now += int(pauses[k - 1])
        steps = rng.integers(step_us[0], step_us[1] + 1, size)
        steps[0] = 0
        burst_t = now + np.cumsum(steps)
        t.extend(burst_t.tolist())
        now = int(burst_t[-1])
    t = np.array(t, np.int64)
    x, y = unique_addresses(t.size, rng)
    return make_events(t, x, y, rng.integers(0, 2, t.size))


@dataclass
class Piece:
    """One read: bytes, host time, whether the reader was waiting (fresh), its last empty look; or a release."""

    data: bytes
    host_t: int
    fresh: bool = True
    after_t: int | None = None
    release: bool = False


def byte_arrivals(due_t: np.ndarray) -> np.ndarray:
    """True host time (us) at which each byte reaches the OS buffer, given the device time at which the board
    has it to send (``due_t``, one per byte): not before then (plus the link), and no faster than the link."""
    due = EPOCH + LINK_US + np.asarray(due_t, np.float64)
    k = np.arange(due.size) * BYTE_US
    return np.maximum.accumulate(due - k) + k + BYTE_US


def event_bytes_due(event_t: np.ndarray, size: int) -> np.ndarray:
    """The device time at which each byte of fixed-size events is due: its event's."""
    return np.repeat(np.asarray(event_t, np.float64), size)


def reader_pieces(data: bytes, arrive: np.ndarray, *, jitter_us: float, rng: np.random.Generator,
                  monotonic: bool = True, splits: int = 2) -> list[Piece]:
    """The pieces a waiting reader passes to the decoder (see the module docstring)."""
    pieces: list[Piece] = []
    done, look, last_t, last_byte = 0, float(arrive[0]) - READ_US, None, None
    n = len(data)
    while done < n:
        # Skip ahead over a pause (the looks there find nothing), then look at random intervals.
        look = max(look + rng.uniform(50, READ_US), float(arrive[done]))
        if last_byte is not None and look - last_byte >= RELEASE_US:
            rel = last_byte + RELEASE_US + rng.uniform(0, READ_US)
            if rel < look:
                pieces.append(Piece(b"", _jittered(rel, jitter_us, rng, last_t, monotonic), release=True))
                last_t = pieces[-1].host_t
        end = int(np.searchsorted(arrive, look, side="right"))
        host_t = _jittered(look, jitter_us, rng, last_t, monotonic)
        cuts = np.sort(rng.integers(done, end + 1, rng.integers(0, splits + 1))) if end - done > 1 else []
        for lo, hi in zip([done, *cuts], [*cuts, end], strict=True):
            if hi > lo:
                pieces.append(Piece(data[lo:hi], host_t))
        done, last_t, last_byte = end, host_t, float(arrive[end - 1])
    return pieces


def pieces_at_looks(data: bytes, arrive: np.ndarray, looks: np.ndarray) -> list[Piece]:
    """The pieces of a reader that looks at the buffer at host times ``looks`` (no jitter): a look that finds
    nothing sets ``after_t``; one that finds bytes reads them all, fresh if the look before found nothing."""
    pieces: list[Piece] = []
    done, empty_at, was_empty, last_read = 0, None, False, None
    for look in np.sort(np.asarray(looks, np.int64)):
        n = int(np.searchsorted(arrive, look, side="right"))
        if n == done:
            empty_at, was_empty = int(look), True
            if last_read is not None and look - last_read >= RELEASE_US:
                pieces.append(Piece(b"", int(look), release=True))
                last_read = None
            continue
        pieces.append(Piece(data[done:n], int(look), was_empty, empty_at))
        done, was_empty, last_read = n, False, int(look)
    return pieces


def _jittered(t: float, jitter_us: float, rng: np.random.Generator, last: int | None, monotonic: bool) -> int:
    v = round(t + rng.uniform(-jitter_us, jitter_us))
    return max(v, last) if monotonic and last is not None else v


def decode_pieces(pieces: list[Piece], *, epoch: bool = True, decoder: StreamDecoder | None = None):
    """Feed ``pieces`` to a decoder (told the epoch, as EDVS does after ``!ET0``, if ``epoch``); returns
    (events, decoder)."""
    dec = decoder or StreamDecoder(E2)
    if epoch:
        dec.reset_time(EPOCH)
    out = []
    for p in pieces:
        if p.release:
            out.append(dec.decode(b"", host_t=p.host_t, release=True))
        else:
            out.append(dec.decode(p.data, host_t=p.host_t, fresh=p.fresh, after_t=p.after_t))
    out.append(dec.flush())
    return np.concatenate(out), dec


def read_paced(ev: np.ndarray, *, jitter_us: float = 20_000 - READ_US, seed: int = 0, epoch: bool = True,
               monotonic: bool = True, splits: int = 2):
    """Encode ``ev`` as E2, deliver it through the virtual clock and decode it; returns (events, decoder)."""
    rng = np.random.default_rng(seed)
    data = encode_events(ev, E2)
    arrive = byte_arrivals(event_bytes_due(ev["t"], E2.format.size))
    pieces = reader_pieces(data, arrive, jitter_us=jitter_us, rng=rng, monotonic=monotonic, splits=splits)
    return decode_pieces(pieces, epoch=epoch)


def check_exact(got: np.ndarray, want: np.ndarray, dec: StreamDecoder, *, absolute: bool = True) -> None:
    """Every encoded event decoded once, in order, with its x, y, p; nothing invented; no clean byte counted
    as corrupt; times exact (``absolute``: on the board's clock, else relative to the first event) before the
    first event the decoder listed as ambiguous, and off by whole wraps at most after it (its documented
    recovery).

    Failure messages start with the kind (``tests/_hostile.py``): DATALOSS for dropped events, SILENT for
    invented ones, wrong times or clean bytes counted corrupt.
    """
    key_want = want["x"].astype(np.int64) * 128 + want["y"]
    key_got = got["x"].astype(np.int64) * 128 + got["y"]
    index = np.full(128 * 128, -1, np.int64)
    index[key_want] = np.arange(want.size)
    found = index[key_got]
    invented = int(np.count_nonzero(found < 0))
    dropped = want.size - np.unique(found[found >= 0]).size
    assert dropped == 0, (f"DATALOSS: {dropped} of {want.size} events dropped (first at index "
                          f"{int(np.setdiff1d(np.arange(want.size), found)[0])}), {invented} invented, "
                          f"{dec.corrupt_bytes} clean bytes counted corrupt")
    assert invented == 0 and got.size == want.size, f"SILENT: {invented} events invented ({got.size} for {want.size})"
    assert (found == np.arange(want.size)).all(), "SILENT: events out of order"
    assert (got["p"] == want["p"]).all(), f"SILENT: {int((got['p'] != want['p']).sum())} polarities wrong"
    assert dec.corrupt_bytes == 0, f"SILENT: {dec.corrupt_bytes} bytes of a clean stream counted corrupt"
    back = np.flatnonzero(np.diff(got["t"]) < 0)
    assert not back.size, f"SILENT: time runs back after event {int(back[0])}"
    err = got["t"].astype(np.int64) - want["t"]
    if not absolute:
        err = err - err[0]
    first = min((a[0] for a in dec.ambiguous), default=want.size)
    off = np.flatnonzero(err[:first])
    assert not off.size, (f"SILENT: event {int(off[0])} is {int(err[off[0]]):+d} us off ({off.size} events off before "
                          f"the first listed as ambiguous, {first})")
    off = np.flatnonzero(err % WRAP)
    assert not off.size, f"SILENT: event {int(off[0])} is {int(err[off[0]]):+d} us off, not by whole wraps"
