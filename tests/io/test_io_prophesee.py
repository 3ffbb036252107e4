"""Prophesee / Metavision formats: EVT 2.0, 2.1, 3.0 ``.raw``, Prophesee ``.dat``, Metavision CSV.

Every file is written byte by byte from the published format descriptions (tests/_prophesee_files.py), never by
a reading library; a stereo pair reads back event for event and matches exactly as the same events from
``.npz``. The formats are told by content: an eDVS text ``.dat`` still reads as eDVS text.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cvstereo.errors import MissingExtraError
from cvstereo.io import detect_format, open_recording, read_matches, read_recording, write_recording
from cvstereo.io import prophesee as prophesee_module
from cvstereo.io.prophesee import decode_evt21
from cvstereo.model.recording import Recording
from tests._hostile import run_cli
from tests._io_helpers import textured_blobs
from tests._prophesee_files import csv_file, dat_file, evt21_words, raw_file, raw_header, scene_events

pytest.importorskip("faery")
pytest.importorskip("evt3")

RAW = ("evt2", "evt21", "evt3")
WIDTH, HEIGHT = 128, 128


def _camera_order(events: np.ndarray) -> np.ndarray:
    """Events in the order a sensor sends them within one microsecond (row, polarity, x): the vector words of
    EVT 2.1 / 3.0 carry no order of their own within a group."""
    return events[np.lexsort((events["x"], events["p"], events["y"], events["t"]))]


@pytest.fixture(scope="module")
def blobs() -> Recording:
    rec = textured_blobs(3)
    return Recording(_camera_order(rec.left), _camera_order(rec.right), None, None, rec.resolution, {})


def _write_pair(folder, rec: Recording, fmt: str) -> tuple:
    """The left and right files of ``rec`` in ``fmt``; returns their paths and the reader options."""
    suffix = {"prophesee-dat": ".dat", "metavision-csv": ".csv"}.get(fmt, ".raw")
    left, right = folder / f"left{suffix}", folder / f"right{suffix}"
    for path, events in ((left, rec.left), (right, rec.right)):
        if fmt == "prophesee-dat":
            dat_file(path, events, *rec.resolution)
        elif fmt == "metavision-csv":
            csv_file(path, events)
        else:
            raw_file(path, events, fmt, *rec.resolution)
    return left, right, ({"resolution": rec.resolution} if fmt == "metavision-csv" else {})


@pytest.mark.parametrize("fmt", [*RAW, "prophesee-dat", "metavision-csv"])
def test_stereo_pair_reads_back_and_matches_like_npz(tmp_path, blobs, fmt, monkeypatch):
    left, right, options = _write_pair(tmp_path, blobs, fmt)
    assert detect_format(left) == fmt
    got = read_recording(left, right, **options)
    for cam in ("left", "right"):
        np.testing.assert_array_equal(getattr(got, cam), getattr(blobs, cam))
    assert got.resolution == blobs.resolution
    write_recording(tmp_path / "same.npz", blobs)
    monkeypatch.chdir(tmp_path)
    extra = ["--resolution", "128x128"] if options else []
    assert run_cli(["match", str(left), str(right), *extra, "-o", "a.npz"]) == (0, "")
    assert run_cli(["match", "same.npz", "-o", "b.npz"]) == (0, "")
    a, b = read_matches(tmp_path / "a.npz"), read_matches(tmp_path / "b.npz")
    assert a.matches.size > 0
    np.testing.assert_array_equal(a.matches, b.matches)


@pytest.mark.parametrize("fmt", RAW)
def test_every_word_kind_and_clock_wraps(tmp_path, fmt):
    """Bursts (vector words), both polarities, the sensor's corners, and more than 2**24 us: the EVT 3.0 clock
    (24 bits) wraps twice, so a decoder that loses a wrap shifts every later time."""
    events = scene_events(4000, 640, 480, seed=1)
    events["t"] = events["t"] * 20  # spread over about a minute
    raw_file(tmp_path / "a.raw", events, fmt, 640, 480)
    stream = open_recording(tmp_path / "a.raw")
    assert stream.cameras == ("mono",) and stream.resolution == (640, 480)
    assert events["t"][-1] > 2 * 2**24
    np.testing.assert_array_equal(stream.read_camera("mono")[0], events)


def test_evt21_word_by_hand():
    """One TIME_HIGH word (t >> 6 = 3) and one ON vector at x 64, y 5, ts 7 with pixels 0, 1 and 31 set."""
    time_high = 0x8 << 60 | 3 << 32
    vector = 0x1 << 60 | 7 << 54 | 64 << 43 | 5 << 32 | (1 << 0 | 1 << 1 | 1 << 31)
    (t, x, y, p), high, bad = decode_evt21(np.array([time_high, vector], np.uint64), None)
    assert t.tolist() == [3 * 64 + 7] * 3 and x.tolist() == [64, 65, 95] and y.tolist() == [5] * 3
    assert p.tolist() == [True] * 3 and high == 3 and bad == -1


def test_evt21_legacy_half_order_and_chunks(tmp_path, monkeypatch):
    """``endianness=legacy``: the 64-bit words stored high half first (IMX636); decoded in many small chunks, the
    time's high bits carry from chunk to chunk."""
    events = scene_events(3000, 320, 320, seed=2)
    halves = evt21_words(events).view("<u4").reshape(-1, 2)[:, ::-1].copy()
    (tmp_path / "a.raw").write_bytes(b"% format EVT21;height=320;width=320;endianness=legacy\n% end\n"
                                     + halves.tobytes())
    monkeypatch.setattr(prophesee_module, "CHUNK_WORDS", 7)
    stream = open_recording(tmp_path / "a.raw")
    chunks = list(stream.chunks("mono"))
    assert len(chunks) > 100
    np.testing.assert_array_equal(np.concatenate([c for c, _ in chunks]), events)


