"""Hostile DV live input (issue 26 item 3): ``live --dv`` and ``record --dv`` against streams that refuse, are
not event streams, disagree, stop, send events out of their sensor, or against a missing dv-processing.

Each refusal is one line ``cvstereo CMD: error: ...`` naming the address, exit 1, no output left; a stream that
stops early ends the run with what it sent (checked against the file). The writers are dv-processing's own
(``tests/_dv_serve.py``). On 8bbe163 there is no ``--dv`` option: every case fails there as a usage error
(exit 2, MESSAGE) or, for the stopping stream, as SILENT (no run at all).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cvstereo.io.npz import read_recording_npz, write_recording_npz
from cvstereo.model.recording import Recording
from tests._dv_serve import free_port, served
from tests._hostile import case, check_case, run_cli

pytest.importorskip("dv_processing")

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def work(tmp_path, monkeypatch, rng):
    """A folder with a short stereo recording (128x128) and a shorter one (its left camera stops early)."""
    monkeypatch.chdir(tmp_path)

    def cam(n, seconds):
        t = np.sort(rng.integers(0, int(seconds * 1e6), n))
        ev = np.zeros(n, [("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
        ev["t"], ev["x"], ev["y"], ev["p"] = t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
        return ev

    write_recording_npz(tmp_path / "rec.npz", Recording(cam(20_000, 0.8), cam(20_000, 0.8)))
    return tmp_path


@pytest.mark.parametrize("cmd", ["live", "record -o out.npz"])
def test_refused_host_is_one_line_naming_it(work, capsys, cmd):
    left, right = f"tcp://127.0.0.1:{free_port()}", f"tcp://127.0.0.1:{free_port()}"
    check_case(case(f"{cmd} --dv {left} {right}", 1, err=(left, "cannot open", "refused"),
                    absent=("out.npz", "out.npz.journal")), work, capsys)


def test_unknown_host_is_one_line_naming_it(work, capsys):
    check_case(case("live --dv tcp://no-such-host.invalid:7777 tcp://127.0.0.1:7778", 1,
                    err=("tcp://no-such-host.invalid:7777", "unknown host")), work, capsys)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1", "tcp://127.0.0.1:0", "tcp://:7777", "tcp://h:port"])
def test_malformed_address_is_one_line_naming_the_option(work, capsys, address):
    check_case(case(f"live --dv {address} tcp://127.0.0.1:7777", 1, err=("--dv", address, "tcp://HOST:PORT")),
               work, capsys)


def test_dv_with_serial_ports_is_refused(work, capsys):
    check_case(case("live --dv tcp://127.0.0.1:1 tcp://127.0.0.1:2 --left /dev/null", 1, err=("--dv", "--left")),
               work, capsys)


@pytest.mark.parametrize("cmd", ["live", "record -o out.npz"])
def test_a_frame_stream_is_not_events(work, capsys, cmd):
    with served(work / "rec.npz", extra=(("--stream", "frames"), ())) as (left, right):
        check_case(case(f"{cmd} --dv {left} {right}", 1, err=(left, "carries no events", "frames"),
                        absent=("out.npz", "out.npz.journal")), work, capsys)


@pytest.mark.parametrize("cmd", ["live", "record -o out.npz"])
def test_two_resolutions_are_refused(work, capsys, cmd):
    with served(work / "rec.npz", extra=((), ("--resolution", "346", "260"))) as (left, right):
        check_case(case(f"{cmd} --dv {left} {right}", 1, err=(left, right, "128x128", "346x260"),
                        absent=("out.npz", "out.npz.journal")), work, capsys)


def test_dv_processing_missing_names_the_extra(work, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dv_processing", None)  # import dv_processing raises ImportError
    check_case(case("live --dv tcp://127.0.0.1:1 tcp://127.0.0.1:2", 1, err=("dv-processing", "cvstereo[dv]")),
               work, capsys)


def test_a_stream_that_stops_ends_the_run_with_what_it_sent(work, capsys):
    # The left writer serves the first 0.2 s only, then leaves; the right goes on to 0.8 s. The record keeps
    # every event of both (the left's stop is a warning, the right is not held back), and ends on its own.
    rec = read_recording_npz(work / "rec.npz")
    short = rec.left[rec.left["t"] < 200_000]
    write_recording_npz(work / "short.npz", Recording(short, short))
    with served(work / "short.npz", cameras=("left",), extra=((),)) as (left,), \
            served(work / "rec.npz", cameras=("right",), extra=((),)) as (right,):
        _out, err = check_case(case(f"record --dv {left} {right} -o got.npz", 0, writes=("got.npz",)), work, capsys)
    got = read_recording_npz(work / "got.npz")
    assert got.left.size == short.size and got.right.size == rec.right.size, \
        f"DATALOSS: {got.left.size}/{short.size} left, {got.right.size}/{rec.right.size} right"
    assert f"{left} ended" in err, f"MESSAGE: the stop is not reported: {err!r}"


def test_events_outside_the_stated_resolution_stop_that_camera_with_one_line(work, capsys):
    # The stream states 64x64 but sends 128x128 events: the matcher would misplace them. Both streams state 64x64
    # (one resolution), the first event out of it stops each camera, named, and nothing wrong is recorded.
    size = ("--resolution", "64", "64")
    with served(work / "rec.npz", extra=(size, size)) as (left, right):
        _code, escaped = run_cli(["record", "--dv", left, right, "-o", "got.npz"])
    err = capsys.readouterr().err
    assert not escaped, escaped
    assert "outside its 64x64 pixels" in err, f"SILENT: events out of the stream's resolution taken: {err!r}"
    if (work / "got.npz").exists():
        got = read_recording_npz(work / "got.npz")
        for ev in (got.left, got.right):
            assert ((ev["x"] < 64) & (ev["y"] < 64)).all(), "SILENT: an event outside 64x64 recorded"
