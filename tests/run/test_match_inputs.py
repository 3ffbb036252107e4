"""match() takes what users have: a Recording, a path, a recording opened for streaming, or the two cameras'
events as arrays of any common shape; and it refuses the easy mistakes with its positional arguments instead
of running something else."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.errors import EventFormatError
from cvstereo.io import open_recording, write_recording
from cvstereo.model.arrays import events_from
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.run import match


@pytest.fixture(scope="module")
def pair():
    """A random texture of ON and OFF events, the right camera's 6 px to the left: disparity 6."""
    rng = np.random.default_rng(0)
    n = 6000
    t = np.sort(rng.integers(0, 80_000, n))
    x = rng.integers(40, 90, n)
    y = rng.integers(20, 60, n)
    p = rng.integers(0, 2, n)
    return make_events(t, x, y, p), make_events(t, x - 6, y, p)


def test_arrays_give_the_same_matches_as_the_recording(pair, tmp_path):
    left, right = pair
    ref = match(Recording(left, right), method="frame-area", threshold=0.5)
    assert len(ref) > 100 and np.median(ref.matches["disparity"]) == 6
    got = match(left, right, method="frame-area", threshold=0.5)
    np.testing.assert_array_equal(got.matches, ref.matches)
    write_recording(tmp_path / "r.npz", Recording(left, right))
    np.testing.assert_array_equal(match(tmp_path / "r.npz", method="frame-area", threshold=0.5).matches, ref.matches)


def test_an_opened_recording_streams_with_its_format_options(pair, tmp_path):
    # A merged text file whose left camera is retina 1 needs a format option: open_recording takes it, and
    # match() streams the opened recording, recording the file it read as its input.
    left, right = pair
    ref = match(Recording(left, right), method="frame-area", threshold=0.5)
    write_recording(tmp_path / "r.txt", Recording(left, right), format="edvs-merged", left_retina=1)
    stream = open_recording(tmp_path / "r.txt", format="edvs-merged", left_retina=1)
    got = match(stream, method="frame-area", threshold=0.5)
    np.testing.assert_array_equal(got.matches, ref.matches)
    assert got.meta["input"] == [str(tmp_path / "r.txt")] and got.meta["fingerprint"] == ref.meta["fingerprint"]
    # The exchanged cameras of a stream are those of the recording exchanged.
    swapped = match(stream.swapped(), method="frame-area", threshold=0.5)
    np.testing.assert_array_equal(swapped.matches, match(Recording(left, right).swapped(), method="frame-area",
                                                          threshold=0.5).matches)


