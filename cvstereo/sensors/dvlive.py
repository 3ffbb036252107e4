"""One camera's events through dv-processing (the ``dv`` extra): a DV network stream (``tcp://HOST:PORT``, what the
DV software and dv-processing's ``NetworkWriter`` publish) or a camera on USB (its serial number or name).

A :class:`DVSource` delivers its camera's events as an eDVS reader does (a queue of
:class:`~cvstereo.sensors.edvs.Chunk`: events in the project's event array, times as the camera gives them,
each chunk with the host time it arrived), so that :class:`~cvstereo.sensors.stereo.StereoRig` merges, bounds
and counts them the same way (docs/guide/live.md). Its resolution is the stream's own (its description).

:meth:`DVSource.open` connects (or opens the camera) and reads the stream's description; :meth:`DVSource.start`
reads the events. A network stream is connected again at :meth:`~DVSource.start`, so that the matcher can be
prepared meanwhile (its kernels compiled, which holds the interpreter): dv-processing's reader loses what it has
not been asked for when its writer leaves, and what a writer sent before the start would not be matched anyway.
A stream that ends (the writer stops, the connection drops) leaves its source :attr:`~DVSource.ended` with every
event it sent delivered and a one-line :attr:`~DVSource.error`; a stream that stays connected but sends nothing
goes silent, and the rig's bounded wait applies. Events that are out of the stream's resolution, or earlier
than the one before them, stop the source with an error naming the event (a matcher would misplace them).
"""

from __future__ import annotations

import queue
import socket
import threading
import time

import numpy as np

from cvstereo.errors import SensorError
from cvstereo.model.events import EVENT_DTYPE, check_resolution
from cvstereo.sensors.edvs import DEFAULT_SILENCE_S, Chunk, host_us

__all__ = ["BEHIND_US", "DV_SCHEME", "POLL_S", "DVSource", "dv_sources", "parse_dv_address"]

#: The prefix of a DV network stream's address; anything else names a camera.
DV_SCHEME = "tcp://"

#: Wait between looks at a stream that had nothing new, s (dv-processing's batch call does not block).
POLL_S = 0.001

#: A reader thread that has not looked at its stream for this long is behind (a busy machine), us: until it looks
#: again, its camera is not taken as silent (see :attr:`DVSource.last_byte_us`).
BEHIND_US = 20_000

#: dv-processing's name of each event field (its EventStore's numpy() record).
_DV_FIELDS = {"t": "timestamp", "x": "x", "y": "y", "p": "polarity"}


def _dv():
    """dv-processing, or an ImportError naming the extra (the seam the tests replace with a fake camera)."""
    try:
        import dv_processing
    except ImportError:
        raise ImportError("live input from DV cameras and streams needs dv-processing: pip install "
                          "'cvstereo[dv]'") from None
    return dv_processing


def _reason(exc: BaseException) -> str:
    """dv-processing's message without the C++ source location it appends in brackets."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text.split(" [", 1)[0]


def parse_dv_address(text: str) -> tuple[str, int] | None:
    """``tcp://HOST:PORT`` -> (HOST, PORT); None for anything else (a camera's serial number or name).

    Raises
    ------
    ValueError
        A ``tcp://`` address without a host or without a port number 1..65535.
    """
    if not text.startswith(DV_SCHEME):
        return None
    host, _, port = text[len(DV_SCHEME):].rpartition(":")
    host = host.strip("[]")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"{text}: a DV network stream is tcp://HOST:PORT with a port number 1..65535 (e.g. "
                         "tcp://127.0.0.1:7777)")
    return host, int(port)


def _network_reader(dv, host: str, port: int):
    """A NetworkReader on HOST:PORT; the host name is resolved here, since dv-processing takes numeric addresses
    only (a name it refuses as an invalid argument)."""
    try:
        address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][4][0]
    except socket.gaierror as exc:
        raise ConnectionError(f"unknown host {host!r}: {exc.strerror}") from None
    return dv.io.NetworkReader(address, port)


class _Cameras:
    """The cameras named by a rig, opened together on first use: two cameras that can be synchronised
    (``openSync``) are, by dv-processing's ``synchronizeAnyTwo``; otherwise each is opened alone."""

    def __init__(self, names: list[str]):
        self.names = names
        self.opened: dict[str, object] = {}

    def open(self, dv, name: str):
        if not self.opened:
            found = {}
            for desc in dv.io.camera.discover():
                found[desc.serialNumber] = found[f"{desc.cameraModel}_{desc.serialNumber}"] = desc
            for n in self.names:
                if n not in found:
                    listed = sorted({f"{d.cameraModel}_{d.serialNumber}" for d in found.values()}) or ["none"]
                    raise ConnectionError(f"no camera {n!r} connected (found: {', '.join(listed)})")
            descs = [found[n] for n in self.names]
            if len(descs) == 2:
                try:
                    pair = [dv.io.camera.openSync(d) for d in descs]
                    dv.io.camera.synchronizeAnyTwo(*pair)
                except RuntimeError:  # a model without the sync connector: each on its own clock
                    pair = [dv.io.camera.open(d) for d in descs]
                self.opened = dict(zip(self.names, pair, strict=True))
            else:
                self.opened = {self.names[0]: dv.io.camera.open(descs[0])}
        return self.opened[name]


