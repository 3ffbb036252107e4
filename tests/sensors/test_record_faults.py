"""Faults around `cvstereo record`: kill -9, SIGTERM, --seconds, unplugging, long pauses, journals.

Every check compares what was recorded with what the virtual boards were given: the recording must hold
exactly the events sent (a prefix of the source after a kill), on one clock, with exact times.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from cvstereo.cli import main
from cvstereo.io.npz import read_recording_npz, write_recording_npz
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.sensors import EDVS, StereoEDVS, VirtualEDVS
from cvstereo.sensors.detect import ProtocolMismatchError
from cvstereo.sensors.journal import read_journal
from cvstereo.sensors.protocol import ProtocolSettings
from cvstereo.sensors.virtual import VirtualClock
from tests._wrap_checks import WRAP, assert_times_exact_or_flagged


def camera(rng, seconds, rate, start_us=0, shift=0):
    n = int(seconds * rate)
    t = np.sort(rng.integers(start_us, start_us + int(seconds * 1e6), n))
    x = np.clip(rng.integers(20, 100, n) + shift, 0, 127)
    return make_events(t, x, rng.integers(0, 128, n), rng.integers(0, 2, n))


@pytest.fixture
def source(tmp_path, rng):
    """A 3 s recording whose right camera starts 0.5 s after the left (a disparity of 6 px)."""
    path = tmp_path / "src.npz"
    left = camera(rng, 3.0, 3000, 1_000_000)
    right = camera(rng, 2.5, 3000, 1_500_000, shift=-6)
    write_recording_npz(path, Recording(left, right))
    return path, Recording(left, right)


def assert_same_stream(got, want, shift):
    """``got`` is ``want`` (or its prefix when ``prefix``) with every time moved by ``shift``."""
    assert got.size and got.size <= want.size
    np.testing.assert_array_equal(got["t"], want["t"][:got.size] + shift)
    for f in ("x", "y", "p"):
        np.testing.assert_array_equal(got[f], want[f][:got.size])


def assert_one_clock(rec, src, *, complete, ambiguous=0):
    """Both cameras hold the source's events moved by one common shift (inter-camera timing kept).

    ``ambiguous``: timestamp wraps record reported it could not decide (the host read late, a loaded
    machine); then times may be off by whole wraps, and only by those.
    """
    shift = int(rec.left["t"][0] - src.left["t"][0])
    if ambiguous:
        for got, want in ((rec.left, src.left), (rec.right, src.right)):
            assert got.size and got.size <= want.size
            err = got["t"] - (want["t"][:got.size] + shift)
            np.testing.assert_array_equal(err % WRAP, 0)
            for f in ("x", "y", "p"):
                np.testing.assert_array_equal(got[f], want[f][:got.size])
    else:
        assert_same_stream(rec.left, src.left, shift)
        assert_same_stream(rec.right, src.right, shift)  # same shift: the right camera still starts 0.5 s later
    if complete:
        assert rec.left.size == src.left.size and rec.right.size == src.right.size


def sent_counts(stderr):
    """(recorded, sent) per camera from record's report lines."""
    got = re.findall(r"^(left|right): (\d+) events \(the virtual board sent (\d+)\)", stderr, re.M)
    return {cam: (int(a), int(b)) for cam, a, b in got}


def ambiguous_wraps(stderr):
    """Timestamp wraps record reported as ambiguous, both cameras."""
    return sum(int(n) for n in re.findall(r"^(?:left|right): .*?, (\d+) ambiguous timestamp wraps", stderr, re.M))


