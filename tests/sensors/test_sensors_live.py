"""Virtual eDVS boards over pseudo-terminals: two sensors on one clock, faults, journal, record and live."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from typing import ClassVar

import numpy as np
import pytest

from cvstereo.errors import SensorError
from cvstereo.io.npz import read_recording_npz, write_recording_npz
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches
from cvstereo.model.recording import Recording
from cvstereo.sensors import EDVS, Journal, StereoEDVS, VirtualClock, VirtualEDVS, read_journal
from cvstereo.sensors.live import run_live
from tests._wrap_checks import assert_times_exact_or_flagged


def camera(rng, seconds, rate, shift=0):
    n = int(seconds * rate)
    t = np.sort(rng.integers(0, int(seconds * 1e6), n))
    x = np.clip(rng.integers(20, 100, n) + shift, 0, 127)
    return make_events(t, x, rng.integers(0, 128, n), rng.integers(0, 2, n))


def collect(rig, until_s):
    got = [[], []]
    t_end = time.monotonic() + until_s
    while time.monotonic() < t_end:
        for cam, chunk in rig.poll(0.05):
            got[cam].append(chunk.events)
    return [np.concatenate(g) if g else np.zeros(0) for g in got]


@pytest.mark.slow
def test_two_boards_at_4_mbaud_deliver_every_event_for_20_s(rng):
    # 20.5 s of stream in real time, 10k events/s per board in E2 (40 kB/s of the link's 400 kB/s), with
    # line noise injected into both streams now and then.
    left, right = camera(rng, 20.5, 10_000), camera(rng, 20.5, 10_000, -6)
    devs = [VirtualEDVS(left), VirtualEDVS(right)]
    with devs[0] as lp, devs[1] as rp, StereoEDVS(lp, rp) as rig:
        rig.start()
        got = [[], []]
        t_end = time.monotonic() + 60
        noise_at, bursts = time.monotonic() + 1, 0
        while time.monotonic() < t_end and not (all(d.done for d in devs) and all(c.silent for c in rig.cams)):
            if time.monotonic() > noise_at and bursts < 7:  # all while events still flow
                bursts += 1
                for d in devs:
                    d.inject_garbage(rng.integers(0, 128, 7, dtype=np.uint8).tobytes())
                noise_at += 2.5
            for cam, chunk in rig.poll(0.05):
                got[cam].append(chunk.events)
        rig.stop()
        status = rig.status()
        ambiguous = [c.decoder.ambiguous for c in rig.cams]
    for cam, sent, dev in ((0, left, devs[0]), (1, right, devs[1])):
        out = np.concatenate(got[cam])
        assert out.size == sent.size
        # Unwrapped, in order; exact unless the reader ran late by more than a wrap (a loaded machine), which
        # the decoder must then have counted.
        assert_times_exact_or_flagged(out["t"], sent["t"] - sent["t"][0] + dev.lead_us, ambiguous[cam])
        np.testing.assert_array_equal(out["x"], sent["x"])
        np.testing.assert_array_equal(out["p"], sent["p"])
        name = ("left", "right")[cam]
        assert status[name]["corrupt_bytes"] == dev.garbage_bytes == 7 * 7


def test_missing_port_is_one_error_naming_it():
    with pytest.raises(SensorError, match="/dev/does-not-exist"):
        EDVS("/dev/does-not-exist").open()
    proc = subprocess.run([sys.executable, "-m", "cvstereo", "record", "--left", "/dev/does-not-exist",
                           "--right", "/dev/also-missing", "-o", "never.npz"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "/dev/does-not-exist" in lines[0]


def test_disconnect_is_reported(rng):
    dev = VirtualEDVS(camera(rng, 3, 2000))
    with dev as port, EDVS(port, name="left") as cam:
        cam.configure()
        cam.start()
        time.sleep(0.5)
        dev.disconnect()
        t_end = time.monotonic() + 10
        while cam.running and time.monotonic() < t_end:
            time.sleep(0.05)
        assert cam.error is not None and port in str(cam.error)
        cam.stop()


def test_silent_sensor_is_reported_while_the_other_records(rng):
    left, right = camera(rng, 6, 3000), camera(rng, 6, 3000)
    devs = [VirtualEDVS(left), VirtualEDVS(right)]
    with devs[0] as lp, devs[1] as rp, StereoEDVS(lp, rp) as rig:
        rig.start()
        collect(rig, 1.0)
        devs[1].stall(float("inf"))
        t_stall = time.monotonic()
        reported = None
        left_after = 0
        while time.monotonic() - t_stall < 6:
            for cam, chunk in rig.poll(0.05):
                left_after += chunk.events.size if cam == 0 else 0
            if reported is None and rig.cams[1].silent:
                reported = time.monotonic() - t_stall
        rig.stop()
    assert reported is not None and 0.8 < reported < 3.0
    assert not rig.cams[0].silent or left_after > 0
    assert left_after > 1000


def test_journal_turns_into_a_recording_even_when_cut_short(tmp_path, rng):
    ev = camera(rng, 1, 1000)
    path = tmp_path / "j.journal"
    with Journal(path, {"scene": "test"}) as j:
        j.append(0, ev[:500])
        j.append(1, ev[:300])
        j.append(0, ev[500:])
    rec, lost = read_journal(path)
    np.testing.assert_array_equal(rec.left, ev)
    assert rec.right.size == 300 and lost == 0 and rec.meta["scene"] == "test"
    with open(path, "ab") as fh:  # a crash in the middle of a record
        fh.write(b"\x01\x10\x00\x00\x00" + b"\x00" * 20)
    rec, lost = read_journal(path)
    assert rec.left.size == ev.size and lost == 25


def test_sigterm_during_record_leaves_a_valid_recording(tmp_path, rng):
    src = tmp_path / "src.npz"
    write_recording_npz(src, Recording(camera(rng, 30, 2000), camera(rng, 30, 2000)))
    out = tmp_path / "out.npz"
    proc = subprocess.Popen([sys.executable, "-m", "cvstereo", "record", "--simulate", str(src), "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Signal only once recording has begun (the journal has data): a loaded machine may take seconds to
    # start Python, and SIGTERM before the handler is installed would test nothing.
    journal = tmp_path / "out.npz.journal"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (journal.exists() and journal.stat().st_size > 20_000):
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    rec = read_recording_npz(out)
    assert rec.left.size > 1000 and rec.right.size > 1000
    assert not os.path.exists(str(out) + ".journal")  # removed once everything is in the recording


class _MeanX(StreamMatcher):
    """Test-only matcher: one match per packet, disparity = mean x(left) - mean x(right)."""

    from dataclasses import dataclass as _dc

    @_dc(frozen=True)
    class Params:
        pass

    variants: ClassVar[dict] = {"default": {}}
    method = "mean-x"

    def _feed(self, left, right):
        if not (left.size and right.size):
            return make_matches([], [], [], [], [], [])
        d = float(left["x"].mean() - right["x"].mean())
        return make_matches([int(left["t"][-1])], [0], [0], [1], [0], [d])


def test_live_prints_disparity_and_lag(rng):
    left, right = camera(rng, 3, 5000, 0), camera(rng, 3, 5000, -8)
    out = io.StringIO()
    with VirtualEDVS(left) as lp, VirtualEDVS(right) as rp, StereoEDVS(lp, rp) as rig:
        rig.start()
        stats = run_live(rig, _MeanX(), seconds=2.5, out=out)
        rig.stop()
    lines = out.getvalue().splitlines()
    assert stats.updates >= 10 and stats.matches > 0
    assert not any("nan" in line for line in lines)
    med = [float(line.split()[1]) for line in lines if line.split()[1] != "n/a"]
    assert med and abs(np.median(med) - 8) < 1.5
    assert all("lag" in line for line in lines)


def test_slave_board_started_before_the_master_clock_runs_still_counts_on_it(rng):
    # On a loaded machine the master's thread may handle `!ETM+` after the slave handled `E+`: the slave must
    # still stamp on the master's clock (real slaves follow the master's sync line), not on its own.
    # Driven command by command, without threads, so the order is the one under test.
    ev = camera(rng, 0.2, 1000)
    clock = VirtualClock()
    master, slave = VirtualEDVS(ev, clock=clock, time_origin_us=0), VirtualEDVS(ev, clock=clock, time_origin_us=0)
    c = master.settings.commands
    master._handle(c.master_arm)
    slave._handle(c.slave)
    slave._handle(c.start)
    assert slave._due_events(time.monotonic() + 0.1, 1 << 20) == b""  # nothing before the master's clock runs
    time.sleep(0.01)
    master._handle(c.master_run)
    master._handle(c.start)
    assert slave._due_events(time.monotonic() + 0.1, 1 << 20)
    assert master._due_events(time.monotonic() + 0.1, 1 << 20)
    assert slave.lead_us == master.lead_us  # one clock and one scene start, whatever the order


def test_live_simulate_matches_every_event_and_prints_its_lag(tmp_path, rng, capsys):
    # To the recording's end (no --seconds): every event is fed before `live` ends, none dropped, and the summary
    # gives the lag percentiles over the packets it fed.
    import json

    from cvstereo.cli import main

    left = camera(rng, 0.8, 4000)
    right = left.copy()
    right["x"] = np.clip(right["x"].astype(int) - 6, 0, 127)
    src = tmp_path / "src.npz"
    write_recording_npz(src, Recording(left, right))
    assert main(["live", "--simulate", str(src), "-m", "frame"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    report = json.loads(err[-1])
    summary, status = report["summary"], report["status"]
    assert (summary["events_left"], summary["events_right"]) == (left.size, right.size)
    assert status["late_events"] == 0 and status["late_events_by_camera"] == [0, 0]
    lag = summary["lag_per_packet"]
    assert lag["packets"] > 10 and 0 <= lag["p50_ms"] <= lag["p90_ms"] <= lag["p99_ms"] <= lag["max_ms"]
    assert any(line.startswith(f"lag per packet (delivery -> matches out), all {lag['packets']} packets")
               for line in err)
    assert "0 late events dropped" in err[-3]


def test_live_runs_a_matcher_that_cannot_be_deep_copied(tmp_path, rng, capsys):
    """OpenCV's matcher objects cannot be deep-copied: its kernels are prepared through a rebuilt copy, and
    ``live -m sgbm`` matches every event (8bbe163's own warm-up copy ended in a TypeError traceback)."""
    import json

    from cvstereo.cli import main

    left = camera(rng, 0.3, 4000)
    right = left.copy()
    right["x"] = np.clip(right["x"].astype(int) - 6, 0, 127)
    write_recording_npz(tmp_path / "src.npz", Recording(left, right))
    assert main(["live", "--simulate", str(tmp_path / "src.npz"), "-m", "sgbm"]) == 0
    err = capsys.readouterr().err
    summary = json.loads(err.strip().splitlines()[-1])["summary"]
    assert "Traceback" not in err and (summary["events_left"], summary["events_right"]) == (left.size, right.size)
    assert summary["matches"] > 0


class _ScriptedRig:
    """A rig double: hands out given packets (None: a wait that timed out), then nothing."""

    class _Side:
        last_arrival, min_offset = None, None

    packet_arrival_us = None

    def __init__(self, packets):
        self._packets = list(packets)
        self.sides = (self._Side(), self._Side())

    def packet(self, timeout_s):
        return self._packets.pop(0) if self._packets else None

    def done(self):
        return not self._packets


class _CountingMeanX(_MeanX):
    """_MeanX counting its feed and flush calls and the matches it returned."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.feeds, self.flushes, self.returned = 0, 0, 0

    def feed(self, left, right, *, until=None):
        self.feeds += 1
        found = super().feed(left, right, until=until)
        self.returned += found.size
        return found

    def flush(self):
        self.flushes += 1
        found = super().flush()
        self.returned += found.size
        return found


def test_live_feeds_through_the_library_feed_loop(monkeypatch):
    # Three packets with events on both sides (one match each by _MeanX's rule), one timed-out wait and one
    # packet with only left events (no match): run_live must hand every packet to cvstereo.run.run_iter, which
    # feeds each once and flushes once, and count what it yields.
    import cvstereo.run
    from cvstereo.model.events import StereoPacket

    def packet(t0, n_right):
        left = make_events(np.arange(t0, t0 + 4), [10, 20, 30, 40], [1, 1, 1, 1], [1, 1, 1, 1])
        right = make_events(np.arange(t0, t0 + n_right), [5, 15, 25, 35][:n_right], [1] * n_right, [1] * n_right)
        return StereoPacket(left, right, t0 + 1000)

    packets = [packet(0, 4), None, packet(1000, 0), packet(2000, 4), packet(3000, 4)]
    calls = []
    original = cvstereo.run.run_iter

    def spy(matcher, source, **kwargs):
        calls.append(matcher)
        yield from original(matcher, source, **kwargs)

    monkeypatch.setattr(cvstereo.run, "run_iter", spy)
    matcher = _CountingMeanX()
    rig = _ScriptedRig(packets)
    stats = run_live(rig, matcher, done=rig.done, out=io.StringIO(), update_s=0.0)
    assert calls == [matcher]
    assert (matcher.feeds, matcher.flushes) == (4, 1)
    assert stats.matches == matcher.returned == 3  # disparity 5 px each: 25 - 20
    assert stats.events == [16, 12]
    assert stats.updates == 4  # a line after every packet fed (update_s=0)
