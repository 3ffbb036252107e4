"""Hostile input to the file readers (issue 13, "Crashes"): every case is a clear, one-line error.

Files are generated under tmp_path: recordings and matches files with a corrupted, lying or foreign npz
member, headers declaring sizes no sensor has, FIFOs, devices and directories where a file is expected.
Each case asserts the exception type and a message fragment (for the CLI: exit code 1 and one stderr
line), that nothing hangs (pytest-timeout) and that the input files' bytes are unchanged afterwards.
"""

from __future__ import annotations

import io
import json
import os
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from cvstereo.events import MAX_RESOLUTION, make_events
from cvstereo.matches import make_matches
from cvstereo.recording import Recording

from cvstereo.cli import main
from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io import open_recording, read_matches, read_recording
from cvstereo.io.npz import iter_npz_chunks, npz_keys, read_npz_header, write_matches, write_recording_npz

pytestmark = pytest.mark.timeout(60)

BIG = f"{MAX_RESOLUTION[0]}x{MAX_RESOLUTION[1]}"


# ---------------------------------------------------------------------------------------------- builders

def _recording(n: int = 3000, truth: bool = True) -> Recording:
    rng = np.random.default_rng(1)

    def cam():
        return make_events(np.cumsum(rng.integers(0, 30, n)), rng.integers(0, 128, n), rng.integers(0, 128, n),
                           rng.integers(0, 2, n))

    ld = rd = None
    if truth:
        ld, rd = rng.uniform(0, 20, n).astype(np.float32), rng.uniform(0, 20, n).astype(np.float32)
    return Recording(cam(), cam(), ld, rd, (128, 128), {"scene": "hostile"})


def _matches_meta(**extra) -> dict:
    return {"method": "frame", "variant": "shared", "params": {}, "anchor": "event", "window_us": 0,
            "anchor_cameras": [0, 1], **extra}


def _write_matches(path: Path, **meta) -> Path:
    m = make_matches(np.arange(0, 5000, 10), 5, 6, 1, 0, 3.0)
    write_matches(path, m, _matches_meta(**meta))
    return path


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as zf:
        return {info.filename: zf.read(info) for info in zf.infolist()}


def _rezip(path: Path, members: dict[str, bytes], *, stored: tuple[str, ...] = ()) -> Path:
    """Write ``members`` (name -> raw .npy bytes) as an npz; members named in ``stored`` uncompressed."""
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data, compress_type=zipfile.ZIP_STORED if name in stored else zipfile.ZIP_DEFLATED)
    return path


def _corrupt_member(path: Path, key: str) -> Path:
    """Flip bytes in the middle of member ``key``'s compressed data (a bit-rotted or badly copied file)."""
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(key + ".npy")
    raw = bytearray(path.read_bytes())
    # Local header: 30 bytes + name + extra field, then the compressed data.
    name_len, extra_len = struct.unpack("<HH", raw[info.header_offset + 26: info.header_offset + 30])
    start = info.header_offset + 30 + name_len + extra_len
    lo, hi = start + info.compress_size // 3, start + max(info.compress_size // 3 + 1, 2 * info.compress_size // 3)
    for i in range(lo, hi):
        raw[i] ^= 0x5A
    path.write_bytes(bytes(raw))
    return path


def _npy_bytes(array: np.ndarray, *, shape: tuple | None = None, descr=None) -> bytes:
    """The .npy serialisation of ``array``, optionally with a header that lies about shape or dtype."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=True)
    if shape is None and descr is None:
        return buf.getvalue()
    header = {"descr": np.lib.format.dtype_to_descr(array.dtype) if descr is None else descr,
              "fortran_order": False, "shape": array.shape if shape is None else shape}
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, header)
    return out.getvalue() + array.tobytes()


def _lying_npz(path: Path, key: str, rows: int, *, stored: bool = False) -> Path:
    """A recording whose member ``key`` declares ``rows`` rows in its header but holds far fewer."""
    write_recording_npz(path, _recording())
    members = _members(path)
    with zipfile.ZipFile(path) as zf:
        arr = np.load(io.BytesIO(zf.read(key + ".npy")))
    members[key + ".npy"] = _npy_bytes(arr, shape=(rows,))
    return _rezip(path, members, stored=(key + ".npy",) if stored else ())


def _replace_member(path: Path, key: str, array: np.ndarray) -> Path:
    members = _members(path)
    members[key + ".npy"] = _npy_bytes(array)
    return _rezip(path, members)


def _cli(argv: list[str], capsys) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, err


def _assert_one_line_error(code: int, err: str, *fragments: str) -> None:
    assert code == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for f in fragments:
        assert f in lines[0], lines[0]


@pytest.fixture
def snapshot():
    """Record files' bytes; assert at teardown that no case changed its input."""
    taken: dict[Path, bytes] = {}

    def take(*paths: Path) -> None:
        for p in paths:
            if Path(p).is_file():
                taken[Path(p)] = Path(p).read_bytes()

    yield take
    for p, data in taken.items():
        assert p.read_bytes() == data, f"{p} was modified"


