"""Two eDVS128 boards on one clock, merged into time-ordered stereo packets.

Clock strategies (:class:`StereoSettings.clock`):

- ``"master-slave"``: the firmware's timestamp sync (``!ETM0`` on the left board, ``!ETS`` on the right,
  then ``!ETM+``; the sequence of edvstools). Both boards then count on the master's clock.
- ``"align"``: for firmware without it: ``!ET0`` to both boards back to back. The residual offset is
  estimated from arrival times (the smallest ``host arrival - device time`` per board bounds its clock
  offset plus transport delay) and reported; ``correct_offset`` subtracts it from the right camera.
"""

from __future__ import annotations

import queue
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cvstereo.model.events import EVENT_DTYPE, StereoPacket, count_before
from cvstereo.sensors.edvs import EDVS, Chunk, host_us
from cvstereo.sensors.protocol import DEFAULT_BAUD, ProtocolSettings

__all__ = ["CAMERAS", "StereoEDVS", "StereoSettings"]

CAMERAS = ("left", "right")


@dataclass(frozen=True)
class StereoSettings:
    """How two boards are run together.

    Parameters
    ----------
    clock : {"master-slave", "align"}
        Timestamp synchronisation (see the module docstring).
    correct_offset : bool
        ``align`` only: shift the right camera by the estimated residual offset.
    margin_us : int
        Transport latency allowed for: a packet closes this long (host time) after its end, so that
        events still in flight from the slower board are not late.
    silence_s : float
        A board silent this long is reported.
    """

    clock: Literal["master-slave", "align"] = "master-slave"
    correct_offset: bool = False
    margin_us: int = 30_000
    silence_s: float = 1.0


class _Side:
    def __init__(self, cam: EDVS):
        self.cam = cam
        self.buf: list[np.ndarray] = []
        self.last_t: int | None = None
        self.min_offset: int | None = None  # min(host arrival - device time), us
        self.events = 0
        self.last_arrival: int | None = None

    def take(self, chunk: Chunk, shift: int = 0) -> None:
        ev = chunk.events
        if shift:
            ev = ev.copy()
            ev["t"] -= shift
        self.buf.append(ev)
        self.events += ev.size
        self.last_t = int(ev["t"][-1])
        self.last_arrival = chunk.arrival_us
        off = chunk.arrival_us - int(chunk.events["t"][-1])
        self.min_offset = off if self.min_offset is None else min(self.min_offset, off)


class StereoEDVS:
    """Two boards (left, right) on one clock.

    Parameters
    ----------
    left_port, right_port : str
    baud : int, keyword-only
    settings : ProtocolSettings, keyword-only
        Both boards use the same protocol settings.
    stereo : StereoSettings, keyword-only
    auto_format, auto_sync : bool, keyword-only
        Detect the event format / sync bit of each board from its first bytes (see :class:`EDVS`).
    """

    def __init__(self, left_port: str, right_port: str, *, baud: int = DEFAULT_BAUD,
                 settings: ProtocolSettings | None = None, stereo: StereoSettings | None = None,
                 auto_format: bool = False, auto_sync: bool = False):
        self.settings = settings or ProtocolSettings()
        self.stereo = stereo or StereoSettings()
        self.cams = [EDVS(p, baud=baud, settings=self.settings, name=n, silence_s=self.stereo.silence_s,
                          auto_format=auto_format, auto_sync=auto_sync)
                     for n, p in zip(CAMERAS, (left_port, right_port), strict=True)]
        self.sides = [_Side(c) for c in self.cams]
        self.watermark: int | None = None
        self.late_events = 0
        self.residual_offset_us: int | None = None

    def open(self) -> StereoEDVS:
        """Open both ports (a missing one raises SensorError naming it; the other is closed again)."""
        try:
            for cam in self.cams:
                cam.open()
        except BaseException:
            self.close()
            raise
        return self

    def start(self, *, biases: dict[int, int] | None = None) -> None:
        """Reset and configure both boards, synchronise their clocks and start streaming."""
        left, right = self.cams
        for cam in self.cams:
            cam.configure(biases=biases)
        c = self.settings.commands
        # The host time of the clock reset lets each decoder count the 16-bit wraps before a camera's first
        # event too (a camera that starts sending later must not start its clock later).
        if self.stereo.clock == "master-slave":
            left.command(c.master_arm)
            right.command(c.slave)
            epoch = host_us()
            left.command(c.master_run)
            for cam in self.cams:
                cam.clock_reset(epoch)
        else:
            for cam in self.cams:
                cam.reset_clock()
        for cam in self.cams:
            cam.drain(0.02)
        for cam in self.cams:
            cam.start(send_start=False)
        # Back to back, so that the boards start as close together as the host allows.
        for cam in self.cams:
            cam.command(c.start)

    def stop(self) -> None:
        for cam in self.cams:
            cam.stop()

    def close(self) -> None:
        for cam in self.cams:
            cam.close()

    def __enter__(self) -> StereoEDVS:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # -- merging ----------------------------------------------------------------------------------
    def _offset_estimate(self) -> int | None:
        offs = [s.min_offset for s in self.sides]
        if None in offs:
            return None
        return int(offs[1] - offs[0])

    def poll(self, timeout_s: float = 0.05) -> list[tuple[int, Chunk]]:
        """Move arrived chunks of both boards into the merge buffers; return them as (camera, chunk)."""
        got = []
        for cam_i, side in enumerate(self.sides):
            q = side.cam.queue
            try:
                while True:
                    chunk = q.get(timeout=timeout_s if not got and cam_i == 1 else 0)
                    shift = 0
                    if cam_i == 1 and self.stereo.clock == "align" and self.stereo.correct_offset:
                        est = self._offset_estimate()
                        shift = -est if est is not None else 0
                    side.take(chunk, shift)
                    got.append((cam_i, chunk))
            except queue.Empty:
                pass
        self.residual_offset_us = self._offset_estimate()
        return got

    def complete_until(self, now_us: int | None = None) -> int | None:
        """The time before which both cameras' events have arrived (see StereoSettings.margin_us)."""
        now = host_us() if now_us is None else now_us
        bounds = []
        for side in self.sides:
            if side.min_offset is None:
                return None
            # Device time now, minus the allowance for bytes still in flight.
            bounds.append(max(side.last_t + 1, now - side.min_offset - self.stereo.margin_us))
        return min(bounds)

    def packet(self, timeout_s: float = 0.05) -> StereoPacket | None:
        """The next time slice of both cameras (possibly empty), or None before both have sent anything.

        Events arriving after the watermark passed them are dropped and counted in :attr:`late_events`.
        """
        self.poll(timeout_s)
        until = self.complete_until()
        if until is None:
            return None
        if self.watermark is not None:
            until = max(until, self.watermark)
        out = []
        for side in self.sides:
            ev = np.concatenate(side.buf) if side.buf else np.zeros(0, EVENT_DTYPE)
            if self.watermark is not None:
                late = ev["t"] < self.watermark
                if late.any():
                    self.late_events += int(late.sum())
                    ev = ev[~late]
            k = count_before(ev["t"], until)
            out.append(ev[:k])
            side.buf = [ev[k:]] if k < ev.size else []
        self.watermark = until
        return StereoPacket(out[0], out[1], until)

    def status(self) -> dict:
        """Per-board counters, the clock strategy and the residual offset estimate."""
        return {
            "left": self.cams[0].status(),
            "right": self.cams[1].status(),
            "clock": self.stereo.clock,
            "residual_offset_us": self.residual_offset_us,
            "late_events": self.late_events,
        }
