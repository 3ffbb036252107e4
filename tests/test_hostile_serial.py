"""Hostile input to the live-sensor side: bad options, outputs over inputs, bad journals, garbage bytes and
wrong protocol settings. Each case asserts the exit code (or exception) and the message, and that no input
file changed."""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest
from cvstereo.events import EVENT_DTYPE, make_events
from cvstereo.recording import Recording

from cvstereo.cli import main
from cvstereo.errors import CorruptFileError
from cvstereo.io.npz import write_recording_npz
from cvstereo.sensors import VirtualEDVS
from cvstereo.sensors.decoder import RESYNC_WINDOW, StreamDecoder
from cvstereo.sensors.detect import ProtocolMismatchError, check_protocol
from cvstereo.sensors.journal import MAGIC, MAX_HEADER_BYTES, read_journal
from cvstereo.sensors.protocol import FORMATS, ProtocolSettings, encode_events

pytestmark = pytest.mark.timeout(60)


def stream(n=10_000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.integers(0, 300, n))
    return make_events(t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n))


@pytest.fixture
def rec_path(tmp_path):
    ev = stream(200)
    path = tmp_path / "p.npz"
    write_recording_npz(path, Recording(ev, ev))
    return path


def journal_bytes(header: bytes, records=b"") -> bytes:
    return MAGIC + header + b"\n" + records


def record(camera, events):
    return struct.pack("<BI", camera, events.size) + events.astype(EVENT_DTYPE).tobytes()


# -- options: usage errors (exit 2), checked before any board is opened ------------------------------------
BAD_OPTIONS = [
    (["--seconds", "-5"], "--seconds must be a finite number greater than 0"),
    (["--seconds", "0"], "--seconds must be a finite number greater than 0"),
    (["--seconds", "nan"], "--seconds must be a finite number greater than 0"),
    (["--seconds", "inf"], "--seconds must be a finite number greater than 0"),
    (["--seconds", "soon"], "--seconds must be a number"),
    (["--speed", "nan"], "--speed must be a finite number greater than 0"),
    (["--speed", "-1"], "--speed must be a finite number greater than 0"),
    (["--speed", "0"], "--speed must be a finite number greater than 0"),
    (["--speed", "1e400"], "--speed must be a finite number greater than 0"),
    (["--baud", "0"], "--baud must be a finite number greater than 0"),
    (["--baud", "1.5"], "--baud must be a whole number"),
    (["--event-format", "E9"], "invalid choice: 'E9'"),
    (["--sync-bit", "maybe"], "invalid choice: 'maybe'"),
]


@pytest.mark.parametrize("command", ["record", "live"])
@pytest.mark.parametrize(("extra", "message"), BAD_OPTIONS, ids=[" ".join(o) for o, _ in BAD_OPTIONS])
def test_bad_option_is_a_usage_error(command, extra, message, rec_path, tmp_path, capsys):
    args = [command, "--simulate", str(rec_path), *extra]
    args += ["-o", str(tmp_path / "o.npz")] if command == "record" else ["--method", "frame"]
    before = rec_path.read_bytes()
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert rec_path.read_bytes() == before and not (tmp_path / "o.npz.journal").exists()


# -- outputs and journals over inputs (exit 1, nothing touched) --------------------------------------------
def _link(kind, src, dst):
    (os.symlink if kind == "symlink" else os.link)(src, dst)
    return dst


@pytest.mark.parametrize("via", ["same path", "symlink", "hard link"])
def test_record_output_over_its_simulate_input_is_refused(via, rec_path, tmp_path, capsys):
    out = rec_path if via == "same path" else _link(via.split()[0].replace("hard", "link"), rec_path,
                                                     tmp_path / "alias.npz")
    before = rec_path.read_bytes()
    assert main(["record", "--simulate", str(rec_path), "-o", str(out), "--seconds", "1"]) == 1
    err = capsys.readouterr().err
    assert "is the --simulate file" in err and len(err.strip().splitlines()) == 1
    assert rec_path.read_bytes() == before


@pytest.mark.parametrize("victim", ["input recording", "other file"])
def test_journal_option_never_truncates_an_existing_file(victim, rec_path, tmp_path, capsys):
    target = rec_path if victim == "input recording" else tmp_path / "matches.npz"
    if victim == "other file":
        target.write_bytes(b"precious")
    before = target.read_bytes()
    assert main(["record", "--simulate", str(rec_path), "-o", str(tmp_path / "o.npz"), "--journal", str(target),
                 "--seconds", "1"]) == 1
    err = capsys.readouterr().err
    assert f"journal {target}: the file exists and is not a cvstereo journal" in err
    assert target.read_bytes() == before


def test_existing_crash_journal_is_refused_not_wiped(rec_path, tmp_path, capsys):
    journal = tmp_path / "rk.npz.journal"
    data = journal_bytes(b"{}", record(0, stream(10)))
    journal.write_bytes(data)
    assert main(["record", "--simulate", str(rec_path), "-o", str(tmp_path / "rk.npz"), "--seconds", "1"]) == 1
    assert f"journal {journal} exists: recover it with --from-journal or delete it" in capsys.readouterr().err
    assert journal.read_bytes() == data