# ------------------------------------------------------------------------- corrupted members, API readers

_RECORDING_READERS = {
    "read_recording": lambda p: read_recording(p),
    "read_recording-format": lambda p: read_recording(p, format="npz"),
    "open_recording.read": lambda p: open_recording(p).read(),
    "open_recording.packets": lambda p: list(open_recording(p).packets(10_000)),
    "open_recording.chunks-right": lambda p: list(open_recording(p).chunks("right")),
    "iter_npz_chunks": lambda p: list(iter_npz_chunks(p, "left")),
}


_EVENT_CASES = [(r, k) for r in _RECORDING_READERS for k in ("left", "right")
                if not (r == "iter_npz_chunks" and k == "right") and not (r.endswith("chunks-right") and k == "left")]


@pytest.mark.parametrize("reader,key", _EVENT_CASES)
def test_corrupted_event_member(tmp_path, snapshot, reader, key):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _corrupt_member(path, key)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=rf"rec\.npz.*'{key}'.*(corrupt|cannot be read)"):
        _RECORDING_READERS[reader](path)


_SMALL_READERS = {"read_recording": read_recording, "open_recording.read": lambda p: open_recording(p).read(),
                  "read_npz_header": read_npz_header}


@pytest.mark.parametrize("reader,key", [(r, k) for r in _SMALL_READERS for k in ("meta", "resolution", "left_disparity")
                                        if not (r == "read_npz_header" and k == "left_disparity")])
def test_corrupted_small_member(tmp_path, snapshot, key, reader):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _corrupt_member(path, key)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=rf"rec\.npz.*'{key}'"):
        _SMALL_READERS[reader](path)


def test_corrupted_matches_member(tmp_path, snapshot):
    path = _corrupt_member(_write_matches(tmp_path / "m.npz"), "matches")
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"m\.npz.*'matches'"):
        read_matches(path)


def test_corrupted_matches_meta(tmp_path, snapshot):
    path = _corrupt_member(_write_matches(tmp_path / "m.npz"), "meta")
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"m\.npz.*'meta'"):
        read_matches(path)


# ---------------------------------------------------------------------------- lying and foreign headers

@pytest.mark.parametrize("rows", [10**15, 10**9, 3001])
@pytest.mark.parametrize("stored", [False, True])
def test_header_declares_more_rows_than_member_holds(tmp_path, snapshot, rows, stored):
    path = _lying_npz(tmp_path / "rec.npz", "left", rows, stored=stored)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'left'.*declares"):
        read_recording(path)


@pytest.mark.parametrize("rows", [10**15, 3001])
def test_header_lie_streaming(tmp_path, snapshot, rows):
    path = _lying_npz(tmp_path / "rec.npz", "right", rows)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'right'.*declares"):
        list(open_recording(path).packets())


def test_header_declares_huge_matches(tmp_path, snapshot):
    path = _write_matches(tmp_path / "m.npz")
    members = _members(path)
    arr = np.load(io.BytesIO(members["matches.npy"]))
    members["matches.npy"] = _npy_bytes(arr, shape=(10**15,))
    _rezip(path, members)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"m\.npz.*'matches'.*declares"):
        read_matches(path)


def _set_uncompressed_size(path: Path, member: str, size: int) -> None:
    """Patch the uncompressed size zip records for ``member`` (local header and central directory)."""
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as zf:
        local, central = zf.getinfo(member).header_offset, zf.start_dir
    raw[local + 22: local + 26] = struct.pack("<I", size)
    pos = central
    while raw[pos: pos + 4] == b"PK\x01\x02":
        name_len, extra_len, comment_len = struct.unpack("<HHH", raw[pos + 28: pos + 34])
        if raw[pos + 46: pos + 46 + name_len] == member.encode():
            raw[pos + 24: pos + 28] = struct.pack("<I", size)
        pos += 46 + name_len + extra_len + comment_len
    path.write_bytes(bytes(raw))


