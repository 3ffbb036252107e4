"""The one table of formats in cvstereo.io: every reader, writer and option check goes through it."""

from __future__ import annotations

import numpy as np
import pytest

import cvstereo.io as cio
from cvstereo.io.stream import open_npz
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording


def test_formats_are_the_table():
    assert cio.FORMATS == tuple(cio.FORMAT_TABLE) == ("npz", "edvs-text", "edvs-merged", "aedat2", "aedat4", "dsec",
                                                      "mvsec", "m3ed", "evt2", "evt21", "evt3", "prophesee-dat",
                                                      "metavision-csv", "rosbag")


def test_a_new_format_is_one_table_entry(tmp_path, monkeypatch):
    """A format added to the table is detected by its extension, opened, read and written with its options."""
    written = []

    def write(path, recording, *, left_retina):
        written.append(left_retina)
        cio.write_recording_npz(path, recording)

    def open_fake(path, *, resolution):
        assert resolution == (128, 128)
        return open_npz(path)

    monkeypatch.setitem(cio.FORMAT_TABLE, "fake", cio.Format(open_fake, write, ("resolution",), (".fake",),
                                                             ("left_retina",)))
    ev = make_events([0, 5], [1, 2], [3, 4], [1, 0])
    path = tmp_path / "r.fake"
    cio.write_recording(path, Recording(ev, ev), left_retina=1)
    assert written == [1] and cio.detect_format(path) == "fake"
    rec = cio.read_recording(path, resolution=(128, 128))
    np.testing.assert_array_equal(rec.left, ev)
    packets = list(cio.open_recording(path, resolution=(128, 128)).packets(1000))
    assert [p.left.size for p in packets] == [2]
    with pytest.raises(ValueError, match=r"one_based does not apply to format 'fake' \(it takes: resolution\)"):
        cio.open_recording(path, one_based=True, resolution=(128, 128))


def test_read_only_format_cannot_be_written(tmp_path, monkeypatch):
    monkeypatch.setitem(cio.FORMAT_TABLE, "ro", cio.Format(open_npz, None, (), (".ro",)))
    ev = make_events([0], [1], [1], [1])
    with pytest.raises(ValueError, match="cannot write format 'ro'"):
        cio.write_recording(tmp_path / "x.npz", Recording(ev, ev), format="ro")
    with pytest.raises(ValueError, match=r"cannot tell the output format from '\.ro'"):
        cio.write_recording(tmp_path / "x.ro", Recording(ev, ev))
