"""Two event cameras merged into time-ordered stereo packets (:class:`StereoRig`); two eDVS128 boards on one clock
(:class:`StereoEDVS`).

Clock strategies (:class:`StereoSettings.clock`):

- ``"master-slave"``: the firmware's timestamp sync (``!ETM0`` on the left board, ``!ETS`` on the right,
  then ``!ETM+``; the sequence of edvstools). Both boards then count on the master's clock.
- ``"align"``: for firmware without it: ``!ET0`` to both boards back to back. The residual offset is
  estimated from arrival times (the smallest ``host arrival - device time`` per board bounds its clock
  offset plus transport delay) and reported; ``correct_offset`` subtracts it from the right camera.

Merging (:meth:`StereoEDVS.packet`): a packet closes at the *watermark*, the time before which both readers have
delivered every event. Each camera's events come in time order, so a camera holds the watermark at its latest
delivered event's time: a reader that runs late (a loaded machine) delays the packets, and loses nothing. A
camera that delivers nothing, and whose reader reads no byte, for :attr:`StereoSettings.silent_wait_us` of host
time while the merger watches (or whose reader reports it silent) holds the other back no longer: the watermark
may then pass its device time that long ago. Its events that arrive behind the watermark after all (a reader
stalled for longer than the bound) are dropped and counted (:attr:`StereoEDVS.late_events`), never merged
silently: a matcher cannot take an event older than one it has matched. The trade-off is the bound: longer, and
a stalled reader loses less; shorter, and a silent camera delays the other's matches less (docs/guide/live.md).
"""

from __future__ import annotations

import queue
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cvstereo.errors import SensorError
from cvstereo.model.events import EVENT_DTYPE, StereoPacket, count_before
from cvstereo.sensors.edvs import EDVS, Chunk, host_us
from cvstereo.sensors.protocol import DEFAULT_BAUD, ProtocolSettings

__all__ = ["CAMERAS", "SILENT_WAIT_US", "StereoEDVS", "StereoRig", "StereoSettings"]

CAMERAS = ("left", "right")

#: Host time a camera may deliver nothing, while the other delivers, before it no longer holds the other
#: back, us (the default of :attr:`StereoSettings.silent_wait_us`).
SILENT_WAIT_US = 100_000


@dataclass(frozen=True)
class StereoSettings:
    """How two boards are run together.

    Parameters
    ----------
    clock : {"master-slave", "align"}
        Timestamp synchronisation (see the module docstring).
    correct_offset : bool
        ``align`` only: shift the right camera by the estimated residual offset.
    silent_wait_us : int
        The bounded wait (see the module docstring): a camera that has delivered nothing, its reader read no
        byte, for this long (host time, us, while the merger watched), or whose reader reports it silent, no
        longer holds the other back; the watermark may then pass its device time this long ago. A reader
        stalled for longer loses the events it delivers behind the watermark (counted); a silent camera delays
        the other this long.
    silence_s : float
        A board silent this long is reported.
    """

    clock: Literal["master-slave", "align"] = "master-slave"
    correct_offset: bool = False
    silent_wait_us: int = SILENT_WAIT_US
    silence_s: float = 1.0

    def __post_init__(self):
        if isinstance(self.silent_wait_us, bool) or not isinstance(self.silent_wait_us, int) \
                or self.silent_wait_us < 0:
            raise ValueError(f"silent_wait_us={self.silent_wait_us!r}: must be a whole number of microseconds "
                             ">= 0 (the host time a silent camera holds the other back).")


def _host_now(now_us: int | None) -> int:
    """``now_us`` if given (a test's clock), else the host clock's time."""
    return host_us() if now_us is None else now_us