def test_member_claims_huge_uncompressed_size(tmp_path, snapshot):
    # The zip directory says the member inflates to 4 GB (a zip bomb's claim): refused before inflating.
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _set_uncompressed_size(path, "left.npy", 0xFFFFFFF0)
    with zipfile.ZipFile(path) as zf:
        assert zf.getinfo("left.npy").file_size == 0xFFFFFFF0
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'left'"):
        read_recording(path)


@pytest.mark.parametrize("key", ["left", "meta", "resolution", "left_disparity"])
def test_object_array_member_names_the_file(tmp_path, snapshot, key):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _replace_member(path, key, np.array([{"evil": 1}, None], dtype=object))
    snapshot(path)
    with pytest.raises(CorruptFileError, match=rf"rec\.npz.*'{key}'.*object"):
        read_recording(path)


def test_object_array_in_matches(tmp_path, snapshot):
    path = _write_matches(tmp_path / "m.npz")
    _replace_member(path, "matches", np.array([1, "x"], dtype=object))
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"m\.npz.*'matches'.*object"):
        read_matches(path)


def test_object_array_streaming(tmp_path, snapshot):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _replace_member(path, "right", np.array([1, "x"], dtype=object))
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'right'.*object"):
        list(open_recording(path).chunks("right"))


@pytest.mark.parametrize("descr", ["<i4", "|V13"])
def test_member_with_wrong_event_dtype(tmp_path, snapshot, descr):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    members = _members(path)
    members["left.npy"] = _npy_bytes(np.zeros(13 * 13, np.uint8), shape=(13,), descr=descr) if descr == "|V13" \
        else _npy_bytes(np.arange(10, dtype="<i4"))
    _rezip(path, members)
    snapshot(path)
    with pytest.raises(EventFormatError, match=r"rec\.npz.*left"):
        read_recording(path)


# ------------------------------------------------------------------------------------ declared sensor size

@pytest.mark.parametrize("res", [[100000, 100000], [2049, 128], [128, 4096], [0, 0], [-1, 128], [128, 0]])
def test_npz_resolution_key_out_of_bounds(tmp_path, snapshot, res):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording(truth=False))
    _replace_member(path, "resolution", np.array(res, np.int64))
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'resolution'"):
        read_recording(path)
    with pytest.raises(CorruptFileError, match=r"rec\.npz.*'resolution'"):
        open_recording(path)


def test_npz_resolution_names_the_limit(tmp_path):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording(truth=False))
    _replace_member(path, "resolution", np.array([100000, 100000], np.int64))
    with pytest.raises(CorruptFileError, match=BIG):
        read_npz_header(path)


def _text_file(path: Path, header: str, lines: int = 20, columns: int = 4) -> Path:
    body = "".join(f"{10 * i} {i % 50} {i % 40} 1" + (f" {i % 2}" if columns == 5 else "") + "\n"
                   for i in range(lines))
    path.write_text(header + body)
    return path


@pytest.mark.parametrize("header,fragment", [
    ("# resolution 100000 100000\n", BIG),
    ("# resolution 4096 2\n", BIG),
    ("# resolution 0 0\n", "line 1"),
    ("# resolution -128 128\n", "line 1"),
    ("# resolution 99999999999999999999999 1\n", "line 1"),
])
@pytest.mark.parametrize("fmt", ["edvs-text", "edvs-merged"])
def test_text_header_resolution_out_of_bounds(tmp_path, snapshot, header, fragment, fmt):
    path = _text_file(tmp_path / "r.txt", header, columns=5 if fmt == "edvs-merged" else 4)
    snapshot(path)
    right = path if fmt == "edvs-text" else None
    with pytest.raises(ValueError, match=rf"r\.txt.*{fragment}"):
        read_recording(path, right, format=fmt, one_based=False, **({"left_retina": 0} if right is None else {}))


@pytest.mark.parametrize("res", [(100000, 100000), (0, 0), (-5, 128), (128, 2049)])
def test_given_resolution_out_of_bounds(tmp_path, snapshot, res):
    path = _text_file(tmp_path / "r.txt", "")
    snapshot(path)
    with pytest.raises(ValueError, match=r"resolution"):
        read_recording(path, path, format="edvs-text", resolution=res)


@pytest.mark.parametrize("res", [(0, 0), (-1, 5), (100000, 100000), (2049, 2048)])
def test_recording_resolution_out_of_bounds(res):
    with pytest.raises(ValueError, match=r"resolution"):
        Recording(make_events([], [], [], []), make_events([], [], [], []), resolution=res)


def test_recording_resolution_at_the_limit_is_accepted():
    ev = make_events([0], [MAX_RESOLUTION[0] - 1], [MAX_RESOLUTION[1] - 1], [1])
    assert Recording(ev, ev, resolution=MAX_RESOLUTION).resolution == MAX_RESOLUTION


