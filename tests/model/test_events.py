"""The event model: conversion, validation errors (field and index named), slicing, packet iteration."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.errors import EventFormatError
from cvstereo.model.events import EVENT_DTYPE, as_events, iter_stereo_packets, make_events, time_slice, validate_events
from tests._io_helpers import random_events


def test_as_events_converts_tonic_order_bool_polarity_and_minus_one():
    tonic = np.zeros(3, dtype=[("x", "<u2"), ("y", "<u2"), ("t", "<i8"), ("p", "?")])
    tonic["x"], tonic["y"], tonic["t"], tonic["p"] = [1, 2, 3], [4, 5, 6], [7, 8, 9], [True, False, True]
    ev = as_events(tonic)
    assert ev.dtype == EVENT_DTYPE
    assert ev["p"].tolist() == [1, 0, 1] and ev["x"].tolist() == [1, 2, 3] and ev["t"].tolist() == [7, 8, 9]
    assert as_events(make_events([0, 1], [0, 0], [0, 0], [-1, 1]))["p"].tolist() == [0, 1]


@pytest.mark.parametrize(("data", "words"), [
    (np.zeros((3, 4), np.int64), ["structured array", "make_events"]),
    (np.zeros(2, dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2")]), ["missing field", "p"]),
    (np.zeros(2, dtype=[("t", "<f8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")]), ["'t'", "float64", "integer"]),
])
def test_wrong_dtype_is_named(data, words):
    with pytest.raises(EventFormatError) as info:
        as_events(data, source="cam.npz")
    assert "cam.npz" in str(info.value)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize(("field", "value", "words"), [
    ("p", 2, ["field 'p'", "index 12", "polarity"]),
    ("x", -1, ["field 'x'", "index 12", ">= 0"]),
    ("y", 128, ["field 'y'", "index 12", "128x128"]),
    ("x", 40_000, ["field 'x'", "index 12", "is 40000", "outside the 128x128 sensor"]),
])
def test_bad_value_names_field_and_index_with_offset(field, value, words):
    raw = np.zeros(5, dtype=[("t", "<i8"), ("x", "<i4"), ("y", "<i4"), ("p", "<i4")])
    raw[field][2] = value
    with pytest.raises(EventFormatError) as info:
        as_events(raw, source="left camera", index_offset=10)
    for word in ["left camera", *words]:
        assert word in str(info.value)


def test_backwards_time_names_index_and_both_times():
    ev = make_events([0, 5, 3, 9], [0] * 4, [0] * 4, [1] * 4)
    with pytest.raises(EventFormatError, match=r"field 't' at index 2 is 3, earlier than index 1 \(5\)"):
        validate_events(ev)


def test_t_floor_checks_the_chunk_boundary():
    ev = make_events([4, 6], [0, 0], [0, 0], [1, 1])
    validate_events(ev, t_floor=4)
    with pytest.raises(EventFormatError, match=r"index 100 is 4, earlier than the preceding event \(5\)"):
        validate_events(ev, t_floor=5, index_offset=100)


def test_validate_events_rejects_other_dtypes():
    with pytest.raises(EventFormatError, match="as_events"):
        validate_events(np.zeros(2, dtype=[("t", "<i4"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")]))


def test_time_slice_is_half_open():
    ev = make_events([0, 5, 5, 10, 15], [0] * 5, [0] * 5, [1] * 5)
    assert ev[time_slice(ev, 5, 15)]["t"].tolist() == [5, 5, 10]
    assert ev[time_slice(ev, None, 5)]["t"].tolist() == [0]
    assert ev[time_slice(ev, 16)].size == 0


def _chunks(events, size):
    return [events[i:i + size] for i in range(0, len(events), size)] or [events]


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2**32 - 1), packet_us=st.integers(1, 400), sizes=st.tuples(st.integers(1, 50),
                                                                                      st.integers(1, 50)))
def test_packets_are_time_slices_whatever_the_chunking(seed, packet_us, sizes):
    rng = np.random.default_rng(seed)
    left, right = random_events(rng, 150, t0=int(rng.integers(0, 5000))), random_events(rng, 120)
    truth = rng.uniform(0, 20, left.size).astype(np.float32)
    cut = [(c, truth[i:i + c.size]) for i, c in zip(range(0, left.size, sizes[0]), _chunks(left, sizes[0]),
                                                    strict=True)]
    packets = list(iter_stereo_packets(cut, _chunks(right, sizes[1]), packet_us))
    whole = list(iter_stereo_packets((left, truth), right, packet_us))
    assert [p.until for p in packets] == [p.until for p in whole]
    for p in packets:
        assert p.until % packet_us == 0
        for got, full in ((p.left, left), (p.right, right)):
            np.testing.assert_array_equal(got, full[time_slice(full, p.until - packet_us, p.until)])
        assert p.left.size or p.right.size  # windows without events are skipped
        np.testing.assert_array_equal(p.left_disparity, truth[time_slice(left, p.until - packet_us, p.until)])
    assert sum(p.left.size for p in packets) == left.size and sum(p.right.size for p in packets) == right.size


def test_packets_skip_empty_windows_and_reject_bad_length():
    left = make_events([5, 1_000_005], [0, 0], [0, 0], [1, 1])
    packets = list(iter_stereo_packets(left, make_events([], [], [], []), 1000))
    assert [p.until for p in packets] == [1000, 1_001_000]
    with pytest.raises(ValueError, match="packet_us must be positive"):
        list(iter_stereo_packets(left, left, 0))


@pytest.mark.parametrize("packet_us", [1, 7, 1000, 40_000])
def test_recording_packets_equal_iter_stereo_packets(packet_us):
    # The in-memory fast path must cut exactly the packets of the streaming iterator, truth included.
    from cvstereo.model.recording import Recording

    rng = np.random.default_rng(packet_us)
    cams = []
    for n in (300, 200):
        t = np.sort(rng.integers(0, 200_000, n))
        cams.append(make_events(t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)))
    truths = [rng.normal(10, 1, c.size).astype(np.float32) for c in cams]
    rec = Recording(cams[0], cams[1], truths[0], truths[1])
    fast = list(rec.packets(packet_us))
    slow = list(iter_stereo_packets((cams[0], truths[0]), (cams[1], truths[1]), packet_us))
    assert len(fast) == len(slow)
    for a, b in zip(fast, slow, strict=True):
        assert a.until == b.until
        for x, y in zip(a[:2] + a[3:], b[:2] + b[3:], strict=True):
            np.testing.assert_array_equal(x, y)