class _Side:
    """One camera's delivered events not yet in a packet, each chunk with the host time it arrived."""

    def __init__(self, cam: EDVS):
        self.cam = cam
        self.buf: list[Chunk] = []
        self.last_t: int | None = None
        self.min_offset: int | None = None  # min(host arrival - device time), us
        self.events = 0
        self.late_events = 0
        self.last_arrival: int | None = None
        self.ended = False  # see StereoEDVS.end_stream

    def take(self, chunk: Chunk, shift: int = 0) -> None:
        ev = chunk.events
        if shift:
            ev = ev.copy()
            ev["t"] -= shift
        self.buf.append(Chunk(ev, chunk.arrival_us))
        self.events += ev.size
        self.last_t = int(ev["t"][-1])
        self.last_arrival = chunk.arrival_us
        off = chunk.arrival_us - int(chunk.events["t"][-1])
        self.min_offset = off if self.min_offset is None else min(self.min_offset, off)

    def split(self, watermark: int | None, until: int) -> tuple[np.ndarray, int | None]:
        """Take the events before ``until`` out of the buffer; drop (and count) those before ``watermark``,
        which arrived after a packet that should have held them was closed. Return the events taken and the
        latest arrival among them (None if none)."""
        out, arrival, rest = [], None, []
        for ev, arr in self.buf:
            if watermark is not None and ev.size and ev["t"][0] < watermark:
                late = ev["t"] < watermark
                self.late_events += int(late.sum())
                ev = ev[~late]
            k = count_before(ev["t"], until)
            if k:
                out.append(ev[:k])
                arrival = arr if arrival is None else max(arrival, arr)
            if k < ev.size:
                rest.append(Chunk(ev[k:], arr))
        self.buf = rest
        return (np.concatenate(out) if out else np.zeros(0, EVENT_DTYPE)), arrival