# ------------------------------------------------------------------------------ non-regular files (API)

_FORMATS = {"npz": "x.npz", "edvs-text": "x.txt", "edvs-merged": "x.dat", "aedat2": "x.aedat"}


@pytest.mark.parametrize("fmt", list(_FORMATS))
def test_fifo_is_refused_without_hanging(tmp_path, fmt):
    fifo = tmp_path / _FORMATS[fmt]
    os.mkfifo(fifo)
    with pytest.raises(OSError, match=r"not a regular file"):
        open_recording(fifo, fifo if fmt == "edvs-text" else None, format=fmt)


@pytest.mark.parametrize("fmt", [None, *_FORMATS])
def test_fifo_detected_format_is_refused(tmp_path, fmt):
    # Without --format the extension decides; the FIFO is still not "no such file".
    fifo = tmp_path / _FORMATS[fmt or "npz"]
    os.mkfifo(fifo)
    with pytest.raises(OSError, match=r"not a regular file"):
        read_recording(fifo)


@pytest.mark.parametrize("fmt", list(_FORMATS))
def test_directory_is_a_directory(tmp_path, fmt):
    folder = tmp_path / _FORMATS[fmt]
    folder.mkdir()
    with pytest.raises(IsADirectoryError, match=r"is a directory"):
        read_recording(folder, folder if fmt == "edvs-text" else None, format=fmt)
    with pytest.raises(IsADirectoryError, match=r"is a directory"):
        read_recording(folder, folder if fmt == "edvs-text" else None)


def test_directory_matches_file(tmp_path):
    (tmp_path / "m.npz").mkdir()
    with pytest.raises(IsADirectoryError, match=r"m\.npz: is a directory"):
        read_matches(tmp_path / "m.npz")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
@pytest.mark.parametrize("fmt", list(_FORMATS))
def test_dev_zero_is_refused(fmt):
    with pytest.raises(OSError, match=r"/dev/zero.*not a regular file"):
        read_recording("/dev/zero", "/dev/zero" if fmt == "edvs-text" else None, format=fmt)


def test_npz_keys_of_fifo(tmp_path):
    fifo = tmp_path / "k.npz"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match=r"not a regular file"):
        npz_keys(fifo)


# ------------------------------------------------------------------------------------ matches meta values

@pytest.mark.parametrize("window_us", [1e300, 10**20, -40000, "forty", float("nan")])
def test_matches_meta_window_us_refused(tmp_path, snapshot, window_us):
    path = tmp_path / "m.npz"
    m = make_matches(np.arange(0, 5000, 10), 5, 6, 1, 0, 3.0)
    # Written by hand: the writer would refuse none of these, a hostile or edited file may hold them.
    meta = json.dumps(_matches_meta(window_us=window_us))
    buf = io.BytesIO()
    np.savez(buf, matches=m, meta=np.array(meta))
    path.write_bytes(buf.getvalue())
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"m\.npz.*window_us"):
        read_matches(path)


# -------------------------------------------------------------------------------------- through the CLI

@pytest.fixture
def good_recording(tmp_path) -> Path:
    path = tmp_path / "good.npz"
    write_recording_npz(path, _recording())
    return path


@pytest.mark.parametrize("command", ["info", "match", "convert", "evaluate"])
def test_cli_corrupted_member(tmp_path, capsys, snapshot, command):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _corrupt_member(path, "left")
    snapshot(path)
    argv = {"info": ["info", path],
            "match": ["match", path, "-o", tmp_path / "m.npz"],
            "convert": ["convert", path, "-o", tmp_path / "out.txt"],
            "evaluate": ["evaluate", path, _write_matches(tmp_path / "m.npz")]}[command]
    code, err = _cli(argv, capsys)
    _assert_one_line_error(code, err, "rec.npz", "'left'")


def test_cli_evaluate_corrupted_matches(tmp_path, capsys, snapshot, good_recording):
    matches = _corrupt_member(_write_matches(tmp_path / "m.npz"), "matches")
    snapshot(matches, good_recording)
    code, err = _cli(["evaluate", good_recording, matches], capsys)
    _assert_one_line_error(code, err, "m.npz", "'matches'")


def test_cli_evaluate_meta_window_us_huge(tmp_path, capsys, snapshot, good_recording):
    path = tmp_path / "m.npz"
    meta = json.dumps(_matches_meta(window_us=1e300, anchor="window"))
    buf = io.BytesIO()
    np.savez(buf, matches=make_matches(np.arange(0, 5000, 10), 5, 6, 1, 0, 3.0), meta=np.array(meta))
    path.write_bytes(buf.getvalue())
    snapshot(path, good_recording)
    code, err = _cli(["evaluate", good_recording, path], capsys)
    _assert_one_line_error(code, err, "m.npz", "window_us")


