"""The stereo merge's watermark (sensors/stereo.py) and lag meter (sensors/lag.py), driven by a fake clock and
scripted reader deliveries: no ports, no threads, no sleeps.

The script: each camera has an event every 250 us; its reader delivers the events of each millisecond of device
time as one chunk, arriving D = 5 ms after the millisecond ends (the clock offset plus the link), unless a test
delays it. The consumer asks for a packet every millisecond of host time. So a timely chunk's
``arrival - last event time`` is 1000 - 750 + 5000 = 5250 us: each camera's clock offset as the merge estimates
it, and device time T is host time T + 5250 for a camera that delivers on time.
"""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.sensors.edvs import Chunk
from cvstereo.sensors.lag import LagMeter
from cvstereo.sensors.stereo import SILENT_WAIT_US, StereoEDVS, StereoSettings

D = 5_000
STEP = 250
OFFSET = 1_000 - 750 + D  # arrival - last event time of a timely chunk


def camera(ms: int, x: int) -> np.ndarray:
    t = np.arange(0, ms * 1_000, STEP)
    return make_events(t, np.full(t.size, x), (t // STEP) % 128, (t // STEP) % 2)


def unopened_rig(**settings) -> StereoEDVS:
    """A rig whose readers never run: the test puts their chunks into the queues."""
    return StereoEDVS("/dev/test-left", "/dev/test-right", stereo=StereoSettings(**settings))


def deliveries(events: np.ndarray, cam: int, arrival_of=lambda k: (k + 1) * 1_000 + D):
    """(arrival, cam, chunk) for each millisecond of device time; ``arrival_of(k)`` for millisecond k."""
    out = []
    for k in range(int(events["t"][-1]) // 1_000 + 1):
        chunk = events[(events["t"] >= k * 1_000) & (events["t"] < (k + 1) * 1_000)]
        if chunk.size:
            out.append((arrival_of(k), cam, chunk))
    return out


def drive(rig: StereoEDVS, script, until_host_us: int, *, silent_after: int | None = None, ticks=None,
          each_tick=None):
    """Deliver ``script`` on time and ask for a packet every host millisecond (or at ``ticks``); ``silent_after``:
    from that host time on both readers report their cameras silent; ``each_tick(now)`` runs first at each tick.
    Return the packets and their host times."""
    script = sorted(script, key=lambda d: (d[0], d[1]))
    packets, i = [], 0
    for now in (range(1_000, until_host_us + 1, 1_000) if ticks is None else ticks):
        if each_tick is not None:
            each_tick(now)
        while i < len(script) and script[i][0] <= now:
            arrival, cam, chunk = script[i]
            rig.cams[cam].queue.put(Chunk(chunk, arrival))
            i += 1
        if silent_after is not None and now >= silent_after:
            for c in rig.cams:
                c.silent = True
        pkt = rig.packet(0, now_us=now)
        if pkt is not None:
            packets.append((now, pkt))
    return packets


def joined(packets, side: str) -> np.ndarray:
    return np.concatenate([getattr(p, side) for _, p in packets])


def test_a_reader_late_by_less_than_the_bound_loses_nothing():
    # The right reader delivers nothing from host 200 ms to 290 ms (a loaded machine), then all it read. The
    # watermark waits for it: nothing is late (a fixed 30 ms allowance behind host time dropped ~60 ms of it).
    left, right = camera(400, 40), camera(400, 30)
    stalled = deliveries(right, 1, lambda k: max((k + 1) * 1_000 + D, 290_000) if 195 <= k < 285 else
                         (k + 1) * 1_000 + D)
    rig = unopened_rig()
    packets = drive(rig, deliveries(left, 0) + stalled, 600_000, silent_after=500_000)
    assert rig.late_events == 0 and not rig.pending
    np.testing.assert_array_equal(joined(packets, "left"), left)
    np.testing.assert_array_equal(joined(packets, "right"), right)
    during = [p.until for now, p in packets if 200_000 <= now < 290_000]
    # Held at the right camera's last delivered event (device 194.75 ms) while it was late.
    assert max(during) == 194_750
    untils = [p.until for _, p in packets]
    assert untils == sorted(untils)


def test_a_silent_camera_holds_the_other_back_only_for_the_bound():
    left, right = camera(500, 40), camera(200, 30)  # the right camera sends nothing after device 200 ms
    rig = unopened_rig()
    packets = dict(drive(rig, deliveries(left, 0) + deliveries(right, 1), 500_000))
    # Its last chunk (device 199-200 ms, last event 199.75 ms) arrived at host 205 ms. Up to 100 ms later the
    # left camera waits for it ...
    assert packets[305_000].until == 199_750
    # ... after that the watermark follows its device time 100 ms ago: host 400 ms - 100 ms - 5.25 ms offset.
    assert packets[400_000].until == 294_750
    assert rig.waited_out > 0 and rig.late_events == 0
    np.testing.assert_array_equal(joined(packets.items(), "right"), right)
    by_400 = [(now, p) for now, p in packets.items() if now <= 400_000]
    assert joined(by_400, "left")[-1]["t"] == 294_750 - STEP  # every left event before it is out by then


def test_events_delivered_behind_the_watermark_after_the_bound_are_dropped_and_counted():
    # The right reader stalls 150 ms (host 205 -> 354.5 ms), longer than the 100 ms bound: the watermark went on.
    left, right = camera(400, 40), camera(400, 30)
    late = deliveries(right, 1, lambda k: 354_500 if 200 <= k < 349 else (k + 1) * 1_000 + D)
    rig = unopened_rig()
    packets = drive(rig, deliveries(left, 0) + late, 600_000, silent_after=500_000)
    # At host 354 ms (the last look before the burst) the watermark stood at the right camera's device time
    # 100 ms before: 354 - 100 - 5.25 = 248.75 ms. The burst's events from device 200 ms up to there, one per
    # 250 us, are dropped: (248_750 - 200_000) / 250 = 195, all of the right camera.
    assert rig.late_events == 195
    assert rig.status()["late_events_by_camera"] == [0, 195]
    kept = joined(packets, "right")
    assert kept.size == right.size - 195
    assert not np.any((kept["t"] >= 200_000) & (kept["t"] < 248_750))
    np.testing.assert_array_equal(joined(packets, "left"), left)


def test_a_stall_of_the_whole_process_is_no_evidence_of_silence():
    # Neither reader delivers and the consumer does not look (the matcher held the process) for 150 ms; then both
    # deliver their backlog. The consumer's own gap proves nothing: nothing is dropped.
    left, right = camera(400, 40), camera(400, 30)
    backlog = lambda k: 360_000 if 200 <= k < 354 else (k + 1) * 1_000 + D  # noqa: E731
    rig = unopened_rig()
    packets = drive(rig, deliveries(left, 0, backlog) + deliveries(right, 1, backlog), 0, silent_after=500_000,
                    ticks=[*range(1_000, 206_000, 1_000), 358_000, *range(361_000, 600_001, 1_000)])
    assert rig.late_events == 0
    np.testing.assert_array_equal(joined(packets, "left"), left)
    np.testing.assert_array_equal(joined(packets, "right"), right)


def test_when_both_go_quiet_the_held_events_come_out_after_the_bound():
    left, right = camera(300, 40), camera(250, 30)  # right ends 50 ms earlier; both then send nothing
    rig = unopened_rig()
    packets = dict(drive(rig, deliveries(left, 0) + deliveries(right, 1), 420_000))
    np.testing.assert_array_equal(joined(packets.items(), "left"), left)
    assert not rig.pending and rig.late_events == 0
    # The left camera's last event (device 299.75 ms) arrived at host 305 ms, and was out by 305 + 100 + 1 ms.
    out_at = min(now for now, p in packets.items() if p.left.size and p.left["t"][-1] == 299_750)
    assert out_at == 406_000


def test_packet_arrival_is_the_latest_arrival_among_its_events():
    rig = unopened_rig()
    ev = camera(10, 40)
    rig.cams[0].queue.put(Chunk(ev[:8], 7_000))     # device 0-1.75 ms
    rig.cams[0].queue.put(Chunk(ev[8:20], 8_500))   # device 2-4.75 ms
    rig.cams[1].queue.put(Chunk(ev[:12], 8_000))    # device 0-2.75 ms
    pkt = rig.packet(0, now_us=9_000)
    # Watermark: the right camera's last event, 2.75 ms: left events of both chunks (7 and 8.5 ms), right ones
    # of the 8 ms chunk.
    assert pkt.until == 2_750 and pkt.left.size == 11 and pkt.right.size == 11
    assert rig.packet_arrival_us == 8_500
    rig.cams[1].queue.put(Chunk(ev[12:14], 9_500))  # device 3-3.25 ms
    pkt = rig.packet(0, now_us=9_500)
    # Up to 3.25 ms: left 2.75 and 3 ms (8.5 ms chunk), right 2.75 (8 ms chunk) and 3 ms (9.5 ms chunk).
    assert pkt.until == 3_250 and pkt.left.size == 2 and pkt.right.size == 2
    assert rig.packet_arrival_us == 9_500
    assert rig.packet(0, now_us=9_600).left.size == 0 and rig.packet_arrival_us is None


def test_the_merged_stream_matches_as_the_recording_read_from_file(rng):
    from cvstereo.run import match

    n = 12_000
    left = make_events(np.sort(rng.integers(0, 600_000, n)), rng.integers(10, 118, n), rng.integers(0, 128, n),
                       rng.integers(0, 2, n))
    right = left.copy()
    right["x"] -= 8  # a scene 8 px of disparity away
    rec = Recording(left, right)
    script = []
    for cam, ev in enumerate((rec.left, rec.right)):
        # Chunks of 1-400 events, each arriving 5 ms after its last event plus up to 60 ms of reader delay, in
        # order per camera (a reader delivers in order).
        cuts = np.cumsum(rng.integers(1, 400, n))
        cuts = cuts[cuts < n]
        arrival = 0
        for chunk in np.split(ev, cuts):
            arrival = max(arrival, int(chunk["t"][-1]) + D + int(rng.integers(0, 60_000)))
            script.append((arrival, cam, chunk))
    rig = unopened_rig()
    packets = [p for _, p in drive(rig, script, 900_000, silent_after=800_000)]
    assert rig.late_events == 0 and not rig.pending
    np.testing.assert_array_equal(np.concatenate([p.left for p in packets]), rec.left)
    np.testing.assert_array_equal(np.concatenate([p.right for p in packets]), rec.right)
    from cvstereo.matchers.registry import create_matcher

    live = create_matcher("frame")
    got = [live.feed(p.left, p.right, until=p.until) for p in packets] + [live.flush()]
    from_file = match(rec, method="frame", rig_check=False).matches  # the events as fed
    np.testing.assert_array_equal(np.concatenate(got), from_file)
    assert from_file.size > 100


@pytest.mark.parametrize("bad", [-1, 0.5, True, "100"])
def test_silent_wait_must_be_whole_microseconds(bad):
    with pytest.raises(ValueError, match="silent_wait_us"):
        StereoSettings(silent_wait_us=bad)


def test_default_bound_is_the_documented_100_ms():
    assert StereoSettings().silent_wait_us == SILENT_WAIT_US == 100_000


def test_lag_meter_percentiles_over_every_packet():
    meter = LagMeter()
    for k in range(1, 101):  # lags 1..100 ms
        meter.record(10_000 * k, 10_000 * k + 1_000 * k)
    meter.record(None, 5)  # an empty packet has no arrival
    p = meter.percentiles()
    # numpy's linear percentile of 1..100: p50 = 50.5, p90 = 90.1, p99 = 99.01
    assert p == pytest.approx({"packets": 100, "p50_ms": 50.5, "p90_ms": 90.1, "p99_ms": 99.01, "max_ms": 100.0})
    assert meter.line().endswith("p50 50.5, p90 90.1, p99 99.0, max 100.0 ms")
    assert LagMeter().percentiles()["max_ms"] is None


def test_a_camera_whose_reader_reads_bytes_is_not_silent_while_they_are_held():
    # The right reader reads bytes all along but delivers nothing from host 205 to 354.5 ms (it holds them while
    # it detects the protocol, say): its last byte's time shows the camera sends, so nothing is dropped.
    left, right = camera(400, 40), camera(400, 30)
    held = deliveries(right, 1, lambda k: 354_500 if 200 <= k < 349 else (k + 1) * 1_000 + D)
    rig = unopened_rig()

    def reader_reads(now):
        if now < 400_000:
            rig.cams[1].last_byte_us = now - 500

    packets = drive(rig, deliveries(left, 0) + held, 600_000, silent_after=500_000, each_tick=reader_reads)
    assert rig.late_events == 0
    np.testing.assert_array_equal(joined(packets, "right"), right)


def test_an_ended_stream_holds_nothing():
    left, right = camera(300, 40), camera(250, 30)
    rig = unopened_rig()
    script = sorted(deliveries(left, 0) + deliveries(right, 1), key=lambda d: (d[0], d[1]))
    for arrival, cam, chunk in script:
        rig.cams[cam].queue.put(Chunk(chunk, arrival))
    pkt = rig.packet(0, now_us=306_000)
    assert pkt.until == 249_750  # held at the right camera's last event
    rig.end_stream(1)
    pkt = rig.packet(0, now_us=306_000)
    assert pkt.until == 299_750 and pkt.left["t"][-1] == 299_500  # now at the left camera's own last event
    rig.end_stream(0)
    pkt = rig.packet(0, now_us=306_000)
    assert pkt.until == 299_751 and pkt.left["t"].tolist() == [299_750] and not rig.pending


def test_simulated_streams_end_once_every_event_sent_was_delivered():
    from types import SimpleNamespace

    from cvstereo.sensors.session import end_finished_streams

    rig = unopened_rig()
    ev = camera(3, 40)
    rig.cams[0].queue.put(Chunk(ev, 4_000))
    rig.cams[1].queue.put(Chunk(ev[:5], 4_000))
    rig.packet(0, now_us=4_000)
    devices = [SimpleNamespace(done=True, sent_events=ev.size), SimpleNamespace(done=True, sent_events=ev.size)]
    end_finished_streams(rig, devices)
    assert [s.ended for s in rig.sides] == [True, False]  # the right camera's last events are still on their way
    end_finished_streams(rig, [SimpleNamespace(done=False, sent_events=0)] * 2)
    assert [s.ended for s in rig.sides] == [True, False]
