"""eDVS text recordings: single-camera pairs and merged five-column files, detection, streaming, errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io import detect_format, open_recording, read_recording, write_recording
from cvstereo.io.edvs_text import (
    iter_text_chunks,
    open_edvs_merged,
    overlay_shift,
    read_edvs_merged,
    scan_text,
    write_edvs_text,
)
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from tests._io_helpers import assert_same_events, random_events, random_recording, recordings

_TMP = settings(deadline=None, max_examples=15, suppress_health_check=[HealthCheck.function_scoped_fixture])


# ------------------------------------------------------------------------------------------- round trips

@_TMP
@given(rec=recordings(resolution=(64, 32)))
def test_pair_round_trip(tmp_path, rec):
    left, right = tmp_path / "l.txt", tmp_path / "r.txt"
    write_recording(left, rec, right=right)
    assert detect_format(left) == "edvs-text"
    back = read_recording(left, right)
    assert back.resolution == (64, 32)  # from the '# resolution' header
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)


@_TMP
@given(rec=recordings(), left_retina=st.sampled_from([0, 1]))
def test_merged_round_trip_states_left_retina_in_the_header(tmp_path, rec, left_retina):
    path = tmp_path / "m.dat"
    write_recording(path, rec, left_retina=left_retina)
    assert detect_format(path) == "edvs-merged"
    back = read_recording(path)
    assert back.meta["left_retina"] == left_retina and back.meta["left_retina_from"] == "header"
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)


def test_commas_comments_blank_lines_crlf_and_minus_one_polarity(tmp_path):
    path = tmp_path / "cam.txt"
    path.write_bytes(b"# a comment\r\n# resolution 128 128\r\n\r\n10, 1, 2, 1\r\n  # indented comment\r\n"
                     b"11,3,4,-1\r\n12 5 6 0 # trailing comment\r\n")
    ev = np.concatenate(list(iter_text_chunks(path)))
    assert ev["t"].tolist() == [10, 11, 12] and ev["x"].tolist() == [1, 3, 5] and ev["p"].tolist() == [1, 0, 0]


def test_one_based_given_or_detected(tmp_path):
    path = tmp_path / "m.dat"
    path.write_text("0 1 1 1 0\n5 128 3 -1 1\n9 12 128 1 0\n")
    rec = read_recording(path, left_retina=0)
    assert rec.meta["one_based"] and rec.meta["one_based_from"] == "detected"
    assert rec.left["x"].tolist() == [0, 11] and rec.left["y"].tolist() == [0, 127] and rec.right["x"][0] == 127
    # Nothing reaches 128: read as zero-based unless told.
    path.write_text("0 1 1 1 0\n5 127 3 -1 1\n")
    assert read_recording(path, left_retina=0).left["x"][0] == 1
    assert read_recording(path, left_retina=0, one_based=True).left["x"][0] == 0


def test_one_based_detection_rejects_a_file_spanning_both_conventions(tmp_path):
    path = tmp_path / "m.dat"
    path.write_text("0 0 1 1 0\n5 128 3 1 1\n")
    with pytest.raises(EventFormatError, match="neither zero- nor one-based"):
        read_recording(path, left_retina=0)


@pytest.mark.parametrize("chunk_lines", [1, 7, 1000])
def test_chunked_streams_equal_the_whole_file(tmp_path, rng, chunk_lines):
    rec = random_recording(rng, 300, 200)
    path = tmp_path / "m.txt"
    write_recording(path, rec, left_retina=1)
    stream = open_edvs_merged(path, chunk_lines=chunk_lines)
    assert max(c.size for c in iter_text_chunks(path, retina=1, chunk_lines=chunk_lines)) <= chunk_lines
    back = stream.read()
    assert_same_events(back.left, rec.left)
    assert_same_events(back.right, rec.right)


# ---------------------------------------------------------------------------------- left-retina detection

def test_overlay_shift_finds_a_known_shift(rng):
    b = rng.poisson(2.0, (32, 64)).astype(float)
    a = np.zeros_like(b)
    a[:, 9:] = b[:, :-9]
    assert overlay_shift(a, b, max_shift=20)[0] == 9
    assert overlay_shift(b, a, max_shift=20)[0] == -9


@pytest.mark.parametrize("left_retina", [0, 1])
def test_left_retina_detected_from_a_shifted_texture(tmp_path, rng, left_retina):
    n, d = 4000, 7
    right = random_events(rng, n)
    right["x"] = np.clip(right["x"], 0, 127 - d)
    right["x"] = right["x"] // 4 * 4  # a texture of columns, so the shift is well defined
    left = right.copy()
    left["x"] += d  # the left camera sees a scene point at the larger x
    path = tmp_path / "m.dat"
    retina = np.where(np.arange(2 * n) < n, left_retina, 1 - left_retina)
    both = np.concatenate([left, right])
    np.savetxt(path, np.column_stack([both["t"], both["x"], both["y"], both["p"], retina]), fmt="%d")
    rec = read_recording(path)
    assert rec.meta["left_retina"] == left_retina and rec.meta["left_retina_from"] == "detected"
    assert rec.meta["overlay_shift_px"] == d
    assert_same_events(rec.left, left)


def test_left_retina_cannot_be_detected_without_parallax(tmp_path, rng):
    ev = random_events(rng, 500)
    path = tmp_path / "m.dat"
    both = np.concatenate([ev, ev])
    np.savetxt(path, np.column_stack([both["t"], both["x"], both["y"], both["p"], np.repeat([0, 1], ev.size)]),
               fmt="%d")
    with pytest.raises(ValueError, match="give left_retina"):
        read_recording(path)
    assert read_recording(path, left_retina=1).meta["left_retina_from"] == "given"


# ------------------------------------------------------------------------------------------ real files

_TUM = {  # file: (events of retina 0, of retina 1, left retina, one-based), from the data's README
    "Fan_disp8.dat": (63_487, 72_746, 1, False),
    "NSTlogo_disp12-8-3.dat": (1_310, 1_290, 1, False),
    "movingPersons.dat": (32_419, 29_528, 0, True),
}


@pytest.mark.shared_data
@pytest.mark.parametrize("name", sorted(_TUM))
def test_real_files_counts_and_detection(tum_dir, name):
    n0, n1, left, one_based = _TUM[name]
    rec = read_edvs_merged(tum_dir / name)
    assert rec.meta["left_retina"] == left and rec.meta["left_retina_from"] == "detected"
    assert rec.meta["one_based"] is one_based and rec.meta["one_based_from"] == "detected"
    assert (rec.left.size, rec.right.size) == ((n1, n0) if left == 1 else (n0, n1))
    assert scan_text(tum_dir / name).counts == (n0, n1)
    assert rec.left["x"].min() >= 0 and rec.left["x"].max() <= 127


@pytest.mark.shared_data
def test_real_file_streams_in_packets_like_the_whole_read(tum_dir):
    path = tum_dir / "Fan_disp8.dat"
    rec = read_recording(path)
    streamed = list(open_recording(path).packets(50_000))
    whole = list(rec.packets(50_000))
    assert [p.until for p in streamed] == [p.until for p in whole]
    for a, b in zip(streamed, whole, strict=True):
        assert_same_events(a.left, b.left)
        assert_same_events(a.right, b.right)
    # One retina per pass, in bounded chunks.
    chunks = list(iter_text_chunks(path, retina=0, chunk_lines=10_000))
    assert sum(c.size for c in chunks) == 63_487 and max(c.size for c in chunks) <= 10_000


# ---------------------------------------------------------------------------------------------- errors

def _write(tmp_path, text: str, name: str = "cam.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_garbage_line_names_file_line_and_text(tmp_path):
    path = _write(tmp_path, "# header\n1 2 3 1\n2 2 3 1\n3 two 3 1\n4 2 3 1\n")
    with pytest.raises(CorruptFileError, match=r"cam.txt, line 4: '3 two 3 1' holds something other than integers"):
        list(iter_text_chunks(path))


def test_garbage_line_in_a_later_chunk_gets_its_global_line_number(tmp_path):
    lines = [f"{i} 1 1 1" for i in range(50)]
    lines[37] = "37 1 1 1 1"
    path = _write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(CorruptFileError, match=r"line 38: '37 1 1 1 1' has 5 columns where .* has 4"):
        list(iter_text_chunks(path, chunk_lines=8))


def test_out_of_range_pixel_names_field_index_and_line(tmp_path):
    path = _write(tmp_path, "0 1 1 1 0\n1 5 5 1 1\n2 130 1 1 0\n", name="m.dat")
    with pytest.raises(EventFormatError) as info:
        read_recording(path, left_retina=0, one_based=False)
    msg = str(info.value)
    for part in ("m.dat [retina 0]", "field 'x'", "index 1", "130", "line 3: '2 130 1 1 0'"):
        assert part in msg


def test_backwards_time_names_line_across_chunks(tmp_path):
    path = _write(tmp_path, "# c\n10 1 1 1\n20 1 1 1\n30 1 1 1\n25 1 1 1\n")
    with pytest.raises(EventFormatError, match=r"field 't' at index 3 is 25.*line 5: '25 1 1 1'"):
        list(iter_text_chunks(path, chunk_lines=3))


def test_bad_retina_id_and_bad_polarity(tmp_path):
    path = _write(tmp_path, "0 1 1 1 0\n1 1 1 1 2\n", name="m.dat")
    with pytest.raises(EventFormatError, match=r"field 'retina' at line 2 is 2"):
        read_recording(path, left_retina=0)
    path = _write(tmp_path, "0 1 1 3\n")
    with pytest.raises(EventFormatError, match=r"field 'p' at index 0 is 3.*line 1"):
        list(iter_text_chunks(path))


def test_column_count_mismatch_between_layouts(tmp_path):
    single, merged = _write(tmp_path, "0 1 1 1\n"), _write(tmp_path, "0 1 1 1 0\n", name="m.dat")
    with pytest.raises(CorruptFileError, match="merged two-camera file"):
        read_recording(merged, single, format="edvs-text")
    with pytest.raises(CorruptFileError, match="single-camera file"):
        read_recording(single, format="edvs-merged")
    with pytest.raises(ValueError, match="3 columns"):
        detect_format(_write(tmp_path, "0 1 1\n", name="three.txt"))


def test_missing_file_and_malformed_header(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"gone\.txt: no such file"):
        read_recording(tmp_path / "gone.txt", tmp_path / "gone2.txt")
    path = _write(tmp_path, "# resolution 128\n0 1 1 1\n")
    with pytest.raises(CorruptFileError, match="line 1: header '# resolution 128' is malformed"):
        list(iter_text_chunks(path))


def test_single_file_is_one_camera(tmp_path, rng):
    path = tmp_path / "cam.txt"
    write_edvs_text(path, random_events(rng, 10))
    stream = open_recording(path)
    assert stream.cameras == ("mono",) and not stream.is_stereo
    with pytest.raises(ValueError, match="holds one camera only"):
        stream.read()


def test_writer_is_atomic_and_validates(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        write_edvs_text(tmp_path / "no" / "x.txt", make_events([0], [0], [0], [1]))
    bad = Recording(make_events([0], [0], [0], [1]), make_events([0], [90], [0], [1]), resolution=(128, 128))
    with pytest.raises(EventFormatError):
        write_edvs_text(tmp_path / "x.txt", bad.right, resolution=(64, 64))
    assert list(tmp_path.iterdir()) == []  # nothing half-written left behind
