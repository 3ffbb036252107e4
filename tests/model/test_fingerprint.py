"""The fingerprint's checksum (cvstereo.model.fingerprint) by hand; its independence of packet cuts and what it tells
apart are in test_hostile2_fingerprint."""

from __future__ import annotations

import numpy as np

from cvstereo.model.events import make_events
from cvstereo.model.fingerprint import difference, fingerprint_of, stream_sum
from cvstereo.model.recording import Recording


def test_the_checksum_of_one_event_by_hand():
    """t = 1, x = 2, y = 3, p = 1: bytes 01 00*7 | 02 00 03 00 01, as words 1 and 2 + 3*256**2 + 256**4."""
    ev = make_events([1], [2], [3], [1])
    fp = fingerprint_of(Recording(ev, ev[:0]))
    assert fp["left"] == {"events": 1, "t_first": 1, "t_last": 1, "checksum": "0000000100030003"}
    assert fp["right"] == {"events": 0, "t_first": None, "t_last": None, "checksum": "0000000000000000"}


def test_the_checksum_wraps_and_does_not_care_where_a_stream_is_cut():
    raw = np.frombuffer(bytes(range(256)) * 3 + b"\xff" * 13, np.uint8)
    whole = stream_sum(raw, 0)
    expected = sum(int(b) << (8 * (k % 8)) for k, b in enumerate(raw.tolist())) % 2**64
    assert whole == expected
    for cut in (1, 7, 8, 13, 500):
        assert (stream_sum(raw[:cut], 0) + stream_sum(raw[cut:], cut)) % 2**64 == whole


def test_a_clock_shift_is_told_from_other_events():
    ev = make_events([0, 10, 20], [1, 2, 3], [4, 5, 6], [1, 0, 1])
    stored = fingerprint_of(Recording(ev, ev))
    early = ev.copy()
    early["t"] -= 2_500_000
    assert difference(stored, Recording(ev, ev)) is None
    assert difference(stored, Recording(early, early)).endswith("differ by 2.5 s (this recording's times are 2.5 s "
                                                                  "earlier)")
    one_camera = difference(stored, Recording(early, ev))  # two clocks apart: not one shift
    assert one_camera == "as many events, but other ones (the left camera's times differ)"
    moved = ev.copy()
    moved["x"][1] += 1
    moved_right = difference(stored, Recording(ev, moved))
    assert moved_right == "as many events, but other ones (the right camera's events differ)"
    assert difference(stored, Recording(ev[:2], ev)).startswith("it was computed on 3 + 3 events")


def test_a_streamed_fingerprint_is_the_one_of_the_recording_read_whole(tmp_path):
    """Chunk by chunk (a file read in several chunks per camera) it equals the whole recording's, and a
    stored fingerprint of other events is not taken for it."""
    from cvstereo.io import open_recording, read_recording, write_recording
    from cvstereo.model.fingerprint import fingerprint_of_stream, is_fingerprint_of_stream

    rng = np.random.default_rng(3)
    n = 300_001  # more than one chunk per camera, and not a whole number of 8-byte words
    t = np.sort(rng.integers(0, 2_000_000, n))
    left = make_events(t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n))
    right = make_events(t[: n // 2], rng.integers(0, 128, n // 2), rng.integers(0, 128, n // 2), 1)
    path = tmp_path / "r.aedat"
    write_recording(path, Recording(left, right))
    stream = open_recording(path)
    assert sum(1 for _ in stream.open_chunks("left")) > 1
    whole = fingerprint_of(read_recording(path))
    assert fingerprint_of_stream(stream) == whole
    assert is_fingerprint_of_stream(whole, stream)
    other = fingerprint_of(Recording(left[1:], right))
    assert not is_fingerprint_of_stream(other, stream)
    assert not is_fingerprint_of_stream({**whole, "checksum": "md5"}, stream)
