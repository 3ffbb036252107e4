"""A virtual eDVS128 on a pseudo-terminal, for tests, samples and ``--simulate``.

It answers the commands of :mod:`cvstereo.sensors.protocol`, streams a recording's events in the chosen
format, paced by their timestamps (times a speed factor) and by the baud rate (10 bit times per byte),
and on request injects garbage bytes, stalls, or disconnects. It runs in its own thread.

>>> from cvstereo.model.events import make_events
>>> ev = make_events([0, 1000, 2000], [1, 2, 3], [4, 5, 6], [1, 0, 1])
>>> with VirtualEDVS(ev) as port:  # doctest: +SKIP
...     cam = EDVS(port).open()
"""

from __future__ import annotations

import contextlib
import os
import queue
import select
import threading
import time
import tty

import numpy as np

from cvstereo.sensors.protocol import DEFAULT_BAUD, FORMAT_NUMBERS, ProtocolSettings, encode_events

__all__ = ["BANNER", "TICK_S", "VirtualClock", "VirtualEDVS", "read_back"]

#: Banner sent after ``R`` (contains "EDVS", as the real board's does).
BANNER = "EDVS128 virtual board (cvstereo), 1us timestamps"

#: Longest the device thread sleeps between looks at its port, s.
TICK_S = 0.002


class VirtualClock:
    """What two virtual boards share, as two real boards after ``!ETM``: the master's clock, and the
    moment the scene starts (the first ``E+`` of either board), so both stamp the same instant alike."""

    def __init__(self):
        self.zero: float | None = None  # host time (time.monotonic) at which the master's clock read 0
        self.start: float | None = None  # host time at which scene time `time_origin_us` is played


