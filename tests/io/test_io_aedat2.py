"""jAER AEDAT 2.0: the DVS128 address layout byte for byte, stereo and mono files, streaming, errors."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io import detect_format, open_recording, read_recording, write_recording
from cvstereo.io.aedat2 import (
    decode_addresses,
    encode_addresses,
    iter_aedat2_chunks,
    open_aedat2,
    read_aedat2_events,
    read_aedat2_header,
    write_aedat2_events,
)
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from tests._io_helpers import assert_same_events, random_events, random_recording, recordings

_TMP = settings(deadline=None, max_examples=15, suppress_health_check=[HealthCheck.function_scoped_fixture])
_HEADER = b"#!AER-DAT2.0\r\n# Data format is int32 address, int32 timestamp (8 bytes total)\r\n"


def _file(tmp_path, records, *, name="rec.aedat", tail=b""):
    """An AEDAT 2.0 file from ``(address, timestamp)`` pairs, written by hand (not by our writer)."""
    path = tmp_path / name
    path.write_bytes(_HEADER + b"".join(struct.pack(">II", a, t) for a, t in records) + tail)
    return path


def test_worked_example_of_formats_md(tmp_path):
    # 0x00008F03: bit 15 right eye, raw y 0x0F = 15, raw x 1, raw polarity 1 -> x 126, y 112, OFF.
    eye, x, y, p = decode_addresses(np.array([0x00008F03], np.uint32))
    assert (int(eye[0]), int(x[0]), int(y[0]), int(p[0])) == (1, 126, 112, 0)
    ev = make_events([0], [126], [112], [0])
    assert int(encode_addresses(ev, 1)[0]) == 0x00008F03
    path = _file(tmp_path, [(0x00008F03, 1234)])
    assert_same_events(read_aedat2_events(path, eye="right"), make_events([1234], [126], [112], [0]))
    assert read_aedat2_events(path, eye="left").size == 0
    # And our writer produces exactly these bytes for that event.
    out = tmp_path / "w.aedat"
    write_aedat2_events(out, make_events([1234], [126], [112], [0]), eye="right")
    data = out.read_bytes()
    assert data.startswith(b"#!AER-DAT2.0\r\n")
    assert data[read_aedat2_header(out).data_offset:] == bytes.fromhex("00008F03000004D2")


def test_corner_addresses():
    # raw x 0 / raw y 0 is our x 127 / y 127; raw polarity 0 is ON.
    eye, x, y, p = decode_addresses(np.array([0x00000000, 0x00007FFE], np.uint32))
    assert x.tolist() == [127, 0] and y.tolist() == [127, 0] and p.tolist() == [1, 1] and eye.tolist() == [0, 0]


@_TMP
@given(rec=recordings())
def test_stereo_round_trip(tmp_path, rec):
    path = tmp_path / "rec.aedat"
    write_recording(path, rec)
    assert detect_format(path) == "aedat2"
    stream = open_recording(path)
    if rec.right.size:  # without right-eye events the file is indistinguishable from a mono one
        back = stream.read()
        assert_same_events(back.left, rec.left)
        assert_same_events(back.right, rec.right)
    else:
        assert stream.cameras == ("mono",)
        assert_same_events(stream.read_camera("mono")[0], rec.left)


def test_two_mono_files_make_a_stereo_recording(tmp_path, rng):
    rec = random_recording(rng, 300, 200)
    left, right = tmp_path / "l.aedat", tmp_path / "r.aedat"
    write_aedat2_events(left, rec.left)
    write_aedat2_events(right, rec.right)  # a mono file: right-eye bit clear
    back = read_recording(left, right)
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)
    alone = open_recording(left)
    assert alone.cameras == ("mono",)
    with pytest.raises(ValueError, match="holds one camera only"):
        alone.read()
    stereo = tmp_path / "s.aedat"
    write_recording(stereo, rec)
    with pytest.raises(ValueError, match="holds both eyes"):
        open_aedat2(stereo, right)


def test_special_events_are_skipped_and_counted(tmp_path):
    path = _file(tmp_path, [(0x80000000, 5), (0x00000000, 6), (0x80000001, 6), (0x00008000, 7), (0x80000000, 8)])
    stream = open_recording(path)
    assert stream.meta["special_events"] == 3
    rec = stream.read()
    assert rec.left["t"].tolist() == [6] and rec.right["t"].tolist() == [7]


def test_chunked_read_equals_whole_read(tmp_path, rng):
    rec = random_recording(rng, 500, 400)
    path = tmp_path / "rec.aedat"
    write_recording(path, rec)
    chunks = list(iter_aedat2_chunks(path, eye="left", chunk_records=16))
    assert max(c.size for c in chunks) <= 16
    assert_same_events(np.concatenate(chunks), rec.left)
    streamed, whole = list(open_aedat2(path, chunk_records=50).packets(2000)), list(rec.packets(2000))
    assert [p.until for p in streamed] == [p.until for p in whole]
    for a, b in zip(streamed, whole, strict=True):
        assert_same_events(a.right, b.right)


def test_truncated_record_names_the_byte_offset(tmp_path):
    path = _file(tmp_path, [(0, 1), (0, 2)], tail=b"\x00\x00\x01")
    offset = len(_HEADER) + 16
    with pytest.raises(CorruptFileError, match=rf"rec.aedat: truncated: the last record, at byte offset {offset}, "
                                               r"has 3 of 8 bytes"):
        open_recording(path)


def test_backwards_timestamps_name_the_byte_offset(tmp_path):
    path = _file(tmp_path, [(0, 100), (0, 200), (0x8000, 150), (0, 50)])  # the right eye's 150 is fine
    offset = len(_HEADER) + 3 * 8
    with pytest.raises(EventFormatError) as info:
        list(iter_aedat2_chunks(path, eye="left", chunk_records=2))
    msg = str(info.value)
    for part in ("[left eye]", "field 't'", "index 2 is 50", f"record 3 at byte offset {offset}", "wrap"):
        assert part in msg


def test_non_dvs128_addresses_and_other_versions_are_rejected(tmp_path):
    path = _file(tmp_path, [(0, 1), (0x00400000, 2)])
    with pytest.raises(CorruptFileError, match=rf"0x00400000 at byte offset {len(_HEADER) + 8}.*not a DVS128"):
        open_recording(path)
    path = tmp_path / "v3.aedat"
    path.write_bytes(b"#!AER-DAT3.1\r\n#!END-HEADER\r\n")
    with pytest.raises(CorruptFileError, match=r"AER-DAT3\.1 is not supported"):
        open_recording(path)
    path = tmp_path / "text.aedat"
    path.write_text("0 1 2 1\n")
    with pytest.raises(CorruptFileError, match=r"not an AEDAT 2\.0 file"):
        open_recording(path)


def test_aedat_in_a_dat_file_is_detected(tmp_path):
    assert detect_format(_file(tmp_path, [(0, 1)], name="old_jaer.dat")) == "aedat2"


def test_writer_rejects_what_aedat_cannot_hold(tmp_path):
    small = Recording(make_events([0], [0], [0], [1]), make_events([0], [0], [0], [1]), resolution=(64, 64))
    with pytest.raises(ValueError, match="128x128"):
        write_recording(tmp_path / "x.aedat", small)
    late = make_events([2**32], [0], [0], [1])
    with pytest.raises(ValueError, match=r"0..2\*\*32-1"):
        write_aedat2_events(tmp_path / "x.aedat", late)
    assert list(tmp_path.iterdir()) == []


def test_header_is_kept(tmp_path, rng):
    path = tmp_path / "rec.aedat"
    write_aedat2_events(path, random_events(rng, 3))
    header = read_aedat2_header(path)
    assert header.lines[0] == "#!AER-DAT2.0" and header.records == 3
    assert header.data_offset == path.stat().st_size - 24
