"""The fingerprint of the events a matches file was computed on, so that it can tell its recording from another.

Per camera: the number of events, the first and the last time, and a checksum of the events as read (before
any rectification or rig correction). The checksum is the sum, modulo 2**64, of the camera's byte stream in the
packed event layout (:data:`~cvstereo.model.events.EVENT_DTYPE`, 13 bytes an event, little-endian) read as
little-endian 64-bit words, the last one padded with zeros: byte k of the stream adds ``b_k * 256**(k % 8)``.
It is computed packet by packet from each packet's offset in the stream, so it does not depend on how the
stream was cut, and costs one pass of a vectorised sum over memory the matcher reads anyway. It is a
checksum, not a cryptographic hash: it tells another recording, a clip, a shifted clock or a moved event
apart from the recording (any change of one event changes it), not a forgery made to collide.

Two recordings with the same events on clocks shifted by a constant have different checksums; :func:`difference`
recognises them by shifting the recording's times by the difference of the first times and checking again,
and says by how much the clocks differ.

>>> from cvstereo.model.events import make_events
>>> ev = make_events([0, 10, 20], [1, 2, 3], [4, 5, 6], [1, 0, 1])
>>> fp = EventFingerprint()
>>> fp.update(ev[:1], ev[:2])
>>> fp.update(ev[1:], ev[2:])
>>> fp.result() == fingerprint_of(Recording(ev, ev))
True
>>> late = make_events([1_000_000, 1_000_010, 1_000_020], [1, 2, 3], [4, 5, 6], [1, 0, 1])
>>> print(difference(fp.result(), Recording(late, late)))
the same events on another clock: the clocks differ by 1 s (this recording's times are 1 s later)
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from cvstereo.model.events import EVENT_DTYPE, as_events
from cvstereo.model.recording import Recording

__all__ = ["CAMERAS", "CHECKSUM", "EventFingerprint", "difference", "fingerprint_of", "fingerprint_of_stream",
           "is_fingerprint_of_stream", "stream_sum", "swap_cameras"]

#: Name of the checksum stored with the fingerprint; a file with another cannot be checked by this version.
CHECKSUM = "sum64-le"
#: Bytes per checksum word.
_WORD = 8
_MOD = 1 << 64
CAMERAS = ("left", "right")


class _Camera:
    """The running fingerprint of one camera's stream."""

    __slots__ = ("events", "t_first", "t_last", "total")

    def __init__(self):
        self.events, self.t_first, self.t_last, self.total = 0, None, None, 0

    def add(self, events: np.ndarray) -> None:
        if not events.size:
            return
        if events.dtype != EVENT_DTYPE:
            events = as_events(events, resolution=None)
        raw = np.ascontiguousarray(events).view(np.uint8)
        self.total = (self.total + stream_sum(raw, self.events * EVENT_DTYPE.itemsize)) % _MOD
        if self.t_first is None:
            self.t_first = int(events["t"][0])
        self.t_last = int(events["t"][-1])
        self.events += int(events.size)

    def result(self) -> dict:
        return {"events": self.events, "t_first": self.t_first, "t_last": self.t_last,
                "checksum": f"{self.total:016x}"}


def stream_sum(raw: np.ndarray, offset: int) -> int:
    """The checksum's share of the bytes ``raw`` at byte ``offset`` of a stream: sum of ``b_k * 256**(k % 8)``
    over their stream positions k, modulo 2**64.

    The bytes up to the next word boundary of the stream and after the last whole word are added one by one;
    the whole words between them in one vectorised sum (little-endian, so the same on every machine).
    """
    head = min((-offset) % _WORD, raw.size)
    total = sum(int(b) << (8 * ((offset + i) % _WORD)) for i, b in enumerate(raw[:head].tolist()))
    body = raw[head:]
    whole = body.size - body.size % _WORD
    if whole:
        total += int(np.add.reduce(body[:whole].view("<u8"), dtype=np.uint64))
    total += sum(int(b) << (8 * j) for j, b in enumerate(body[whole:].tolist()))
    return total % _MOD


class EventFingerprint:
    """The fingerprint of a stereo stream, fed packet by packet (:meth:`update`), any cut giving the same."""

    def __init__(self):
        self._cameras = (_Camera(), _Camera())

    def update(self, left: np.ndarray, right: np.ndarray) -> None:
        """Add the next packet's events of both cameras (time-ordered, in stream order)."""
        self._cameras[0].add(left)
        self._cameras[1].add(right)

    def result(self) -> dict:
        """``{"checksum": CHECKSUM, "left": {...}, "right": {...}}``, each camera with ``events``, ``t_first``,
        ``t_last`` (None without events) and ``checksum`` (16 hex digits): JSON for a matches file's meta."""
        return {"checksum": CHECKSUM, **{name: cam.result() for name, cam in zip(CAMERAS, self._cameras,
                                                                                  strict=True)}}


