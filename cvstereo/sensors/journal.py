"""An append-only journal of live events, flushed at least every second, convertible to a recording.

Layout: the line ``CVSJOURNAL1``, one line of JSON (meta), then records of a little-endian header
``camera (uint8), count (uint32)`` followed by ``count`` events of EVENT_DTYPE. A crash can cut only the
last record short; :func:`read_journal` keeps everything before it.
"""

from __future__ import annotations

import json
import mmap
import os
import stat
import struct
import time
from pathlib import Path

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.model.events import EVENT_DTYPE
from cvstereo.model.recording import Recording
from cvstereo.model.sensor_size import DEFAULT_RESOLUTION

__all__ = ["FLUSH_EVERY_S", "MAGIC", "MAX_HEADER_BYTES", "Journal", "is_journal", "journal_exists_message",
           "read_journal"]

MAGIC = b"CVSJOURNAL1\n"
_HEAD = struct.Struct("<BI")

#: Longest time events wait in memory before reaching the disk, s.
FLUSH_EVERY_S = 1.0

#: Longest header line accepted (the meta JSON of a journal is a few hundred bytes).
MAX_HEADER_BYTES = 1 << 20


class Journal:
    """Append events of camera 0 (left) / 1 (right) to ``path``.

    Parameters
    ----------
    path : path-like
        Created; an existing file is never replaced (FileExistsError: it may be a journal left by a crash,
        or any other file).
    meta : dict
        Stored in the header; ends up in the recording's meta.
    flush_every_s : float
        Events reach the disk (flush + fsync) at least this often, provided :meth:`append` or
        :meth:`maybe_flush` is called; a crash loses at most this much.
    """

    def __init__(self, path: str | os.PathLike, meta: dict | None = None, *, flush_every_s: float = FLUSH_EVERY_S):
        self.path = Path(path)
        self.flush_every_s = float(flush_every_s)
        try:
            self._fh = open(self.path, "xb")  # kept open for the journal's lifetime
        except FileExistsError:
            raise FileExistsError(journal_exists_message(self.path)) from None
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


def is_journal(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a regular file starting as a cvstereo journal does."""
    try:
        with open(path, "rb") as fh:
            return stat.S_ISREG(os.fstat(fh.fileno()).st_mode) and fh.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def journal_exists_message(path: str | os.PathLike) -> str:
    """Why an existing ``path`` is not taken as a new journal, and what to do."""
    if is_journal(path):
        return f"journal {path} exists: recover it with --from-journal or delete it"
    return f"journal {path}: the file exists and is not a cvstereo journal; give a path that does not exist"


def read_journal(path: str | os.PathLike) -> tuple[Recording, int]:
    """Read a journal into a :class:`Recording`; also return the bytes of a cut-short last record.

    Raises
    ------
    FileNotFoundError, CorruptFileError
    """
    path = Path(path)
    try:
        st = os.stat(path)  # before opening: opening a FIFO would wait for a writer
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such journal.") from None
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(f"{path}: is a directory, not a journal.")
    if not stat.S_ISREG(st.st_mode):
        raise CorruptFileError(f"{path}: not a regular file (a device or FIFO); a journal is a file on disk.")
    if st.st_size == 0:
        raise CorruptFileError(f"{path}: empty file, not a cvstereo journal.")
    with open(path, "rb") as fh:
        data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    try:
        return _parse(path, data)
    finally:
        data.close()


def _parse(path: Path, data) -> tuple[Recording, int]:
    if data[:len(MAGIC)] != MAGIC:
        raise CorruptFileError(f"{path}: not a cvstereo journal (it does not start with {MAGIC!r}).")
    nl = data.find(b"\n", len(MAGIC), len(MAGIC) + MAX_HEADER_BYTES)
    if nl < 0:
        if len(data) > len(MAGIC) + MAX_HEADER_BYTES:
            raise CorruptFileError(f"{path}: journal header longer than {MAX_HEADER_BYTES} bytes; not a journal "
                                   "written by cvstereo.")
        raise CorruptFileError(f"{path}: the journal header is cut short; nothing was recorded.")
    try:
        meta = json.loads(data[len(MAGIC):nl])
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise CorruptFileError(f"{path}: journal header is not JSON ({exc}).") from None
    if not isinstance(meta, dict):
        raise CorruptFileError(f"{path}: journal header holds a JSON {type(meta).__name__}, not an object "
                               "(the meta of the recording).")
    parts: list[list[np.ndarray]] = [[], []]
    pos = nl + 1
    size = EVENT_DTYPE.itemsize
    while pos + _HEAD.size <= len(data):
        cam, count = _HEAD.unpack_from(data, pos)
        end = pos + _HEAD.size + count * size
        if cam > 1:
            # A crash cuts only the last record short; a wrong camera id is damage, not a crash.
            raise CorruptFileError(f"{path}: the journal record at byte {pos} names camera {cam} (0 = left or "
                                   "1 = right expected); the file is damaged.")
        if end > len(data):
            break
        parts[cam].append(np.frombuffer(data, EVENT_DTYPE, count, pos + _HEAD.size).copy())
        pos = end
    lost = len(data) - pos
    cams = [np.concatenate(p) if p else np.zeros(0, EVENT_DTYPE) for p in parts]
    meta = dict(meta)
    meta["journal_truncated_bytes"] = lost
    try:
        # The cameras' resolution, where the recorder stored it (DV cameras); else the eDVS128's, the default.
        resolution = tuple(meta["resolution"]) if "resolution" in meta else DEFAULT_RESOLUTION
        return Recording(cams[0], cams[1], resolution=resolution, meta=meta), lost
    except (ValueError, TypeError) as exc:
        raise CorruptFileError(f"{path}: {exc}") from None
