"""One eDVS128 board over pyserial: open, configure, start/stop, and a reader thread feeding a queue.

The reader detects (or checks) the protocol from the first bytes, waits while the consumer is behind (flow
control) but never drops a chunk, and on stop reads the bytes still on their way before it ends.

>>> # with hardware (or a VirtualEDVS port):
>>> # with EDVS("/dev/ttyUSB0") as cam:
>>> #     cam.configure(); cam.start(); chunk = cam.queue.get(timeout=1.0)
"""

from __future__ import annotations

import queue
import threading
import time
from typing import NamedTuple

import numpy as np
import serial

from cvstereo.errors import SensorError
from cvstereo.model.sensor_size import DEFAULT_RESOLUTION
from cvstereo.sensors.decoder import StreamDecoder, warm_up
from cvstereo.sensors.detect import DETECT_BYTES, ProtocolMismatchError, check_protocol
from cvstereo.sensors.protocol import BITS_PER_BYTE, DEFAULT_BAUD, ProtocolSettings

__all__ = ["DEFAULT_SILENCE_S", "DRAIN_MAX_S", "DRAIN_QUIET_S", "EDVS", "RELEASE_AFTER_S", "Chunk", "host_us"]

#: Seconds without a byte after which a streaming sensor counts as silent (the issue: "about a second").
DEFAULT_SILENCE_S = 1.0

#: Pause after which events held for confirmation are released, so a quiet sensor does not hold them.
RELEASE_AFTER_S = 0.02

#: After stop(): keep reading until the port is quiet this long (bytes already on their way are kept).
DRAIN_QUIET_S = 0.05

#: After stop(): read at most this long.
DRAIN_MAX_S = 1.0


class Chunk(NamedTuple):
    """Events decoded from one read, and the host time (``time.monotonic_ns() // 1000``) they arrived."""

    events: np.ndarray
    arrival_us: int


def host_us() -> int:
    """The host clock used for arrival times, microseconds."""
    return time.monotonic_ns() // 1000