class StereoRig:
    """Two event sources (left, right) merged on one clock: the watermark, the bounded wait, late events.

    A source is one camera's reader (:class:`~cvstereo.sensors.edvs.EDVS`,
    :class:`~cvstereo.sensors.dvlive.DVSource`): it has ``name``, ``port`` (where it reads from),
    ``resolution``, ``open()``, ``start()``, ``stop()``, ``close()``, ``status()``, and while it streams a
    ``queue`` of :class:`~cvstereo.sensors.edvs.Chunk` in its camera's time order, ``last_byte_us`` (host time
    it last read anything), ``silent``, ``silence_s``, ``error`` and ``protocol``. The merging needs nothing
    else, so that every source is merged, bounded and counted the same way.

    Parameters
    ----------
    sources : (left, right)
    stereo : StereoSettings, keyword-only
    """

    def __init__(self, sources, *, stereo: StereoSettings | None = None):
        self.stereo = stereo or StereoSettings()
        self.cams = list(sources)
        if len(self.cams) != len(CAMERAS):
            raise ValueError(f"a stereo rig takes {len(CAMERAS)} sources (left, right), got {len(self.cams)}")
        self.sides = [_Side(c) for c in self.cams]
        self.watermark: int | None = None
        #: Packets closed past a camera that held nothing back: silent (the bounded wait), or its stream ended.
        self.waited_out = 0
        #: Host time (us) at which the latest event of the last packet arrived (None: the packet is empty).
        self.packet_arrival_us: int | None = None
        self._looked_us: int | None = None  # host time the last packet() call ended
        self._watched_since: int | None = None  # host time since which packet() calls came often
        self.residual_offset_us: int | None = None

    @property
    def resolution(self) -> tuple[int, int]:
        """The cameras' (width, height); both sources have it (see the sources' ``open``)."""
        return self.cams[0].resolution

    def open(self) -> StereoRig:
        """Open both sources (one that cannot be opened raises SensorError naming it; the other is closed
        again), and refuse two cameras of different resolutions (one matcher takes both)."""
        try:
            for cam in self.cams:
                cam.open()
            left, right = (tuple(cam.resolution) for cam in self.cams)
            if left != right:
                raise SensorError(f"the left camera ({self.cams[0].port}) is {left[0]}x{left[1]} and the right "
                                  f"({self.cams[1].port}) {right[0]}x{right[1]}: a stereo pair needs two "
                                  "cameras of one resolution.")
        except BaseException:
            self.close()
            raise
        return self

    def start(self) -> None:
        """Start both sources streaming, back to back."""
        for cam in self.cams:
            cam.start()

    def stop(self) -> None:
        for cam in self.cams:
            cam.stop()

    def close(self) -> None:
        for cam in self.cams:
            cam.close()

    def __enter__(self) -> StereoRig:
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
        """The watermark: the time before which both cameras have delivered every event (see the module
        docstring); None before both have delivered anything.

        A camera holds it at its latest delivered event's time (later events are not earlier). A camera that
        delivered nothing and whose reader read no byte for ``silent_wait_us`` holds it at its device time
        ``silent_wait_us`` before now (``now_us``) instead, its clock offset known from its arrivals. Silence
        counts only while this merger looked often (:meth:`packet` calls never ``silent_wait_us / 2`` apart: a
        process that did not run, its readers neither, proves no silence), or once its reader reports it
        silent. A camera whose stream has ended (:meth:`end_stream`) holds nothing.
        """
        if any(side.min_offset is None and not side.ended for side in self.sides):
            return None
        now = _host_now(now_us)
        wait = self.stereo.silent_wait_us
        watched = now if self._watched_since is None else self._watched_since
        bounds = []
        for side in self.sides:
            if side.ended:
                continue
            # Bytes read but not delivered yet (held while the protocol is detected or a wrap is decided) show
            # a camera that sends: silence counts from the later of its last delivery and its last byte, and
            # only over time this merger watched (a stalled process stalls the readers too).
            heard = max(side.last_arrival, side.cam.last_byte_us or side.last_arrival)
            silent = side.cam.silent or now - max(heard, watched) > wait
            bounds.append(max(side.last_t, now - wait - side.min_offset) if silent else side.last_t)
        if bounds:
            return min(bounds)
        lasts = [side.last_t for side in self.sides if side.last_t is not None]
        return max(lasts) + 1 if lasts else None

    def packet(self, timeout_s: float = 0.05, *, now_us: int | None = None) -> StereoPacket | None:
        """The next time slice of both cameras (possibly empty), or None before both have sent anything.

        Events arriving after the watermark passed them are dropped and counted in :attr:`late_events`.
        :attr:`packet_arrival_us` tells when the packet's latest event arrived. ``now_us``: the host time
        (default: the clock's), for tests.
        """
        # Taken before the queues are read: whatever a reader delivered before it is in them.
        now = _host_now(now_us)
        if self._looked_us is None or now - self._looked_us > self.stereo.silent_wait_us // 2:
            self._watched_since = now  # not looking meanwhile (the matcher ran long): silence not seen
        self.poll(timeout_s)
        until = self.complete_until(now)
        if until is None:
            self._looked_us = _host_now(now_us)
            return None
        if until > min(side.last_t for side in self.sides if side.last_t is not None):
            self.waited_out += 1
        if self.watermark is not None:
            until = max(until, self.watermark)
        parts = [side.split(self.watermark, until) for side in self.sides]
        arrivals = [a for _, a in parts if a is not None]
        self.packet_arrival_us = max(arrivals) if arrivals else None
        self.watermark = until
        self._looked_us = _host_now(now_us)
        return StereoPacket(parts[0][0], parts[1][0], until)

    def end_stream(self, camera: int) -> None:
        """Camera ``camera`` (0 left, 1 right) will send nothing more and every event it sent was delivered
        (a simulated recording played to its end): it no longer holds the other back."""
        self.sides[camera].ended = True

    @property
    def late_events(self) -> int:
        """Events dropped because they arrived behind the watermark (both cameras)."""
        return sum(side.late_events for side in self.sides)

    @property
    def pending(self) -> bool:
        """Events delivered or queued that no packet has taken yet."""
        return any(side.buf or not side.cam.queue.empty() for side in self.sides)

    def status(self) -> dict:
        """Per-board counters, the clock strategy and the residual offset estimate."""
        return {
            "left": self.cams[0].status(),
            "right": self.cams[1].status(),
            "clock": self.stereo.clock,
            "residual_offset_us": self.residual_offset_us,
            "late_events": self.late_events,
            "late_events_by_camera": [side.late_events for side in self.sides],
            "silent_wait_us": self.stereo.silent_wait_us,
            "packets_past_a_silent_camera": self.waited_out,
        }


class StereoEDVS(StereoRig):
    """Two eDVS128 boards (left, right) on one clock (the clock strategies: see the module docstring).

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
        stereo = stereo or StereoSettings()
        super().__init__([EDVS(p, baud=baud, settings=self.settings, name=n, silence_s=stereo.silence_s,
                               auto_format=auto_format, auto_sync=auto_sync)
                          for n, p in zip(CAMERAS, (left_port, right_port), strict=True)], stereo=stereo)

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
