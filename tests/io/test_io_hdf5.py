"""DSEC and MVSEC HDF5 layouts: fixture files written with h5py read back exactly, streamed by time slices."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io.stream import MONO
from tests._io_helpers import assert_same_events, random_events

pytest.importorskip("h5py")
pytest.importorskip("hdf5plugin")

from cvstereo.io.hdf5 import hdf5_layout, open_dsec, open_mvsec, read_time_slice
from tests._hdf5_fixtures import write_dsec_events, write_mvsec_events

T_OFFSET = 49_599_300_523  # DSEC-like: microseconds of the day


@pytest.fixture
def dsec_pair(tmp_path, rng):
    left = random_events(rng, 3000, (640, 480), t0=T_OFFSET, max_step=120)  # ~180 ms
    right = random_events(rng, 2500, (640, 480), t0=T_OFFSET + 33, max_step=140)
    files = tmp_path / "left.h5", tmp_path / "right.h5"
    for path, ev in zip(files, (left, right), strict=True):
        write_dsec_events(path, ev, t_offset=T_OFFSET)
    return files, left, right


def test_dsec_reads_back_exactly_in_time_slices(dsec_pair):
    (lpath, rpath), left, right = dsec_pair
    assert hdf5_layout(lpath) == "dsec"
    stream = open_dsec(lpath, rpath, chunk_ms=20)
    assert stream.resolution == (640, 480) and stream.is_stereo
    chunks = [ev for ev, _ in stream.chunks("left")]
    # Each chunk is one 20 ms slice of relative time, cut by ms_to_idx.
    for ev in chunks:
        k = (ev["t"] - T_OFFSET) // 20_000
        assert k.min() == k.max()
    assert len(chunks) == (left["t"][-1] - T_OFFSET) // 20_000 + 1
    rec = stream.read()
    assert_same_events(rec.left, left)
    assert_same_events(rec.right, right)
    mono = open_dsec(rpath)
    assert mono.cameras == (MONO,)
    assert_same_events(mono.read_camera(MONO)[0], right)


def test_dsec_time_slice_reads_one_window(dsec_pair):
    (lpath, _), left, _ = dsec_pair
    for t0, t1 in ((T_OFFSET + 12_345, T_OFFSET + 47_001), (0, T_OFFSET + 5), (T_OFFSET + 10**9, T_OFFSET + 10**10)):
        sel = (left["t"] >= t0) & (left["t"] < t1)
        assert_same_events(read_time_slice(lpath, t0, t1), left[sel])


def test_mvsec_reads_back_exactly(tmp_path, rng):
    t0 = 1_504_645_177_000_000  # ROS time in us
    left = random_events(rng, 2000, (346, 260), t0=t0)
    right = random_events(rng, 1800, (346, 260), t0=t0 + 4)
    path = tmp_path / "indoor_flying1_data.hdf5"
    write_mvsec_events(path, left, right)
    assert hdf5_layout(path) == "mvsec"
    stream = open_mvsec(path)
    assert stream.resolution == (346, 260)
    rec = stream.read()
    assert_same_events(rec.left, left)
    assert_same_events(rec.right, right)
    t_a, t_b = int(left["t"][300]), int(left["t"][900])
    sel = (left["t"] >= t_a) & (left["t"] < t_b)
    assert_same_events(read_time_slice(path, t_a, t_b, camera="left"), left[sel])


def test_bad_files_name_what_is_wrong(tmp_path):
    import h5py

    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("images", data=np.zeros(3))
    with pytest.raises(CorruptFileError, match="neither the DSEC layout"):
        hdf5_layout(path)
    with pytest.raises(CorruptFileError, match="not a DSEC event file"):
        open_dsec(path)
    with h5py.File(path, "w") as f:
        f.create_dataset("davis/left/events", data=np.array([[1.0, 2.0, 0.5, 1.0], [1.5, 2.0, 0.6, 1.0]]))
    with pytest.raises(EventFormatError, match=r"/davis/left/events column x at index 1 is 1.5, not a whole"):
        open_mvsec(path).read_camera(MONO)
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(CorruptFileError, match="not a readable HDF5 file"):
        hdf5_layout(tmp_path / "junk.h5")


def test_read_recording_detects_both_layouts(dsec_pair, tmp_path, rng):
    from cvstereo.io import detect_format, read_recording

    (lpath, rpath), left, right = dsec_pair
    assert detect_format(lpath) == "dsec"
    rec = read_recording(lpath, rpath)
    assert_same_events(rec.left, left) and rec.resolution == (640, 480)
    path = tmp_path / "m.hdf5"
    small = [ev[(ev["x"] < 346) & (ev["y"] < 260)][:10] for ev in (left, right)]
    write_mvsec_events(path, *small)
    assert detect_format(path) == "mvsec"
    assert read_recording(path).resolution == (346, 260)
    with pytest.raises(ValueError, match="a second file do"):
        read_recording(path, rpath)


def test_dsec_time_range(dsec_pair, tmp_path):
    from cvstereo.io.hdf5 import dsec_time_range
    from cvstereo.model.events import empty_events

    (lpath, _), left, _ = dsec_pair
    assert dsec_time_range(lpath) == (int(left["t"][0]), int(left["t"][-1]))
    write_dsec_events(tmp_path / "empty.h5", empty_events(), t_offset=5)
    assert dsec_time_range(tmp_path / "empty.h5") is None