def test_tonic_order_dv_names_and_plain_columns(pair):
    left, right = pair
    ref = match(left, right, method="frame-area", threshold=0.5).matches
    tonic = [("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "?")]
    dv = [("timestamp", "i8"), ("x", "i2"), ("y", "i2"), ("polarity", "u1")]

    def convert(ev, dtype):
        out = np.empty(ev.size, dtype)
        for name, _ in dtype:
            out[name] = ev[{"timestamp": "t", "polarity": "p"}.get(name, name)]
        return out

    for dtype in (tonic, dv):
        got = match(convert(left, dtype), convert(right, dtype), method="frame-area", threshold=0.5)
        np.testing.assert_array_equal(got.matches, ref)

    def mvsec(ev):  # x, y, t in seconds, p in -1/+1, as floats
        return np.column_stack([ev["x"], ev["y"], ev["t"] / 1e6, 2.0 * ev["p"] - 1]).astype(np.float64)

    got = match(mvsec(left), mvsec(right), method="frame-area", threshold=0.5, columns="xytp", time_unit="s")
    np.testing.assert_array_equal(got.matches, ref)


class _Store:
    """A stand-in for dv-processing's EventStore: its numpy() gives timestamp, x, y, polarity."""

    def __init__(self, ev):
        self._arr = np.empty(ev.size, [("timestamp", "i8"), ("x", "i2"), ("y", "i2"), ("polarity", "u1")])
        for name, field in (("timestamp", "t"), ("x", "x"), ("y", "y"), ("polarity", "p")):
            self._arr[name] = ev[field]

    def numpy(self):
        return self._arr


def test_event_store_like_objects(pair):
    left, right = pair
    ref = match(left, right, method="frame-area", threshold=0.5).matches
    np.testing.assert_array_equal(match(_Store(left), _Store(right), method="frame-area", threshold=0.5).matches, ref)


def test_real_event_store_when_dv_processing_is_installed(pair):
    dv = pytest.importorskip("dv_processing")
    left, right = pair
    stores = []
    for ev in (left, right):
        store = dv.EventStore()
        for e in ev:
            store.push_back(int(e["t"]), int(e["x"]), int(e["y"]), bool(e["p"]))
        stores.append(store)
    np.testing.assert_array_equal(match(*stores, method="frame-area", threshold=0.5).matches,
                                  match(left, right, method="frame-area", threshold=0.5).matches)


@pytest.mark.parametrize(("args", "kwargs", "message"), [
    ("rec-method", {}, "the method is keyword-only"),
    ("rec-right", {}, "a Recording holds both cameras"),
    ("left-only", {}, "give the right camera's events too"),
    ("path-events", {}, "both cameras as files, or both as event arrays"),
    ("path", {"columns": "txyp"}, "for events given as arrays"),
    ("stream-right", {}, "an opened recording has its cameras and format already"),
    ("stream", {"resolution": (128, 128)}, "an opened recording has its cameras and format already"),
])
def test_argument_mistakes_raise_type_error(pair, tmp_path, args, kwargs, message):
    left, right = pair
    rec = Recording(left, right)
    write_recording(tmp_path / "r.npz", rec)
    positional = {"rec-method": (rec, "event-area"), "rec-right": (rec, tmp_path / "r.npz"), "left-only": (left,),
                  "path-events": (tmp_path / "r.npz", right), "path": (tmp_path / "r.npz",),
                  "stream-right": (open_recording(tmp_path / "r.npz"), tmp_path / "r.npz"),
                  "stream": (open_recording(tmp_path / "r.npz"),)}[args]
    with pytest.raises(TypeError, match=message):
        match(*positional, method="frame-area", threshold=0.5, **kwargs)


@pytest.mark.parametrize(("data", "kwargs", "message"), [
    (np.zeros((3, 4)), {}, "needs its column order"),
    (np.zeros((3, 4)), {"columns": "txyx"}, "order of the letters"),
    (np.zeros((3, 5)), {"columns": "txyp"}, r"\(N, 4\) array"),
    (np.array([[0, 1.5, 2, 1]]), {"columns": "txyp", "time_unit": "us"}, "field 'x' at index 0 is 1.5"),
    (np.array([[np.nan, 1, 2, 1]]), {"columns": "txyp", "time_unit": "us"}, "field 't' at index 0 is nan, not a"),
])
def test_events_from_refuses_what_it_cannot_read_safely(data, kwargs, message):
    with pytest.raises(EventFormatError, match=message):
        events_from(data, **kwargs)


def test_arrays_at_another_sensor_size(pair):
    left, right = pair
    big_l, big_r = left.copy(), right.copy()
    big_l["x"] += 200
    big_r["x"] += 200
    with pytest.raises(EventFormatError, match="outside"):
        match(big_l, big_r, method="frame-area", threshold=0.5)
    got = match(big_l, big_r, method="frame-area", threshold=0.5, resolution=(346, 260))
    assert got.meta["resolution"] == [346, 260] and np.median(got.matches["disparity"]) == 6


def test_the_matches_meta_holds_the_recordings_origin():
    """meta["origin_us"]: the time shown as 0 (docs/formats.md), the earliest event of both cameras on a clock of
    1.7e12 us, or the origin a clip of a recording keeps in its meta."""
    import numpy as np

    from cvstereo.model.events import make_events
    from cvstereo.model.recording import Recording
    from cvstereo.run import match

    rng = np.random.default_rng(5)
    t = 1_700_000_000_000 + np.sort(rng.integers(0, 400_000, 3000))
    x, y, p = rng.integers(20, 128, t.size), rng.integers(0, 128, t.size), rng.integers(0, 2, t.size)
    left = make_events(t, x, y, p)
    right = make_events(t[5:] - 3, x[5:] - 10, y[5:], p[5:])  # the right camera starts later
    rec = Recording(left, right, resolution=(128, 128))
    expected = min(int(left["t"][0]), int(right["t"][0]))
    assert match(rec, rig_check=False).meta["origin_us"] == expected
    clip = Recording(left[100:], right[100:], resolution=(128, 128), meta={"origin_us": expected})
    assert match(clip, rig_check=False).meta["origin_us"] == expected
