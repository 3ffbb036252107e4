"""An append-only journal of live events, flushed at least every second, convertible to a recording.

Layout: the line ``CVSJOURNAL1``, one line of JSON (meta), then records of a little-endian header
``camera (uint8), count (uint32)`` followed by ``count`` events of EVENT_DTYPE. A crash can cut only the
last record short; :func:`read_journal` keeps everything before it.
"""

from __future__ import annotations

import json
import os
import struct
import time
from pathlib import Path

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.events import EVENT_DTYPE
from cvstereo.recording import Recording

MAGIC = b"CVSJOURNAL1\n"
_HEAD = struct.Struct("<BI")

#: Longest time events wait in memory before reaching the disk, s.
FLUSH_EVERY_S = 1.0


class Journal:
    """Append events of camera 0 (left) / 1 (right) to ``path``.

    Parameters
    ----------
    path : path-like
        Created (or replaced).
    meta : dict
        Stored in the header; ends up in the recording's meta.
    flush_every_s : float
        Events reach the disk (flush + fsync) at least this often, provided :meth:`append` or
        :meth:`maybe_flush` is called; a crash loses at most this much.
    """

    def __init__(self, path: str | os.PathLike, meta: dict | None = None, *, flush_every_s: float = FLUSH_EVERY_S):
        self.path = Path(path)
        self.flush_every_s = float(flush_every_s)
        self._fh = open(self.path, "wb")  # kept open for the journal's lifetime
        self._fh.write(MAGIC + json.dumps(meta or {}, sort_keys=True).encode() + b"\n")
        self._last_flush = time.monotonic()
        self.counts = [0, 0]
        self.flush()

    def append(self, camera: int, events: np.ndarray) -> None:
        """Append time-ordered events of one camera."""
        if events.size:
            self._fh.write(_HEAD.pack(int(camera), int(events.size)))
            self._fh.write(np.ascontiguousarray(events, dtype=EVENT_DTYPE).tobytes())
            self.counts[camera] += int(events.size)
        self.maybe_flush()

    def maybe_flush(self) -> None:
        """Flush if the last flush is ``flush_every_s`` old."""
        if time.monotonic() - self._last_flush >= self.flush_every_s:
            self.flush()

    def flush(self) -> None:
        """Write buffered records through to the disk."""
        self._fh.flush()
        os.fsync(self._fh.fileno())
        self._last_flush = time.monotonic()

    def close(self) -> None:
        if not self._fh.closed:
            self.flush()
            self._fh.close()

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_journal(path: str | os.PathLike) -> tuple[Recording, int]:
    """Read a journal into a :class:`Recording`; also return the bytes of a cut-short last record.

    Raises
    ------
    FileNotFoundError, CorruptFileError
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such journal.")
    data = path.read_bytes()
    if not data.startswith(MAGIC):
        raise CorruptFileError(f"{path}: not a cvstereo journal (it does not start with {MAGIC!r}).")
    nl = data.find(b"\n", len(MAGIC))
    if nl < 0:
        raise CorruptFileError(f"{path}: the journal header is cut short; nothing was recorded.")
    try:
        meta = json.loads(data[len(MAGIC):nl])
    except json.JSONDecodeError as exc:
        raise CorruptFileError(f"{path}: journal header is not JSON ({exc}).") from None
    parts: list[list[np.ndarray]] = [[], []]
    pos = nl + 1
    size = EVENT_DTYPE.itemsize
    while pos + _HEAD.size <= len(data):
        cam, count = _HEAD.unpack_from(data, pos)
        end = pos + _HEAD.size + count * size
        if cam > 1 or end > len(data):
            break
        parts[cam].append(np.frombuffer(data, EVENT_DTYPE, count, pos + _HEAD.size).copy())
        pos = end
    lost = len(data) - pos
    cams = [np.concatenate(p) if p else np.zeros(0, EVENT_DTYPE) for p in parts]
    meta = dict(meta)
    meta["journal_truncated_bytes"] = lost
    return Recording(cams[0], cams[1], meta=meta), lost