class VirtualEDVS:
    """A virtual eDVS128 streaming ``events`` on a pty; a context manager yielding the port path.

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        What the sensor "sees"; event k is sent ``(t_k - t_0) / speed`` seconds after ``E+``.
    baud : int, keyword-only
        Link speed: at most ``baud / 10`` bytes per second (times ``speed``).
    speed : float, keyword-only
        Stream time per wall time (1 = real time).
    settings : ProtocolSettings, keyword-only
        Sync-bit polarity, polarity sense, numbering of the firmware simulated. The event format is
        whatever the host asks for with ``!Ex`` (initially ``settings.event_format``).
    clock_offset_us : int, keyword-only
        Device time of the first event before any timestamp synchronisation (a free-running board).
    reset_jitter_us : int, keyword-only
        Device clock after ``!ET0``, simulating two boards reset a little apart.
    clock : VirtualClock, keyword-only
        Shared with the other board of a pair: after ``!ETM+`` (master) / ``!ETS`` (slave) both count on
        the master's clock, and both play the scene from the same moment, so the time between the two
        cameras' events is kept exactly (real boards after ``!ETM`` do the same).
    time_origin_us : int, keyword-only
        Scene time played when streaming starts (default: the first event's); give both boards of a pair
        the recording's start, so a camera that starts later also starts later here.
    echo : bool, keyword-only
        Echo command lines until ``!U0`` (as the firmware does).
    """

    def __init__(self, events: np.ndarray, *, baud: int = DEFAULT_BAUD, speed: float = 1.0,
                 settings: ProtocolSettings | None = None, clock_offset_us: int = 0, reset_jitter_us: int = 0,
                 echo: bool = True, clock: VirtualClock | None = None, time_origin_us: int | None = None):
        self.events = events
        self.baud = int(baud)
        self.speed = float(speed)
        self.settings = settings or ProtocolSettings()
        self.format = self.settings.event_format
        self.clock_offset_us = int(clock_offset_us)
        self.reset_jitter_us = int(reset_jitter_us)
        self.echo = echo
        self.biases: dict[int, int] = {}
        self.commands: list[str] = []
        self.streaming = False
        self.sent_events = 0
        self.late_us = 0  # longest an event waited past its time before this board sent it (its thread ran late)
        self.sent_bytes = 0
        self.garbage_bytes = 0
        self.port: str | None = None
        self._master: int | None = None
        self._slave: int | None = None
        self._thread: threading.Thread | None = None
        self._quit = threading.Event()
        self._lock = threading.Lock()
        self._garbage: list[bytes] = []
        self._stall_until = 0.0
        self._disconnect = False
        self._pending = b""
        if not self.speed > 0 or self.speed == float("inf"):
            raise ValueError(f"speed must be a positive finite number, got {speed}.")
        self._t0 = int(time_origin_us) if time_origin_us is not None else (int(events["t"][0]) if events.size else 0)
        self._clock = clock
        self._zero: float | None = None  # host time at which this board's clock read 0 (None: not yet)
        self._is_slave = False
        self._stream_start: float | None = None
        self.lead_us = 0  # device time at which scene time `time_origin_us` is stamped
        self._await_master = False  # a slave streaming before the master's clock runs
        self._next = 0
        self._t_prev = 0

    # -- life cycle -------------------------------------------------------------------------------
    def start(self) -> str:
        """Create the pty and start the device thread; return the port path."""
        self._master, self._slave = os.openpty()
        # Raw mode: no echo, no line editing, no CR/LF translation by the tty layer itself.
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._run, name=f"virtual-edvs-{self.port}", daemon=True)
        self._thread.start()
        return self.port

    def close(self) -> None:
        """Stop the thread and close the pty."""
        self._quit.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._close_fds()

    def _close_fds(self) -> None:
        for name in ("_master", "_slave"):
            fd = getattr(self, name)
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
                setattr(self, name, None)

    def __enter__(self) -> str:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # -- fault injection --------------------------------------------------------------------------
    def inject_garbage(self, data: bytes) -> None:
        """Send ``data`` between two events (as soon as the stream is at an event boundary)."""
        with self._lock:
            self._garbage.append(bytes(data))

    def stall(self, seconds: float) -> None:
        """Send nothing for ``seconds`` (events due meanwhile follow afterwards); ``inf`` = go silent."""
        self._stall_until = time.monotonic() + seconds

    def disconnect(self) -> None:
        """Vanish as an unplugged board does: the pty is closed and reads on it fail."""
        self._disconnect = True

    @property
    def done(self) -> bool:
        """Every event of the recording has been sent."""
        return self._next >= self.events.size and not self._pending

    # -- device thread ----------------------------------------------------------------------------
    def _reply(self, text: str) -> None:
        self._pending += (text + "\r\n").encode("ascii")

    def _handle(self, line: str) -> None:
        cmd = line.strip()
        if not cmd:
            return
        self.commands.append(cmd)
        if self.echo:
            self._reply(cmd)
        c = self.settings.commands
        if cmd == c.reset or cmd == "r":
            self.streaming = False
            self.echo = True
            self._reply(BANNER)
        elif cmd in (c.start, "+"):
            self._start_stream(time.monotonic())
        elif cmd in (c.stop, "-"):
            self.streaming = False
        elif cmd == c.echo_off:
            self.echo = False
        elif cmd in (c.timestamp_reset, "!ET", "!ET=0"):
            self._zero = time.monotonic() - self.reset_jitter_us / 1e6 / self.speed
            self._is_slave = False
        elif cmd == c.master_run:
            self._zero = time.monotonic()
            self._is_slave = False
            if self._clock is not None:
                self._clock.zero = self._zero
        elif cmd == c.slave:
            self._is_slave = True
            self._zero = time.monotonic()  # without a shared clock: synchronised by the command itself
        elif cmd == c.master_arm:
            pass
        elif cmd.startswith("!E") and cmd[2:].isdigit():
            number = int(cmd[2:])
            names = {v: k for k, v in FORMAT_NUMBERS[self.settings.numbering].items()}
            if number in names:
                self.format = names[number]
            else:
                self._reply(f"unknown event format {cmd}")
        elif cmd.startswith("!B") and "=" in cmd:
            key, _, value = cmd[2:].partition("=")
            with contextlib.suppress(ValueError):
                self.biases[int(key)] = int(value)
        elif cmd == c.flush_biases:
            pass
        elif cmd == c.help:
            self._reply("E+/- start/stop events; !Ex event format; !Bx=y bias; !BF flush biases; R reset")
        else:
            self._reply(f"?? {cmd}")

    def _start_stream(self, now: float) -> None:
        self.streaming = True
        if self._stream_start is not None:
            # Resumed after E-: the next event is due now (the device clock runs on meanwhile).
            if self._next < self.events.size:
                self._stream_start = now - (int(self.events["t"][self._next]) - self._t0) / 1e6 / self.speed
            return
        zero = self._zero
        if self._is_slave:
            # A slave counts on the master's clock (without a shared one: reset by the sync itself).
            if self._clock is not None:
                if self._clock.zero is None:
                    # The master's thread has not run its `!ETM+` yet (a loaded machine); a real slave's
                    # counter follows the master's sync line, so wait for the master's zero, not our own.
                    self._await_master = True
                    self._stream_start = self._clock.start if self._clock.start is not None else now
                    if self._clock.start is None:
                        self._clock.start = now
                    return
                zero = self._clock.zero
        if zero is None:
            zero = now - self.clock_offset_us / 1e6 / self.speed  # free-running: `clock_offset_us` at E+
        start = now
        if self._clock is not None:
            if self._clock.start is None:
                self._clock.start = now
            start = self._clock.start
        self._stream_start = start
        self.lead_us = round((start - zero) * self.speed * 1e6)

    def _due_events(self, now: float, budget: int) -> bytes:
        """Encode the events due by ``now`` (at most ``budget`` bytes), with garbage at a boundary."""
        if self._await_master and self._clock is not None and self._clock.zero is not None:
            self._await_master = False
            self.lead_us = round((self._stream_start - self._clock.zero) * self.speed * 1e6)
        if not self.streaming:  # garbage injected before the start command arrives waits for the stream
            return b""
        if now < self._stall_until or self._next >= self.events.size or self._await_master:
            with self._lock:
                garbage, self._garbage = b"".join(self._garbage), []
            self.garbage_bytes += len(garbage)
            return garbage
        fmt_size = ProtocolSettings(event_format=self.format).format.max_size
        t_due = self._t0 + (now - self._stream_start) * self.speed * 1e6
        hi = int(np.searchsorted(self.events["t"], t_due, side="right"))
        hi = min(hi, self._next + max(1, budget // fmt_size))
        out = b""
        with self._lock:
            garbage, self._garbage = b"".join(self._garbage), []
        if hi > self._next:
            chunk = self.events[self._next:hi].copy()
            self.late_us = max(self.late_us, round(t_due - int(chunk["t"][0])))
            chunk["t"] = chunk["t"] - self._t0 + self.lead_us
            s = ProtocolSettings(event_format=self.format, sync_bit_set=self.settings.sync_bit_set,
                                 off_bit_set=self.settings.off_bit_set, numbering=self.settings.numbering)
            out = encode_events(chunk, s, t_prev=self._t_prev)
            self._t_prev = int(chunk["t"][-1])
            self.sent_events += hi - self._next
            self._next = hi
        self.garbage_bytes += len(garbage)
        return garbage + out

    def _run(self) -> None:
        rate = self.baud / 10 * self.speed  # bytes per second the link carries
        line = b""
        credit_t = time.monotonic()
        try:
            while not self._quit.is_set():
                if self._disconnect:
                    self._close_fds()
                    return
                r, _, _ = select.select([self._master], [], [], TICK_S)
                if r:
                    try:
                        data = os.read(self._master, 4096)
                    except OSError:
                        data = b""
                    line += data
                    while True:
                        cut = min((i for i in (line.find(b"\n"), line.find(b"\r")) if i >= 0), default=-1)
                        if cut < 0:
                            break
                        self._handle(line[:cut].decode("ascii", "replace"))
                        line = line[cut + 1:]
                now = time.monotonic()
                # The link never carries more than `rate` bytes per second.
                budget = int((now - credit_t) * rate)
                if budget <= 0:
                    continue
                if len(self._pending) < budget:
                    self._pending += self._due_events(now, budget - len(self._pending))
                if not self._pending:
                    credit_t = now
                    continue
                try:
                    n = os.write(self._master, self._pending[:budget])
                except BlockingIOError:
                    n = 0
                self._pending = self._pending[n:]
                self.sent_bytes += n
                credit_t = max(credit_t + n / rate, now - 0.01)
        except OSError:
            return


def read_back(events: np.ndarray, *, settings: ProtocolSettings | None = None, timeout_s: float | None = None):
    """Play ``events`` on a virtual board in real time and read them back as ``record`` does (one board, its
    clock reset before streaming), until the board is done and has gone silent, or ``timeout_s`` (default:
    twice the stream's length plus 10 s) has passed.

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE, EDVS, VirtualEDVS
        The events decoded (times on the board's clock: the events' own, from ``t = 0``, plus the board's lead),
        the reader (its ``decoder`` and ``status()``) and the board (``done``: it sent every event).
    """
    from cvstereo.sensors.edvs import EDVS  # loads the decoder (numba) only when a stream is read

    if timeout_s is None:
        timeout_s = 2 * (int(events["t"][-1]) / 1e6 if events.size else 0) + 10
    board = VirtualEDVS(events, settings=settings, time_origin_us=0)
    got = []
    with board as port, EDVS(port, settings=settings) as reader:
        reader.configure()
        reader.reset_clock()
        reader.start()
        deadline = time.monotonic() + timeout_s
        while not (board.done and reader.silent) and time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                got.append(reader.queue.get(timeout=0.05).events)
        reader.stop()
        while not reader.queue.empty():
            got.append(reader.queue.get().events)
    return (np.concatenate(got) if got else events[:0]), reader, board