def test_output_equal_to_journal_is_refused(rec_path, tmp_path, capsys):
    out = tmp_path / "o.npz"
    assert main(["record", "--simulate", str(rec_path), "-o", str(out), "--journal", str(out)]) == 1
    assert "is the --journal file" in capsys.readouterr().err
    assert not out.exists()


def test_from_journal_onto_itself_is_refused(tmp_path, capsys):
    journal = tmp_path / "j.journal"
    data = journal_bytes(b"{}", record(0, stream(10)))
    journal.write_bytes(data)
    assert main(["record", "--from-journal", str(journal), "-o", str(journal)]) == 1
    assert "is the --from-journal file" in capsys.readouterr().err
    assert journal.read_bytes() == data


# -- bad journals -----------------------------------------------------------------------------------------
def _fifo(tmp_path):
    path = tmp_path / "fifo.journal"
    os.mkfifo(path)
    return path


BAD_JOURNALS = {
    "device": (lambda tmp: "/dev/zero", "not a regular file"),
    "fifo": (_fifo, "not a regular file"),
    "directory": (lambda tmp: tmp, "is a directory"),
    "missing": (lambda tmp: tmp / "none.journal", "no such journal"),
    "empty": (lambda tmp: _write(tmp, b""), "empty file"),
    "wrong magic": (lambda tmp: _write(tmp, b"PK\x03\x04 zip"), "not a cvstereo journal"),
    "header a JSON list": (lambda tmp: _write(tmp, journal_bytes(b"[1, 2]")), "holds a JSON list, not an object"),
    "header a JSON number": (lambda tmp: _write(tmp, journal_bytes(b"7")), "holds a JSON int, not an object"),
    "header not JSON": (lambda tmp: _write(tmp, journal_bytes(b"{oops")), "journal header is not JSON"),
    "header not UTF-8": (lambda tmp: _write(tmp, journal_bytes(b"\xff\xfe")), "journal header is not JSON"),
    "header endless": (lambda tmp: _write(tmp, MAGIC + b" " * (MAX_HEADER_BYTES + 10)), "header longer than"),
    "header cut short": (lambda tmp: _write(tmp, MAGIC + b'{"a": '), "header is cut short"),
    "camera id 7": (lambda tmp: _write(tmp, journal_bytes(b"{}", record(7, stream(3)))), "names camera 7"),
    "time backwards": (lambda tmp: _write(tmp, journal_bytes(b"{}", record(0, stream(5)[::-1]))), "j.journal"),
}