class DVSource:
    """One camera's events through dv-processing, delivered as chunks with host arrival times.

    Parameters
    ----------
    where : str
        ``tcp://HOST:PORT`` (a DV network stream) or a camera's serial number or ``MODEL_SERIAL`` name.
    name : str, keyword-only
        Used in messages ("left", "right").
    silence_s : float, keyword-only
        A stream that delivers nothing for this long is reported silent.
    cameras : optional, keyword-only
        The rig's cameras opened together (:func:`dv_sources`); by default a camera is opened alone.

    Attributes
    ----------
    queue, silent, error, protocol, last_byte_us
        As :class:`~cvstereo.sensors.edvs.EDVS`'s (``protocol`` names the stream, ``last_byte_us`` is the host
        time the last batch arrived).
    resolution : (int, int)
        From the stream's description, once open.
    ended : bool
        The stream ended and every event it sent is in :attr:`queue`.
    """

    def __init__(self, where: str, *, name: str = "sensor", silence_s: float = DEFAULT_SILENCE_S, cameras=None):
        self.address = parse_dv_address(where)
        self.port = where
        self.name = name
        self.silence_s = float(silence_s)
        self._cameras = cameras if cameras is not None or self.address else _Cameras([where])
        self.queue: queue.Queue[Chunk] = queue.Queue()
        self.resolution: tuple[int, int] | None = None
        self.protocol: str | None = None
        self.silent = False
        self.silences = 0
        self.error: BaseException | None = None
        self.ended = False
        self.events = 0
        self._data_us: int | None = None  # host time the last batch was taken
        self._looked_us: int | None = None  # host time the reader last looked at the stream
        self._last_t: int | None = None
        self._reader = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def _what(self) -> str:
        return f"DV stream {self.port}" if self.address else f"DV camera {self.port}"

    def open(self) -> DVSource:
        """Connect (or open the camera) and read its description (:meth:`start` reads the events).

        Raises
        ------
        SensorError
            The host refuses or cannot be reached, the camera is not connected, the stream carries no events
            (frames or IMU only) or states no sensor's resolution; the message names the address.
        ImportError
            dv-processing is not installed (the message names the extra).
        """
        reader = self._connect()
        if not reader.isEventStreamAvailable():
            kinds = [k for k, f in (("frames", "isFrameStreamAvailable"), ("IMU", "isImuStreamAvailable"),
                                    ("triggers", "isTriggerStreamAvailable")) if getattr(reader, f)()]
            raise SensorError(f"{self.name} camera: {self._what()} carries no events (it carries "
                              f"{' and '.join(kinds) or 'nothing known'}); give the address of an event output.")
        try:
            self.resolution = check_resolution(tuple(reader.getEventResolution() or ()),
                                               source=f"{self.name} camera: {self._what()}'s resolution")
        except ValueError as exc:
            raise SensorError(str(exc)) from None
        width, height = self.resolution
        self.protocol = f"DV events of {reader.getCameraName() or 'an unnamed camera'}, {width}x{height}"
        # A camera streams from its opening on; a network stream is connected again at start().
        self._reader = None if self.address else reader
        return self

    def _connect(self):
        """dv-processing's reader of the stream or camera; a SensorError naming it if it cannot be opened."""
        dv = _dv()
        try:
            return _network_reader(dv, *self.address) if self.address else self._cameras.open(dv, self.port)
        except (RuntimeError, OSError) as exc:
            hint = ("check that the DV software or writer is running and publishes on that host and port" if
                    self.address else "check the cable and the serial number (dv-list-devices lists them)")
            raise SensorError(f"{self.name} camera: cannot open {self._what()} ({_reason(exc)}); {hint}.") from None

    def start(self) -> None:
        """Start reading the stream (a network stream is connected again: its events from now on).

        Raises
        ------
        SensorError
            The network stream cannot be connected again (its writer left since :meth:`open`).
        """
        if self._thread is not None or self.resolution is None:
            return
        if self._reader is None:
            self._reader = self._connect()
        self._data_us = self._looked_us = host_us()
        self._thread = threading.Thread(target=self._run, name=f"dv-{self.name}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop reading (what arrived so far is in :attr:`queue`)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def close(self) -> None:
        """Stop reading and let the connection (or camera) go."""
        self.stop()
        self._reader = None

    def __enter__(self) -> DVSource:
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def last_byte_us(self) -> int | None:
        """The host time of the last batch taken, as the rig's bounded wait reads it; while the reader thread is
        behind (it has not looked at the stream for :data:`BEHIND_US`: a busy machine did not run it), now: a
        reader that did not look proves no silence, so that its camera's events are delayed, not dropped late."""
        if self._looked_us is not None and host_us() - self._looked_us > BEHIND_US:
            return host_us()
        return self._data_us

    @property
    def running(self) -> bool:
        """The reader thread is alive (not stopped, not ended)."""
        return self._thread is not None and self._thread.is_alive()

    def _events(self, raw: np.ndarray) -> np.ndarray:
        """dv-processing's batch as the project's event array, after checking what a matcher relies on."""
        ev = np.empty(raw.shape[0], EVENT_DTYPE)
        for ours, theirs in _DV_FIELDS.items():
            ev[ours] = raw[theirs]
        width, height = self.resolution
        t = ev["t"]
        bad = (ev["x"] < 0) | (ev["x"] >= width) | (ev["y"] < 0) | (ev["y"] >= height)
        back = np.flatnonzero(np.diff(t, prepend=t[0] if self._last_t is None else self._last_t) < 0)
        if bad.any():
            i = int(np.argmax(bad))
            raise SensorError(f"{self.name} camera: {self._what()} sent event {self.events + i} at "
                              f"({ev['x'][i]}, {ev['y'][i]}), outside its {width}x{height} pixels; reading stopped.")
        if back.size:
            i = int(back[0])
            raise SensorError(f"{self.name} camera: {self._what()} sent event {self.events + i} at t={t[i]} us, "
                              f"earlier than the event before it; a camera's times must not go back "
                              "(reading stopped).")
        return ev

    def _take(self, reader) -> list[np.ndarray]:
        """Every batch the reader has now, as dv-processing's records, taken without pause: its reader drops
        packets when it is not asked for them fast enough, so the conversion waits until none is left."""
        raws = []
        while (batch := reader.getNextEventBatch()) is not None:
            raws.append(batch.numpy())
        return raws

    def _run(self) -> None:
        reader = self._reader
        try:
            while not self._stop.is_set():
                raws = self._take(reader)
                now = self._looked_us = host_us()
                if not raws:
                    if not reader.isRunning():
                        if not (raws := self._take(reader)):  # what came before the end
                            self.error = SensorError(f"{self.name} camera: {self._what()} ended (the writer "
                                                     "stopped or the connection dropped)")
                            break
                    else:
                        if not self.silent and (now - self._data_us) / 1e6 >= self.silence_s:
                            self.silent = True
                            self.silences += 1
                        time.sleep(POLL_S)
                        continue
                self._data_us = now
                self.silent = False
                raw = np.concatenate(raws) if len(raws) > 1 else raws[0]
                if raw.shape[0]:
                    ev = self._events(raw)
                    self.queue.put(Chunk(ev, now))
                    self.events += ev.size
                    self._last_t = int(ev["t"][-1])
        except (RuntimeError, OSError) as exc:
            self.error = SensorError(f"{self.name} camera: {self._what()} failed ({_reason(exc)})")
        except SensorError as exc:
            self.error = exc
        # Ended (or failed): nothing more will come, and everything read is in the queue.
        self.ended = self.error is not None
        self.silent = True

    def status(self) -> dict:
        """Counters for reports: events, silences, error (and the fields eDVS boards report)."""
        return {"port": self.port, "bytes": None, "events": self.events, "corrupt_bytes": 0, "ambiguous_wraps": 0,
                "protocol": self.protocol, "silences": self.silences, "silent": self.silent,
                "error": None if self.error is None else str(self.error)}


def dv_sources(left: str, right: str, *, silence_s: float = DEFAULT_SILENCE_S) -> list[DVSource]:
    """The two sources of a DV rig; two cameras on USB are opened together and synchronised where their model
    allows it (``openSync``), network streams are taken with the times their writers give."""
    names = [w for w in (left, right) if parse_dv_address(w) is None]
    cameras = _Cameras(names) if names else None
    return [DVSource(w, name=n, silence_s=silence_s, cameras=cameras)
            for n, w in zip(("left", "right"), (left, right), strict=True)]
