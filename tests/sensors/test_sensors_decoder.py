"""The eDVS byte decoder: every format round-trips, timestamps unwrap, corrupt bytes are skipped and counted."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.model.events import make_events
from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.protocol import ProtocolSettings, encode_events

TS_BYTES = {"E0": 0, "E2": 2, "E3": 3, "E4": 4}


def spec_encode(t, x, y, p, fmt, *, sync=True, off_set=True, t_prev=0) -> bytes:
    """Encode from formats.md, independently of the library: [sync|y] [pol|x] [timestamp]."""
    out = bytearray()
    for ti, xi, yi, pi in zip(t, x, y, p, strict=True):
        pol = (pi == 0) if off_set else (pi == 1)
        out.append((0x80 if sync else 0) | int(yi))
        out.append((0x80 if pol else 0) | int(xi))
        if fmt == "E1":
            delta, groups = int(ti) - t_prev, []
            t_prev = int(ti)
            while True:
                groups.insert(0, delta & 0x7F)
                delta >>= 7
                if not delta:
                    break
            groups[-1] |= 0x80
            out += bytes(groups)
        else:
            n = TS_BYTES[fmt]
            out += (int(ti) % (1 << (8 * n))).to_bytes(n, "big") if n else b""
    return bytes(out)


def stream(rng, n, max_step=300):
    t = np.cumsum(rng.integers(0, max_step, n))
    return make_events(t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n))


def decode_all(dec, data, rng, max_piece=700):
    parts, i = [], 0
    while i < len(data):
        k = int(rng.integers(1, max_piece))
        parts.append(dec.decode(data[i:i + k]))
        i += k
    parts.append(dec.flush())
    return np.concatenate(parts)


@pytest.mark.parametrize("fmt", ["E0", "E1", "E2", "E3", "E4"])
@pytest.mark.parametrize(("sync", "off_set"), [(True, True), (False, False)])
def test_round_trip_every_format(fmt, sync, off_set, rng):
    ev = stream(rng, 3000)
    data = spec_encode(ev["t"], ev["x"], ev["y"], ev["p"], fmt, sync=sync, off_set=off_set)
    s = ProtocolSettings(event_format=fmt, sync_bit_set=sync, off_bit_set=off_set)
    assert encode_events(ev, s) == data  # the library's encoder (virtual eDVS) agrees with the spec
    out = decode_all(StreamDecoder(s), data, rng)
    assert out.size == ev.size
    for f in ("x", "y", "p"):
        np.testing.assert_array_equal(out[f], ev[f])
    if fmt != "E0":
        np.testing.assert_array_equal(out["t"], ev["t"])


def test_unwraps_16_bit_timestamps_across_many_wraps(rng):
    ev = stream(rng, 20_000, max_step=2000)  # ~20 s: about 300 wraps of 65.536 ms
    assert ev["t"][-1] > 100 * 65536
    data = spec_encode(ev["t"], ev["x"], ev["y"], ev["p"], "E2")
    out = decode_all(StreamDecoder(ProtocolSettings(event_format="E2")), data, rng)
    np.testing.assert_array_equal(out["t"], ev["t"])


def test_unwraps_24_bit_and_accepts_a_long_pause(rng):
    t = np.concatenate([np.arange(0, 5000, 100), np.arange(5000 + (1 << 24) - 70_000, (1 << 24) + 100_000, 100)])
    ev = make_events(t, np.full(t.size, 3), np.full(t.size, 4), np.ones(t.size))
    s = ProtocolSettings(event_format="E3")
    out = decode_all(StreamDecoder(s), encode_events(ev, s), rng)
    np.testing.assert_array_equal(out["t"], t)


def _with_garbage(ev, fmt, rng, bursts, garbage_fn):
    cuts = np.sort(rng.choice(np.arange(1, ev.size), bursts, replace=False))
    s = ProtocolSettings(event_format=fmt)
    pieces, prev, total, tp = [], 0, 0, 0
    for c in [*cuts.tolist(), ev.size]:
        pieces.append(encode_events(ev[prev:c], s, t_prev=tp))
        tp = int(ev["t"][c - 1])
        if c < ev.size:
            g = garbage_fn()
            pieces.append(g)
            total += len(g)
        prev = c
    return b"".join(pieces), total, s


@pytest.mark.parametrize("fmt", ["E1", "E2", "E3", "E4"])
def test_garbage_without_sync_bits_is_skipped_and_counted(fmt, rng):
    # Line noise that never looks like an event start: every event is still received, every byte counted.
    ev = stream(rng, 20_000)
    data, total, s = _with_garbage(ev, fmt, rng, 40, lambda: rng.integers(0, 128, int(rng.integers(1, 30)),
                                                                            dtype=np.uint8).tobytes())
    dec = StreamDecoder(s)
    out = decode_all(dec, data, rng)
    np.testing.assert_array_equal(out["t"], ev["t"])
    np.testing.assert_array_equal(out["x"], ev["x"])
    assert dec.corrupt_bytes == total


@pytest.mark.parametrize("fmt", ["E3", "E4"])
def test_random_garbage_is_skipped_and_counted(fmt):
    # Arbitrary bytes (half of them look like event starts): timestamps tell garbage from events.
    rng = np.random.default_rng(1)
    ev = stream(rng, 20_000)
    data, total, s = _with_garbage(ev, fmt, rng, 30, lambda: rng.integers(0, 256, int(rng.integers(1, 20)),
                                                                            dtype=np.uint8).tobytes())
    dec = StreamDecoder(s)
    out = decode_all(dec, data, rng)
    np.testing.assert_array_equal(out["t"], ev["t"])
    assert dec.corrupt_bytes == total


def test_incomplete_trailing_event_counts_as_corrupt_at_end():
    s = ProtocolSettings(event_format="E2")
    dec = StreamDecoder(s)
    ev = make_events([1, 2], [1, 2], [3, 4], [1, 0])
    out = np.concatenate([dec.decode(encode_events(ev, s) + b"\x81\x01"), dec.flush()])
    assert out.size == 2 and dec.corrupt_bytes == 2
