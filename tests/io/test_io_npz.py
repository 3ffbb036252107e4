"""Stereo recording .npz: round trips, chunked (streaming) reads equal whole reads, corrupt files."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io import open_recording, read_recording, write_recording
from cvstereo.io.stream import open_npz
from cvstereo.model.events import make_events
from tests._io_helpers import assert_same_events, random_recording, recordings

_TMP = settings(deadline=None, max_examples=15, suppress_health_check=[HealthCheck.function_scoped_fixture])


@_TMP
@given(rec=recordings(truth=True, resolution=(64, 48)))
def test_round_trip_keeps_events_truth_resolution_and_meta(tmp_path, rec):
    path = tmp_path / "rec.npz"
    rec = type(rec)(rec.left, rec.right, rec.left_disparity, rec.right_disparity, rec.resolution,
                    {"scene": "random", "rig": {"baseline_m": 0.1}})
    write_recording(path, rec)
    back = read_recording(path)
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)
    np.testing.assert_array_equal(back.left_disparity, rec.left_disparity)  # NaN where unknown, kept
    np.testing.assert_array_equal(back.right_disparity, rec.right_disparity)
    assert back.resolution == (64, 48) and back.meta == rec.meta


@pytest.mark.parametrize("truth", [False, True])
def test_chunked_read_equals_whole_read(tmp_path, rng, truth):
    rec = random_recording(rng, 1000, 777, truth=truth)
    path = tmp_path / "rec.npz"
    write_recording(path, rec)
    stream = open_npz(path, chunk_rows=64)
    assert stream.has_truth is truth and stream.resolution == rec.resolution and stream.is_stereo
    chunks = list(stream.chunks("left"))
    assert len(chunks) == 16 and max(c[0].size for c in chunks) == 64
    back = stream.read()
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)
    if truth:
        np.testing.assert_array_equal(back.left_disparity, rec.left_disparity)
    whole, streamed = list(rec.packets(5000)), list(open_recording(path).packets(5000))
    assert [p.until for p in streamed] == [p.until for p in whole]
    for a, b in zip(streamed, whole, strict=True):
        assert_same_events(a.left, b.left)
        assert_same_events(a.right, b.right)


def test_streaming_names_a_time_error_across_a_chunk_boundary(tmp_path):
    left = make_events(np.r_[np.arange(100), 50, 200], np.zeros(102), np.zeros(102), np.ones(102))
    path = tmp_path / "bad.npz"
    np.savez_compressed(path, left=left, right=left[:1])
    with pytest.raises(EventFormatError, match=r"bad.npz \[left\]: field 't' at index 100 is 50"):
        open_npz(path, chunk_rows=25).read()


def test_truth_of_the_wrong_length_is_reported(tmp_path, rng):
    rec = random_recording(rng, 50, 50)
    path = tmp_path / "bad.npz"
    np.savez_compressed(path, left=rec.left, right=rec.right, left_disparity=np.zeros(49, np.float32),
                        right_disparity=np.zeros(50, np.float32))
    with pytest.raises(CorruptFileError, match="left_disparity"):
        open_npz(path, chunk_rows=20).read()


@pytest.mark.parametrize("content", [b"not a zip archive at all", b"PK\x03\x04truncated"])
def test_corrupt_npz_names_the_file(tmp_path, content):
    path = tmp_path / "broken.npz"
    path.write_bytes(content)
    for read in (read_recording, lambda p: open_recording(p).read()):
        with pytest.raises(CorruptFileError, match=r"broken\.npz: not a readable \.npz"):
            read(path)


def test_npz_without_a_camera_is_rejected(tmp_path, rng):
    path = tmp_path / "half.npz"
    np.savez_compressed(path, left=random_recording(rng, 5, 5).left)
    with pytest.raises(CorruptFileError, match="right"):
        open_recording(path)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nothere\.npz: no such file"):
        open_recording(tmp_path / "nothere.npz")


def test_npz_takes_no_text_options(tmp_path, rng):
    path = tmp_path / "rec.npz"
    write_recording(path, random_recording(rng, 5, 5))
    with pytest.raises(ValueError, match="left_retina do"):
        read_recording(path, left_retina=1)


def test_written_files_get_the_usual_permissions(tmp_path):
    # The atomic writer's temporary file is private; the finished file must not be (umask decides, as open()).
    import os
    import stat

    from cvstereo.io import write_recording_npz
    from cvstereo.model.events import make_events
    from cvstereo.model.recording import Recording

    ev = make_events([1], [2], [3], [1])
    out = tmp_path / "r.npz"
    write_recording_npz(out, Recording(ev, ev))
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask
