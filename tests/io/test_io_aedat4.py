"""AEDAT4 through dv-processing: files written by dv-processing's own writers read back exactly."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.errors import CorruptFileError
from cvstereo.io.stream import MONO
from tests._io_helpers import assert_same_events, random_events

dv = pytest.importorskip("dv_processing")

from cvstereo.io import _aedat4_worker  # noqa: E402
from cvstereo.io.aedat4 import aedat4_cameras, open_aedat4  # noqa: E402

RES = (640, 480)


def _store(events):
    store = dv.EventStore()
    for t, x, y, p in events.tolist():
        store.push_back(int(t), int(x), int(y), bool(p))  # dv: True = ON
    return store


def _write(writer, events, batches=3):
    # Several packets, so that the reader has several batches to stream.
    for part in np.array_split(events, batches):
        writer.writeEvents(_store(part))


@pytest.fixture
def streams(rng):
    t0 = 1_700_000_000_000_000  # DV stamps microseconds since the UNIX epoch
    return random_events(rng, 700, RES, t0=t0), random_events(rng, 500, RES, t0=t0 + 7)


def test_stereo_file_reads_back_exactly(tmp_path, streams, monkeypatch):
    left, right = streams
    path = tmp_path / "stereo.aedat4"
    cfg = [dv.io.MonoCameraWriter.EventOnlyConfig(name, RES) for name in ("DVXplorer_L", "DVXplorer_R")]
    writer = dv.io.StereoCameraWriter(str(path), *cfg)
    _write(writer.left, left)
    _write(writer.right, right)
    del writer  # closes the file
    assert aedat4_cameras(path) == [("DVXplorer_L", RES), ("DVXplorer_R", RES)]
    stream = open_aedat4(path)
    assert stream.is_stereo and stream.resolution == RES
    assert stream.meta["cameras"] == {"left": "DVXplorer_L", "right": "DVXplorer_R"}
    monkeypatch.setattr(_aedat4_worker, "FRAME_EVENTS", 300)  # the forked worker sees it: frames of 300 at most
    sizes = [ev.size for ev, _ in stream.chunks("left")]
    assert sum(sizes) == left.size and len(sizes) > 1 and max(sizes) <= 300  # streamed, not read whole
    rec = stream.read()
    assert_same_events(rec.left, left)
    assert_same_events(rec.right, right)
    # The other camera named left: the cameras swap.
    swapped = open_aedat4(path, left_camera="DVXplorer_R").read()
    assert_same_events(swapped.left, right)
    assert open_aedat4(path, left_camera="DVXplorer_R").meta["left_camera_from"] == "left_camera option"
    with pytest.raises(ValueError, match=r"no camera 'nope'.*DVXplorer_L, DVXplorer_R"):
        open_aedat4(path, left_camera="nope")


def test_one_file_per_camera(tmp_path, streams):
    files = []
    for name, events in zip(("L", "R"), streams, strict=True):
        files.append(tmp_path / f"{name}.aedat4")
        writer = dv.io.MonoCameraWriter(str(files[-1]), dv.io.MonoCameraWriter.EventOnlyConfig(name, RES))
        _write(writer, events, batches=2)
        del writer
    rec = open_aedat4(*files).read()
    assert_same_events(rec.left, streams[0])
    assert_same_events(rec.right, streams[1])
    mono = open_aedat4(files[0])
    assert mono.cameras == (MONO,)
    events, truth = mono.read_camera(MONO)
    assert_same_events(events, streams[0]) and truth is None
    with pytest.raises(ValueError, match="one camera only"):
        mono.read()


def test_polarity_is_on_one(tmp_path):
    path = tmp_path / "p.aedat4"
    writer = dv.io.MonoCameraWriter(str(path), dv.io.MonoCameraWriter.EventOnlyConfig("cam", (346, 260)))
    store = dv.EventStore()
    store.push_back(5, 345, 259, True)
    store.push_back(6, 0, 0, False)
    writer.writeEvents(store)
    del writer
    events, _ = open_aedat4(path).read_camera(MONO)
    assert events.tolist() == [(5, 345, 259, 1), (6, 0, 0, 0)]


def test_not_aedat4(tmp_path):
    bad = tmp_path / "x.aedat4"
    bad.write_bytes(b"#!AER-DAT2.0\r\n")
    with pytest.raises(CorruptFileError, match=r"not an AEDAT 4\.0 file"):
        open_aedat4(bad)
    with pytest.raises(FileNotFoundError, match="no such file"):
        open_aedat4(tmp_path / "missing.aedat4")


def test_read_recording_detects_aedat4(tmp_path, streams):
    from cvstereo.io import detect_format, read_recording

    path = tmp_path / "stereo.aedat4"
    cfg = [dv.io.MonoCameraWriter.EventOnlyConfig(name, RES) for name in ("a", "b")]
    writer = dv.io.StereoCameraWriter(str(path), *cfg)
    _write(writer.left, streams[0], batches=1)
    _write(writer.right, streams[1], batches=1)
    del writer
    assert detect_format(path) == "aedat4"
    path = path.rename(tmp_path / "stereo.aedat")  # the content decides, not only the extension
    assert detect_format(path) == "aedat4"
    with pytest.raises(ValueError, match=r"must end in '\.aedat4'"):
        read_recording(path)
    rec = read_recording(path.rename(tmp_path / "again.aedat4"))
    assert_same_events(rec.right, streams[1])