class EDVS:
    """One eDVS128 board on a serial port.

    Parameters
    ----------
    port : str
        Serial device (``/dev/ttyUSB0``, ``COM5``, a VirtualEDVS pty).
    baud : int, keyword-only
    settings : ProtocolSettings, keyword-only
    name : str, keyword-only
        Used in messages ("left", "right").
    queue_size : int, keyword-only
        Chunks the queue holds; a full queue makes the reader wait (the device is then throttled by
        RTS/CTS flow control rather than losing events).
    silence_s : float, keyword-only
        A streaming sensor that sends nothing for this long is reported silent.
    rtscts : bool, keyword-only
        Hardware flow control (on for the eDVS).
    auto_format, auto_sync : bool, keyword-only
        Detect the event format / sync-bit polarity from the first bytes instead of taking
        ``settings``' values; values not detected are checked against the stream (a mismatch stops the
        reader with :class:`~cvstereo.sensors.detect.ProtocolMismatchError` in :attr:`error`).

    Attributes
    ----------
    queue : queue.Queue of Chunk
    silent : bool
        No byte for ``silence_s`` while streaming.
    error : BaseException or None
        Why the reader stopped (unplugged cable, wrong protocol settings, ...).
    protocol : str or None
        The format and sync bit decoded, and whether they were detected, checked or assumed.
    resolution : (int, int)
        The eDVS128's pixel array, (128, 128).
    """

    resolution = DEFAULT_RESOLUTION

    def __init__(self, port: str, *, baud: int = DEFAULT_BAUD, settings: ProtocolSettings | None = None,
                 name: str = "sensor", queue_size: int = 1024, silence_s: float = DEFAULT_SILENCE_S,
                 rtscts: bool = True, auto_format: bool = False, auto_sync: bool = False):
        self.port = str(port)
        self.baud = int(baud)
        self.settings = settings or ProtocolSettings()
        self.name = name
        self.silence_s = float(silence_s)
        self.rtscts = rtscts
        # Unbounded: the reader itself waits while `queue_size` chunks are waiting (flow control), but a
        # chunk is never dropped, not even while stopping.
        self.queue_size = int(queue_size)
        self.queue: queue.Queue[Chunk] = queue.Queue()
        self.auto_format = auto_format
        self.auto_sync = auto_sync
        self.protocol: str | None = None
        self._probe = bytearray()
        self._probe_times: list[tuple[int, int, bool, int | None]] = []
        self._probe_tried = 0
        self._epoch_us: int | None = None
        self.decoder = self._new_decoder(self.settings)
        self.silent = False
        self.silences = 0
        self.error: BaseException | None = None
        self.bytes_received = 0
        self.last_byte_us: int | None = None
        self._serial: serial.Serial | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def _new_decoder(self, settings: ProtocolSettings) -> StreamDecoder:
        dec = StreamDecoder(settings, byte_rate=self.baud / BITS_PER_BYTE)
        dec.reset_time(self._epoch_us)
        return dec

    def clock_reset(self, epoch_us: int) -> None:
        """The device clock read zero at host time ``epoch_us`` (after ``!ET0`` or ``!ETM+``)."""
        self._epoch_us = int(epoch_us)
        self.decoder.reset_time(self._epoch_us)

    def reset_clock(self) -> None:
        """Reset the board's timestamp counter (``!ET0``) and tell the decoder when: the host time just before
        the command, so that the wraps before the first event are counted too."""
        epoch = host_us()
        self.command(self.settings.commands.timestamp_reset)
        self.clock_reset(epoch)

    # -- connection -------------------------------------------------------------------------------
    def open(self) -> EDVS:
        """Open the port.

        Raises
        ------
        SensorError
            The port does not exist, is unplugged or busy; the message names the port.
        """
        try:
            self._serial = serial.Serial(self.port, self.baud, timeout=0.02, write_timeout=2.0,
                                         rtscts=self.rtscts)
        except (serial.SerialException, OSError, ValueError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise SensorError(
                f"{self.name} sensor: cannot open serial port {self.port} ({reason}); check that the eDVS is "
                "plugged in and the port name is right (ls /dev/ttyUSB* /dev/ttyACM*)."
            ) from None
        warm_up()  # now, not after the clocks are synchronised: a stall then would delay the stream
        return self

    def close(self) -> None:
        """Stop the reader (if running) and close the port."""
        self.stop()
        if self._serial is not None:
            try:
                self._serial.close()
            except OSError:
                pass
            self._serial = None

    def __enter__(self) -> EDVS:
        if self._serial is None:
            self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _write(self, text: str) -> None:
        if self._serial is None:
            raise SensorError(f"{self.name} sensor ({self.port}) is not open; call open() first.")
        try:
            self._serial.write(self.settings.line(text))
            self._serial.flush()
        except (serial.SerialException, OSError) as exc:
            raise SensorError(f"{self.name} sensor ({self.port}): write failed ({exc}); is it unplugged?") from None

    def command(self, text: str) -> None:
        """Send one command line (no reply is read)."""
        self._write(text)

    def _read_reply(self, timeout_s: float, until: str | None = None) -> str:
        assert self._serial is not None
        deadline = time.monotonic() + timeout_s
        got = bytearray()
        while time.monotonic() < deadline:
            try:
                data = self._serial.read(self._serial.in_waiting or 1)
            except (serial.SerialException, OSError) as exc:
                raise SensorError(f"{self.name} sensor ({self.port}): read failed ({exc}).") from None
            got += data
            if until is not None and until.encode() in got:
                # Let the rest of the line arrive, then stop.
                time.sleep(0.01)
                got += self._serial.read(self._serial.in_waiting)
                break
        return got.decode("ascii", "replace")

    def reset(self, timeout_s: float = 2.0) -> str:
        """Reset the board (``R``) and return its banner.

        Raises
        ------
        SensorError
            No reply containing the banner text (not an eDVS, wrong baud rate, or powered off).
        """
        if self._serial is None:
            self.open()
        self._serial.reset_input_buffer()
        self._write(self.settings.commands.reset)
        reply = self._read_reply(timeout_s, self.settings.commands.banner)
        if self.settings.commands.banner not in reply:
            raise SensorError(
                f"{self.name} sensor ({self.port}): no eDVS answered the reset within {timeout_s:g} s "
                f"(got {reply[:40]!r}); check the baud rate ({self.baud}) and that the board is powered."
            )
        return reply.strip()

    def configure(self, *, biases: dict[int, int] | None = None, reset: bool = True) -> None:
        """Reset (optional), echo off, event format, biases; leaves the input buffer empty."""
        if reset:
            self.reset()
        cmds = [self.settings.commands.echo_off, self.settings.format_command()]
        for index, value in (biases or {}).items():
            cmds.append(self.settings.bias_command(index, value))
        if biases:
            cmds.append(self.settings.commands.flush_biases)
        for c in cmds:
            self._write(c)
        self.drain()

    def drain(self, settle_s: float = 0.05) -> None:
        """Discard replies still arriving (command echoes, help text)."""
        assert self._serial is not None
        time.sleep(settle_s)
        self._serial.reset_input_buffer()

    # -- streaming --------------------------------------------------------------------------------
    def start(self, *, send_start: bool = True) -> None:
        """Start the reader thread, then streaming (``E+``)."""
        if self._thread is not None:
            return
        warm_up()  # (done at open() already: then free)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"edvs-{self.name}", daemon=True)
        self.last_byte_us = host_us()
        self._thread.start()
        if send_start:
            self._write(self.settings.commands.start)

    def stop(self, *, send_stop: bool = True) -> None:
        """Stop streaming (``E-``, unless the port is gone) and join the reader thread."""
        if self._thread is None:
            return
        if send_stop and self.error is None and self._serial is not None:
            try:
                self._write(self.settings.commands.stop)
            except SensorError:
                pass
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._thread = None

    @property
    def running(self) -> bool:
        """The reader thread is alive (not stopped, not failed)."""
        return self._thread is not None and self._thread.is_alive()

    def _put(self, chunk: Chunk) -> None:
        # Wait while the consumer is behind (flow control), never past a stop request, and never drop.
        while self.queue.qsize() >= self.queue_size and not self._stop.is_set():
            time.sleep(0.005)
        self.queue.put(chunk)

    def _decode(self, data: bytes, now: int, *, fresh: bool = True, after: int | None = None, final: bool = False,
                release: bool = False) -> None:
        """Decode bytes (after the protocol is settled: until then they wait in the probe); ``after`` is the
        host time of the last look that found the OS buffer empty (none of ``data`` had arrived then)."""
        if self.protocol is None:
            if data:
                self._probe += data
                self._probe_times.append((len(self._probe), now, fresh, after))
            if len(self._probe) < max(DETECT_BYTES, 2 * self._probe_tried) and not (final or release):
                return  # look again at twice the sample (detection is not free: linear in all)
            self._probe_tried = len(self._probe)
            settled = check_protocol(bytes(self._probe), self.settings, auto_format=self.auto_format,
                                     auto_sync=self.auto_sync, name=self.name, final=final, pause=release)
            if settled is None:
                return
            settings, self.protocol = settled
            if settings != self.decoder.settings:
                self.decoder = self._new_decoder(settings)
            probe, times, self._probe, self._probe_times = bytes(self._probe), self._probe_times, bytearray(), []
            start = 0
            for end, t, f, a in times:  # replay with the arrival time of each piece
                self._decode(probe[start:end], t, fresh=f, after=a)
                start = end
            data = b""
        ev = self.decoder.decode(data, host_t=now, fresh=fresh, after_t=after, final=final,
                                 release=release and not final)
        if ev.size:
            self._put(Chunk(ev, now))

    def _run(self) -> None:
        ser = self._serial
        assert ser is not None
        held = False
        stop_at: float | None = None
        empty_at: int | None = None  # host time before the last look that found no byte waiting
        try:
            while True:
                if self._stop.is_set() and stop_at is None:
                    stop_at = time.monotonic()
                # Taken before the look, so every byte read later arrived after it, however late this
                # thread runs (a loaded machine): it bounds the device time from below (decoder: after_t).
                before = host_us()
                waiting = ser.in_waiting
                if waiting == 0:
                    empty_at = before
                data = ser.read(max(1, min(waiting, 1 << 16)))
                now = host_us()
                if data:
                    self.bytes_received += len(data)
                    self.last_byte_us = now
                    if self.silent:
                        self.silent = False
                    self._decode(data, now, fresh=waiting == 0, after=empty_at)
                    held = True
                    if stop_at is not None and time.monotonic() - stop_at > DRAIN_MAX_S:
                        break
                    continue
                quiet_s = (now - (self.last_byte_us or now)) / 1e6
                if stop_at is not None and (quiet_s >= DRAIN_QUIET_S or time.monotonic() - stop_at > DRAIN_MAX_S):
                    break  # stopped, and the bytes already on their way have been read
                if held and quiet_s >= RELEASE_AFTER_S:
                    self._decode(b"", now, release=True)
                    held = False
                if not self.silent and quiet_s >= self.silence_s:
                    self.silent = True
                    self.silences += 1
        except ProtocolMismatchError as exc:
            self.error = exc
            return
        except (serial.SerialException, OSError, TypeError) as exc:
            # pyserial raises SerialException (or TypeError from a closed fd) when the device vanishes.
            self.error = SensorError(f"{self.name} sensor ({self.port}) disconnected: {exc}")
        # The stream ended (stopped or unplugged): every byte received so far is decoded and delivered.
        try:
            self._decode(b"", host_us(), final=True)
        except ProtocolMismatchError as exc:
            self.error = exc

    def status(self) -> dict:
        """Counters for reports: bytes, events, corrupt bytes, silences, error."""
        return {
            "port": self.port,
            "bytes": self.bytes_received,
            "events": self.decoder.events_decoded,
            "corrupt_bytes": self.decoder.corrupt_bytes,
            "ambiguous_wraps": self.decoder.ambiguous_wraps,
            "protocol": self.protocol,
            "silences": self.silences,
            "silent": self.silent,
            "error": None if self.error is None else str(self.error),
        }