def fingerprint_of(recording: Recording) -> dict:
    """The fingerprint of a recording in memory (:meth:`EventFingerprint.result`)."""
    fp = EventFingerprint()
    fp.update(recording.left, recording.right)
    return fp.result()


def fingerprint_of_stream(stream) -> dict:
    """The fingerprint of a stereo recording opened for streaming, read one chunk at a time.

    It is :func:`fingerprint_of` of the recording the stream reads, computed without holding that recording, so
    that a matches file can be checked against a recording larger than memory (a DSEC sequence).

    Parameters
    ----------
    stream : cvstereo.io.stream.RecordingStream
        A stereo stream (``stream.is_stereo``).
    """
    if not stream.is_stereo:
        raise ValueError("a fingerprint is taken of a stereo recording; this stream holds one camera")
    cameras = (_Camera(), _Camera())
    for cam, name in zip(cameras, CAMERAS, strict=True):
        for events, _ in stream.open_chunks(name):
            cam.add(events)
    return {"checksum": CHECKSUM, **{name: cam.result() for name, cam in zip(CAMERAS, cameras, strict=True)}}


def is_fingerprint_of_stream(stored, stream) -> bool:
    """Whether ``stored`` (a matches file's ``meta["fingerprint"]``) is the fingerprint of ``stream``'s events.

    False for anything else, a fingerprint this version cannot read included: the caller then reads the
    recording whole and lets :func:`difference` say what differs, which only a mismatch pays for.
    """
    if not isinstance(stored, Mapping) or stored.get("checksum") != CHECKSUM or not stream.is_stereo:
        return False
    own = fingerprint_of_stream(stream)
    return all(own[c] == stored.get(c) for c in CAMERAS)


def swap_cameras(fingerprint: Mapping) -> dict:
    """The fingerprint with its cameras exchanged (that of the recording with left and right swapped)."""
    return {**fingerprint, "left": fingerprint["right"], "right": fingerprint["left"]}


def difference(stored: Mapping, recording: Recording) -> str | None:
    """Why ``recording`` is not the one a fingerprint was taken of, in words; None when it is.

    Raises
    ------
    ValueError
        ``stored`` is not a fingerprint this version reads (another checksum, missing or malformed fields).
    """
    if not isinstance(stored, Mapping) or stored.get("checksum") != CHECKSUM:
        raise ValueError("its fingerprint of the recording is not one this cvstereo reads (checksum "
                         f"{repr(stored.get('checksum') if isinstance(stored, Mapping) else stored)[:40]})")
    try:
        want = [(int(stored[c]["events"]), _time(stored[c]["t_first"]), int(stored[c]["checksum"], 16))
                for c in CAMERAS]
    except (KeyError, TypeError, ValueError):
        raise ValueError("its fingerprint of the recording is malformed (each camera needs events, t_first, "
                         "t_last and checksum)") from None
    own = fingerprint_of(recording)
    if all(own[c] == stored[c] for c in CAMERAS):
        return None
    cams = [recording.left, recording.right]
    counts = [ev.size for ev in cams]
    if counts != [n for n, _, _ in want]:
        return (f"it was computed on {want[0][0]:,} + {want[1][0]:,} events (left + right), this recording has "
                f"{counts[0]:,} + {counts[1]:,}")
    shifts = {t_first - int(ev["t"][0]) for ev, (_, t_first, _) in zip(cams, want, strict=True) if ev.size}
    if len(shifts) == 1 and (shift := shifts.pop()) != 0 and all(
            _shifted_sum(ev, shift) == total for ev, (_, _, total) in zip(cams, want, strict=True)):
        s = f"{abs(shift) / 1e6:.6g} s"
        return (f"the same events on another clock: the clocks differ by {s} (this recording's times are {s} "
                f"{'later' if shift < 0 else 'earlier'})")
    what = [f"the {c} camera's {'times' if own[c]['t_first'] != stored[c]['t_first'] else 'events'}"
            for c in CAMERAS if own[c] != stored[c]]
    return f"as many events, but other ones ({' and '.join(what)} differ)"


def _time(value) -> int | None:
    """A stored first time: a whole number of microseconds or None (no events)."""
    if value is None or (isinstance(value, int) and not isinstance(value, bool)):
        return value
    raise TypeError(f"not a time: {value!r}")


def _shifted_sum(events: np.ndarray, shift: int) -> int:
    """The checksum of ``events`` with ``shift`` added to every time (modulo 2**64, as int64 wraps)."""
    moved = np.array(events, dtype=EVENT_DTYPE)
    moved["t"] = (moved["t"].view(np.uint64) + np.uint64(shift % _MOD)).view(np.int64)
    return stream_sum(moved.view(np.uint8), 0)