def _write(tmp, data):
    path = tmp / "j.journal"
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("case", list(BAD_JOURNALS))
def test_bad_journal_is_one_error_naming_it(case, tmp_path, capsys):
    make, message = BAD_JOURNALS[case]
    path = make(tmp_path)
    before = path.read_bytes() if os.path.isfile(path) else None
    assert main(["record", "--from-journal", str(path), "-o", str(tmp_path / "o.npz")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("cvstereo record: error:")
    assert message in err and str(path) in err
    assert not (tmp_path / "o.npz").exists()
    if before is not None:
        assert path.read_bytes() == before


def test_journal_cut_short_by_a_crash_keeps_every_whole_record(tmp_path):
    ev = stream(50)
    path = _write(tmp_path, journal_bytes(b'{"scene": "x"}', record(0, ev[:30]) + record(1, ev) +
                                          record(0, ev[30:]) + record(1, ev[:10])[:-7]))
    rec, lost = read_journal(path)
    np.testing.assert_array_equal(rec.left, ev)
    np.testing.assert_array_equal(rec.right, ev)
    assert lost == 5 + 10 * EVENT_DTYPE.itemsize - 7 and rec.meta["scene"] == "x"


def test_read_journal_api_raises_corrupt_file_error(tmp_path):
    with pytest.raises(CorruptFileError, match="holds a JSON list"):
        read_journal(_write(tmp_path, journal_bytes(b"[]")))


# -- garbage and wrong protocol settings --------------------------------------------------------------------
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_pure_garbage_is_counted_as_corrupt_with_bounded_memory(fmt):
    # 200 KB of line noise: every byte is accounted for (corrupt or inside an event), nearly all corrupt, and
    # the decoder never holds more than a bounded number of bytes however much garbage comes (linear time).
    garbage = np.random.default_rng(5).integers(0, 256, 200_000, dtype=np.uint8).tobytes()
    s = ProtocolSettings(event_format=fmt)
    dec = StreamDecoder(s)
    held = 0
    for i in range(0, len(garbage), 4096):
        dec.decode(garbage[i:i + 4096])
        held = max(held, dec.pending_bytes)
    dec.flush()
    assert dec.corrupt_bytes + dec.bytes_decoded == len(garbage)
    assert dec.corrupt_bytes > 0.9 * len(garbage)
    assert held <= RESYNC_WINDOW + 4096 + 16 * s.format.max_size


@pytest.mark.parametrize(("sent", "read"), [("E2", "E4"), ("E4", "E2"), ("E3", "E2"), ("E1", "E2")])
def test_wrong_format_is_counted_honestly(sent, read):
    data = encode_events(stream(), ProtocolSettings(event_format=sent))
    dec = StreamDecoder(ProtocolSettings(event_format=read))
    dec.decode(data, final=True)
    assert dec.corrupt_bytes + dec.bytes_decoded == len(data)
    assert dec.corrupt_bytes > 0.5 * len(data)


WRONG_SETTINGS = [
    ("E2", True, dict(event_format="E4"), False, True, "stream looks like E2, sync bit set"),
    ("E2", True, dict(sync_bit_set=False), True, False, "stream looks like E2, sync bit set"),
    ("E4", False, dict(event_format="E2", sync_bit_set=False), False, False, "stream looks like E4, sync bit clear"),
    ("E0", True, dict(event_format="E2"), False, True, "stream looks like E0, sync bit set"),
]


@pytest.mark.parametrize(("fmt", "sync", "given", "auto_f", "auto_s", "message"), WRONG_SETTINGS)
def test_explicit_setting_contradicting_the_stream_is_refused(fmt, sync, given, auto_f, auto_s, message):
    data = encode_events(stream(2000), ProtocolSettings(event_format=fmt, sync_bit_set=sync))
    with pytest.raises(ProtocolMismatchError, match=message):
        check_protocol(data, ProtocolSettings(**given), auto_format=auto_f, auto_sync=auto_s, name="left")


@pytest.mark.parametrize("fmt", list(FORMATS))
@pytest.mark.parametrize("sync", [True, False])
def test_auto_detects_every_format_and_sync_bit(fmt, sync):
    data = encode_events(stream(2000), ProtocolSettings(event_format=fmt, sync_bit_set=sync))
    settings, note = check_protocol(data, ProtocolSettings(), auto_format=True, auto_sync=True, name="left")
    assert (settings.event_format, settings.sync_bit_set) == (fmt, sync)
    assert note.startswith(f"{fmt}, sync bit {'set' if sync else 'clear'} (detected")


def test_auto_refuses_garbage_and_an_explicit_format_reports_it():
    garbage = np.random.default_rng(6).integers(0, 256, 70_000, dtype=np.uint8).tobytes()
    with pytest.raises(ProtocolMismatchError, match="do not look like eDVS events in any format"):
        check_protocol(garbage, ProtocolSettings(), auto_format=True, auto_sync=True, name="left")
    settings, note = check_protocol(garbage, ProtocolSettings(event_format="E3"), auto_format=False,
                                    auto_sync=False, name="left")
    assert settings.event_format == "E3" and "fits no format" in note


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(confirm=1), "confirm must be at least 2"),
    (dict(byte_rate=0), "byte_rate must be positive"),
    (dict(byte_rate=float("nan")), "byte_rate must be positive"),
])
def test_decoder_rejects_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        StreamDecoder(ProtocolSettings(), **kwargs)


@pytest.mark.parametrize("speed", [float("nan"), 0.0, -2.0, float("inf")])
def test_virtual_board_rejects_bad_speed(speed):
    with pytest.raises(ValueError, match="speed must be a positive finite number"):
        VirtualEDVS(stream(10), speed=speed)


def test_unknown_event_format_names_the_choices():
    with pytest.raises(ValueError, match="unknown eDVS event format 'E9'; choose one of: E0, E1, E2, E3, E4"):
        ProtocolSettings(event_format="E9")


@pytest.mark.parametrize("auto", [False, True])
def test_a_board_sending_200_kb_of_garbage_is_reported_honestly(auto):
    import time

    from cvstereo.sensors import EDVS

    garbage = np.random.default_rng(7).integers(0, 256, 200_000, dtype=np.uint8).tobytes()
    dev = VirtualEDVS(stream(0), baud=8_000_000)
    with dev as port, EDVS(port, auto_format=auto, auto_sync=auto) as cam:
        cam.configure()
        cam.start()
        dev.inject_garbage(garbage)
        deadline = time.monotonic() + 20
        while cam.bytes_received < len(garbage) and cam.error is None and time.monotonic() < deadline:
            time.sleep(0.05)
        cam.stop()
        s = cam.status()
    if auto:
        assert isinstance(cam.error, ProtocolMismatchError)
        assert "do not look like eDVS events in any format" in str(cam.error)
    else:
        assert s["bytes"] == len(garbage)
        assert s["corrupt_bytes"] + cam.decoder.bytes_decoded == len(garbage)
        assert s["corrupt_bytes"] > 0.99 * len(garbage)
        assert "fits no format" in s["protocol"]