def test_header_without_end_and_old_evt_key(tmp_path):
    """Older files end the header at the first line without '% ' and name the encoding '% evt 3.0'."""
    events = scene_events(500, 64, 48)
    from tests._prophesee_files import evt3_words

    body = b"% evt 3.0\n% geometry 64x48\n" + evt3_words(events).tobytes()
    (tmp_path / "old.bin").write_bytes(body)
    assert detect_format(tmp_path / "old.bin") == "evt3"
    np.testing.assert_array_equal(open_recording(tmp_path / "old.bin").read_camera("mono")[0], events)


def test_formats_told_by_content_not_extension(tmp_path, blobs):
    """A TUM eDVS text '.dat' stays eDVS text; a Prophesee '.dat' named '.txt' is still Prophesee; Metavision CSV
    and a comma-separated eDVS text file are told apart by their columns."""
    write_recording(tmp_path / "edvs.dat", blobs)
    assert detect_format(tmp_path / "edvs.dat") == "edvs-merged"
    np.testing.assert_array_equal(read_recording(tmp_path / "edvs.dat").left, blobs.left)
    dat_file(tmp_path / "cd.txt", blobs.left, 128, 128)
    assert detect_format(tmp_path / "cd.txt") == "prophesee-dat"
    csv_file(tmp_path / "mv.csv", blobs.left)
    assert detect_format(tmp_path / "mv.csv") == "metavision-csv"
    csv_file(tmp_path / "edvs.csv", blobs.left, order="txyp")
    assert detect_format(tmp_path / "edvs.csv") == "edvs-text"


def test_csv_columns_option_names_line_and_geometry(tmp_path, blobs):
    csv_file(tmp_path / "l.csv", blobs.left, order="tpxy")
    csv_file(tmp_path / "r.csv", blobs.right, order="tpxy")
    got = read_recording(tmp_path / "l.csv", tmp_path / "r.csv", format="metavision-csv", columns="t,p,x,y",
                         resolution=(128, 128))
    np.testing.assert_array_equal(got.left, blobs.left)
    np.testing.assert_array_equal(got.right, blobs.right)
    # A names line and a %geometry line: no option needed.
    text = (tmp_path / "l.csv").read_text()
    (tmp_path / "named.csv").write_text("%geometry:128,128\nt,p,x,y\n" + text)
    stream = open_recording(tmp_path / "named.csv")
    assert stream.format == "metavision-csv" and stream.resolution == (128, 128)
    np.testing.assert_array_equal(stream.read_camera("mono")[0], blobs.left)
    # The CLI's --columns reaches the reader.
    code, _ = run_cli(["info", str(tmp_path / "l.csv"), str(tmp_path / "r.csv"), "--format", "metavision-csv",
                       "--columns", "t,p,x,y", "--resolution", "128x128"])
    assert code == 0
    # Without --format: --columns (only Metavision CSV takes it) makes the comma-separated file, which detection
    # alone takes for eDVS text (its first column is a time), the CSV it describes.
    got = read_recording(tmp_path / "l.csv", tmp_path / "r.csv", columns="t,p,x,y", resolution=(128, 128))
    np.testing.assert_array_equal(got.left, blobs.left)
    code, _ = run_cli(["match", str(tmp_path / "l.csv"), str(tmp_path / "r.csv"), "--columns", "t,p,x,y",
                       "--resolution", "128x128", "-o", str(tmp_path / "m.npz"), "--no-progress"])
    assert code == 0
    # eDVS text (space-separated) with --columns is still refused, in one sentence naming the option
    (tmp_path / "e.txt").write_text("".join(f"{int(e['t'])} {e['x']} {e['y']} {e['p']}\n" for e in blobs.left[:50]))
    with pytest.raises(ValueError, match=r"columns does not apply to format 'edvs-text'"):
        read_recording(tmp_path / "e.txt", columns="t,x,y,p")


def test_packets_stream_without_reading_whole_files(tmp_path, blobs):
    left, right, _ = _write_pair(tmp_path, blobs, "evt3")
    packets = list(open_recording(left, right).packets(10_000))
    assert len(packets) >= 15
    assert sum(p.left.size for p in packets) == blobs.left.size


@pytest.mark.parametrize("fmt", ["evt2", "evt3", "prophesee-dat"])
def test_missing_decoder_names_the_extra(tmp_path, blobs, fmt, monkeypatch):
    left, _, _ = _write_pair(tmp_path, blobs, fmt)
    monkeypatch.setitem(sys.modules, prophesee_module.DECODERS[fmt], None)
    with pytest.raises(MissingExtraError, match=r"cvstereo\[prophesee\]"):
        open_recording(left)


def test_evt21_needs_no_extra(tmp_path, blobs, monkeypatch):
    left, _, _ = _write_pair(tmp_path, blobs, "evt21")
    monkeypatch.setitem(sys.modules, "faery", None)
    monkeypatch.setitem(sys.modules, "evt3", None)
    np.testing.assert_array_equal(open_recording(left).read_camera("mono")[0], blobs.left)


def test_header_size_is_read(tmp_path):
    assert raw_header("evt3", 1280, 720).count(b"1280") == 2
    events = scene_events(100, 1280, 720)
    raw_file(tmp_path / "hd.raw", events, "evt3", 1280, 720)
    assert open_recording(tmp_path / "hd.raw").resolution == (1280, 720)