@pytest.mark.parametrize("fmt", [None, *_FORMATS])
def test_cli_info_dev_zero(capsys, fmt):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    code, err = _cli(["info", "/dev/zero", *(["--format", fmt] if fmt else [])], capsys)
    _assert_one_line_error(code, err, "/dev/zero")


@pytest.mark.parametrize("fmt", [None, *_FORMATS])
def test_cli_info_fifo(tmp_path, capsys, fmt):
    fifo = tmp_path / _FORMATS[fmt or "npz"]
    os.mkfifo(fifo)
    code, err = _cli(["info", fifo, *(["--format", fmt] if fmt else [])], capsys)
    _assert_one_line_error(code, err, str(fifo), "not a regular file")


@pytest.mark.parametrize("name", ["d.npz", "d.txt", "d.aedat"])
def test_cli_info_directory(tmp_path, capsys, name):
    (tmp_path / name).mkdir()
    code, err = _cli(["info", tmp_path / name], capsys)
    _assert_one_line_error(code, err, name, "is a directory")


def test_cli_info_object_array(tmp_path, capsys, snapshot):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording())
    _replace_member(path, "left", np.array([1, "x"], dtype=object))
    snapshot(path)
    code, err = _cli(["info", path], capsys)
    _assert_one_line_error(code, err, "rec.npz", "'left'")


def test_cli_info_header_lie(tmp_path, capsys, snapshot):
    path = _lying_npz(tmp_path / "rec.npz", "left", 10**15)
    snapshot(path)
    code, err = _cli(["info", path], capsys)
    _assert_one_line_error(code, err, "rec.npz", "'left'")


def test_cli_info_huge_text_resolution(tmp_path, capsys, snapshot):
    path = _text_file(tmp_path / "r.dat", "# resolution 100000 100000\n# left_retina 0\n", columns=5)
    snapshot(path)
    code, err = _cli(["info", path], capsys)
    _assert_one_line_error(code, err, "r.dat", BIG)


def test_cli_info_huge_npz_resolution(tmp_path, capsys, snapshot):
    path = tmp_path / "rec.npz"
    write_recording_npz(path, _recording(truth=False))
    _replace_member(path, "resolution", np.array([100000, 100000], np.int64))
    snapshot(path)
    code, err = _cli(["info", path], capsys)
    _assert_one_line_error(code, err, "rec.npz", BIG)


@pytest.mark.parametrize("value", ["100000x100000", "0x0", "2049x2048", "-5x3", "12", "axb", "128x128x3"])
def test_cli_resolution_option(tmp_path, capsys, value):
    path = _text_file(tmp_path / "r.txt", "")
    with pytest.raises(SystemExit) as exc:
        main(["info", str(path), f"--resolution={value}"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--resolution" in err and "Traceback" not in err


def test_cli_resolution_option_names_the_limit(tmp_path, capsys):
    path = _text_file(tmp_path / "r.txt", "")
    with pytest.raises(SystemExit):
        main(["info", str(path), "--resolution=100000x100000"])
    assert BIG in capsys.readouterr().err


def test_cli_info_matches_file_says_what_it_is(tmp_path, capsys, snapshot):
    # `info` summarises a matches file as such (cvstereo/cli/info.py) rather than misreading it as a recording.
    path = _write_matches(tmp_path / "m.npz")
    snapshot(path)
    assert main(["info", str(path)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith(f"{path}: matches file") and "500 matches" in captured.out


# ------------------------------------------------------------------------- file contents quoted in errors

@pytest.mark.parametrize("name,content", [
    ("e.txt", b"0 1 2 1\n5 \x1b[2J\x1b]0;owned\x07 3 1\n"),
    ("e.txt", b"0 1 2 1\n7 1 2 1 1\r\x1b[1A\n"),
    ("e.aedat", b"#!AER-DAT3.1\x1b[31m\r\n"),
])
def test_control_characters_are_not_echoed(tmp_path, capsys, snapshot, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    snapshot(path)
    with pytest.raises(CorruptFileError, match=r"\\x1b"):
        read_recording(path, path if name.endswith(".txt") else None, one_based=False) if name.endswith(".txt") \
            else read_recording(path)
    code, err = _cli(["info", path], capsys)
    _assert_one_line_error(code, err, name)
    assert "\x1b" not in err and "\r" not in err and "\x07" not in err
