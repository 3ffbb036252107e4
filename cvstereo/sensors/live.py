"""Run a matcher on the live stream of two boards and report disparity, distance and lag as it goes."""

from __future__ import annotations

import hashlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cvstereo.geometry.depth import DepthModel
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import StereoPacket
from cvstereo.sensors.edvs import host_us
from cvstereo.sensors.lag import LagMeter
from cvstereo.sensors.stereo import StereoRig

__all__ = ["PACKET_WAIT_S", "UPDATE_S", "LiveStats", "run_live"]

#: Seconds between status lines (10 Hz).
UPDATE_S = 0.1
#: Longest wait for the rig's next packet, s: the stop conditions are checked at least this often.
PACKET_WAIT_S = 0.02


@dataclass
class LiveStats:
    """What a live run measured."""

    updates: int = 0
    matches: int = 0
    events: list[int] = field(default_factory=lambda: [0, 0])
    lags_ms: list[float] = field(default_factory=list)
    latencies_ms: list[float] = field(default_factory=list)
    lag: LagMeter = field(default_factory=LagMeter)
    #: sha256 of the matches' bytes in the order they came: equal to a file's matches hashed the same way when
    #: the live run matched the same events.
    digest: Any = field(default_factory=hashlib.sha256)

    def summary(self) -> dict:
        lag = np.asarray(self.lags_ms) if self.lags_ms else np.zeros(1)
        lat = np.asarray(self.latencies_ms)
        return {"updates": self.updates, "matches": self.matches, "events_left": self.events[0],
                "events_right": self.events[1], "lag_ms_mean": float(lag.mean()), "lag_ms_max": float(lag.max()),
                "latency_ms_median": float(np.median(lat)) if lat.size else None,
                "latency_ms_p95": float(np.percentile(lat, 95)) if lat.size else None,
                "lag_per_packet": self.lag.percentiles(), "matches_sha256": self.digest.hexdigest()}


def _num(value: float, width: int, digits: int) -> str:
    """A number for the status line; "n/a" where there is none (no matches yet, no depth model)."""
    return f"{value:{width}.{digits}f}" if np.isfinite(value) else f"{'n/a':>{width}}"


def run_live(rig: StereoRig, matcher: StreamMatcher, *, depth: DepthModel | None = None,
             seconds: float | None = None, stop: threading.Event | None = None, out=None,
             update_s: float = UPDATE_S, done=None,
             on_packet: Callable[[StereoPacket, np.ndarray], None] | None = None) -> LiveStats:
    """Feed the rig's packets to ``matcher`` and print one status line per ``update_s``.

    The packets go through the library's one feed loop (:func:`cvstereo.run.run_iter`), read as they come and
    not kept, so that memory does not grow with the session. A line shows the median disparity of the matches
    since the last line, the distance it means (``depth``), events per second of each sensor, and the lag:
    how far the newest matched event lies behind real time (host now minus its arrival-time mapped device
    time). The latency recorded per line is from the arrival of the newest event that produced a match to the
    line being printed. The run ends at ``stop``, after ``seconds`` or when ``done()`` says so; the matcher is
    then flushed and its last matches counted. ``on_packet(packet, matches)``, where given, sees every packet
    with the matches its feed returned, right after the feed (``live --rerun`` logs them there:
    :class:`cvstereo.viz.rerun_log.LiveLog`).
    """
    from cvstereo.run import run_iter

    out = sys.stdout if out is None else out  # the stream of the call, not the one at import (tests swap it)
    stats = LiveStats()
    recent: list[np.ndarray] = []
    counts = [0, 0]
    last_line = time.monotonic()
    newest_arrival: int | None = None
    for pkt, m in run_iter(matcher, _rig_packets(rig, seconds, stop, done)):
        stats.digest.update(m.tobytes())
        if pkt is None:  # the flush, once the packets ended
            stats.matches += m.size
            break
        for i, ev in enumerate((pkt.left, pkt.right)):
            counts[i] += ev.size
            stats.events[i] += ev.size
        # run_iter yields right after feeding this packet, before the next is taken from the rig.
        stats.lag.record(rig.packet_arrival_us, host_us())
        if on_packet is not None:
            on_packet(pkt, m)
        if m.size:
            recent.append(m["disparity"])
            stats.matches += m.size
            arrivals = [a for a in (s.last_arrival for s in rig.sides) if a is not None]
            newest_arrival = max(arrivals) if arrivals else None
        now = time.monotonic()
        if now - last_line >= update_s:
            dt = now - last_line
            last_line = now
            d = np.concatenate(recent) if recent else np.zeros(0, np.float32)
            recent = []
            med = float(np.median(d)) if d.size else float("nan")
            dist = float(depth.distance(med)) if (depth is not None and d.size) else float("nan")
            offs = [s.min_offset for s in rig.sides if s.min_offset is not None]
            lag_ms = float("nan")
            if offs and matcher.watermark is not None:
                lag_ms = (host_us() - (matcher.watermark + min(offs))) / 1e3
                stats.lags_ms.append(lag_ms)
            line = (f"disparity {_num(med, 6, 2)} px  distance {_num(dist, 6, 2)} m  "
                    f"L {counts[0] / dt:8.0f} ev/s  R {counts[1] / dt:8.0f} ev/s  lag {_num(lag_ms, 6, 1)} ms")
            counts = [0, 0]
            print(line, file=out, flush=True)
            if d.size and newest_arrival is not None:
                stats.latencies_ms.append((host_us() - newest_arrival) / 1e3)
            stats.updates += 1
    return stats


def _rig_packets(rig: StereoRig, seconds: float | None, stop: threading.Event | None, done
                 ) -> Iterator[StereoPacket]:
    """The rig's packets as they complete, until ``stop`` is set, ``seconds`` have passed or ``done()``; the
    conditions are checked before every wait for a packet (a wait lasts at most :data:`PACKET_WAIT_S`)."""
    t_end = None if seconds is None else time.monotonic() + seconds
    while not (stop is not None and stop.is_set()) and (t_end is None or time.monotonic() < t_end):
        if done is not None and done():
            return
        pkt = rig.packet(PACKET_WAIT_S)
        if pkt is not None:
            yield pkt