def test_paced_board_with_long_pauses_gives_exact_times(rng):
    # Bursts of events with pauses of 70-300 ms in between, paced in real time: a 16-bit timestamp wraps
    # every 65.536 ms, so each pause hides one to four wraps that only the arrival times can tell.
    pauses = [70_000, 300_000, 131_072, 95_000, 200_000, 65_600, 150_000]
    t, now = [], 0
    for pause in [0, *pauses]:
        now += pause
        t.extend(now + 1000 * np.arange(10))
        now = t[-1]
    t = np.array(t)
    left = make_events(t, rng.integers(0, 128, t.size), rng.integers(0, 128, t.size), rng.integers(0, 2, t.size))
    right = left.copy()
    right["t"] += 20_000  # the right camera sees every burst 20 ms later
    clock = VirtualClock()
    devs = [VirtualEDVS(ev, clock=clock, time_origin_us=0) for ev in (left, right)]
    with devs[0] as lp, devs[1] as rp, StereoEDVS(lp, rp) as rig:
        rig.start()
        got = [[], []]
        t_end = time.monotonic() + 10
        while time.monotonic() < t_end and not (all(d.done for d in devs) and all(c.silent for c in rig.cams)):
            for cam, chunk in rig.poll(0.05):
                got[cam].append(chunk.events)
        rig.stop()
        for cam, chunk in rig.poll(0):
            got[cam].append(chunk.events)
        wraps = [c.decoder.hidden_wraps for c in rig.cams]
        ambiguous = [c.decoder.ambiguous for c in rig.cams]
    assert devs[0].lead_us == devs[1].lead_us  # one clock
    for cam, sent in ((0, left), (1, right)):
        out = np.concatenate(got[cam])
        assert out.size == sent.size
        # Every time exact on the shared clock, unless the reader ran late by more than a wrap at a pause (a
        # loaded machine): the decoder must have counted that gap, and times after it are off by whole wraps.
        assert_times_exact_or_flagged(out["t"], sent["t"] + devs[cam].lead_us, ambiguous[cam])
    # Sanity of the expectation itself: without the arrival times these pauses would have lost wraps.
    naive = sum(p // WRAP for p in pauses)
    assert naive >= 9 and (wraps[0] >= naive - 2 or ambiguous[0])


def test_seconds_keeps_every_event_and_the_inter_camera_timing(tmp_path, source, capsys):
    src_path, src = source
    out = tmp_path / "out.npz"
    assert main(["record", "--simulate", str(src_path), "-o", str(out), "--seconds", "1.2"]) == 0
    err = capsys.readouterr().err
    counts = sent_counts(err)
    rec = read_recording_npz(out)
    assert counts["left"] == (rec.left.size, rec.left.size) and counts["right"] == (rec.right.size, rec.right.size)
    assert rec.left.size > 1000 and rec.right.size > 500
    assert_one_clock(rec, src, complete=False)
    assert "E2, sync bit set (detected" in err
    assert not (tmp_path / "out.npz.journal").exists()  # removed after a successful write


def test_rerecording_a_whole_simulated_recording_keeps_its_timing(tmp_path, rng, capsys):
    src = Recording(camera(rng, 0.8, 2000, 0), camera(rng, 0.5, 2000, 500_000, shift=-6))
    write_recording_npz(tmp_path / "s.npz", src)
    assert main(["record", "--simulate", str(tmp_path / "s.npz"), "-o", str(tmp_path / "o.npz"),
                 "--seconds", "20"]) == 0
    rec = read_recording_npz(tmp_path / "o.npz")
    assert_one_clock(rec, src, complete=True)
    # The same first-event difference, hence the same disparities for any matcher.
    assert rec.right["t"][0] - rec.left["t"][0] == src.right["t"][0] - src.left["t"][0]


def _start_record(src_path, out, *extra):
    return subprocess.Popen([sys.executable, "-m", "cvstereo", "record", "--simulate", str(src_path), "-o",
                             str(out), *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_journal(path, size, proc):
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None and not (path.exists() and path.stat().st_size > size):
        time.sleep(0.05)
    assert proc.poll() is None, proc.communicate()[1]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_keeps_every_event_received(tmp_path, source, sig):
    src_path, src = source
    out = tmp_path / "out.npz"
    proc = _start_record(src_path, out)
    _wait_for_journal(tmp_path / "out.npz.journal", 30_000, proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    rec = read_recording_npz(out)
    counts = sent_counts(err)
    assert counts["left"] == (rec.left.size, rec.left.size), err
    assert counts["right"] == (rec.right.size, rec.right.size), err
    assert_one_clock(rec, src, complete=False, ambiguous=ambiguous_wraps(err))


def test_kill_9_then_from_journal_recovers_an_exact_prefix(tmp_path, source, capsys):
    src_path, src = source
    out = tmp_path / "out.npz"
    journal = tmp_path / "out.npz.journal"
    proc = _start_record(src_path, out)
    _wait_for_journal(journal, 40_000, proc)
    proc.kill()
    proc.communicate(timeout=60)
    before = journal.read_bytes()
    # The next run must not wipe the crash journal.
    assert main(["record", "--simulate", str(src_path), "-o", str(out), "--seconds", "1"]) == 1
    err = capsys.readouterr().err
    assert f"journal {journal} exists: recover it with --from-journal or delete it" in err
    assert journal.read_bytes() == before
    assert main(["record", "--from-journal", str(journal), "-o", str(out)]) == 0
    rec = read_recording_npz(out)
    jrec, _ = read_journal(journal)
    assert rec.left.size == jrec.left.size > 0 and rec.right.size == jrec.right.size
    assert_one_clock(rec, src, complete=False)
    assert journal.read_bytes() == before  # an input: kept


def test_unplugging_a_board_loses_none_of_the_events_it_sent(rng):
    ev = camera(rng, 0.5, 20_000)  # 10,000 events
    dev = VirtualEDVS(ev)
    got = []
    with dev as port, EDVS(port, name="left") as cam:
        cam.configure()
        cam.start()
        deadline = time.monotonic() + 20
        while not dev.done and time.monotonic() < deadline:
            while not cam.queue.empty():
                got.append(cam.queue.get().events)
            time.sleep(0.01)
        time.sleep(0.2)  # the last bytes reach the host before the cable goes
        dev.disconnect()
        while cam.running and time.monotonic() < deadline:
            time.sleep(0.02)
        cam.stop()
        while not cam.queue.empty():
            got.append(cam.queue.get().events)
    out = np.concatenate(got)
    assert cam.error is not None and "disconnected" in str(cam.error)
    assert out.size == ev.size == dev.sent_events
    np.testing.assert_array_equal(np.diff(out["t"]), np.diff(ev["t"]))


@pytest.mark.parametrize("auto", [False, True])
def test_a_board_with_legacy_numbering_is_detected_or_refused(rng, auto):
    # Asked for "!E2", a board with the 2011 numbering sends 24-bit timestamps (E3).
    left, right = camera(rng, 0.6, 4000), camera(rng, 0.6, 4000)
    clock = VirtualClock()
    devs = [VirtualEDVS(ev, clock=clock, settings=ProtocolSettings(numbering="legacy")) for ev in (left, right)]
    with devs[0] as lp, devs[1] as rp, StereoEDVS(lp, rp, auto_format=auto) as rig:
        rig.start()
        got = [[], []]
        t_end = time.monotonic() + 10
        while time.monotonic() < t_end and not (all(d.done for d in devs) and all(c.silent for c in rig.cams)):
            for cam, chunk in rig.poll(0.05):
                got[cam].append(chunk.events)
            if any(c.error for c in rig.cams):
                break
        rig.stop()
        for cam, chunk in rig.poll(0):
            got[cam].append(chunk.events)
    assert devs[0].format == "E3"
    if auto:
        assert all(c.error is None for c in rig.cams)
        assert rig.cams[0].protocol.startswith("E3, sync bit set (detected")
        for cam, sent in ((0, left), (1, right)):
            np.testing.assert_array_equal(np.concatenate(got[cam])["t"], sent["t"] - sent["t"][0] + devs[0].lead_us)
    else:
        for c in rig.cams:
            assert isinstance(c.error, ProtocolMismatchError)
            assert "stream looks like E3, sync bit set" in str(c.error) and "--event-format E2" in str(c.error)
        assert sum(g.size for gs in got for g in gs) == 0  # nothing mis-decoded slipped out
