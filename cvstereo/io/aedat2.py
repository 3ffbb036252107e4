"""jAER AEDAT 2.0 files of DVS128 sensors (mono, or a stereo pair in one file): chunked reading, writing.

A file is ``#``-comment header lines (the first is ``#!AER-DAT2.0``, each ends in CRLF), then records of
a big-endian uint32 address and a big-endian uint32 timestamp in microseconds. The DVS128 address
(formats.md, after jAER's ``DVS128.Extractor`` and ``Stereopsis``):

======  =====================================================================================
bit 0   raw polarity, 0 = ON (jAER flips it): ``p = 1 - raw``
1-7     raw x: ``x = 127 - raw x`` (x as the sensor sees the scene)
8-14    raw y: ``y = 127 - raw y`` (jAER draws y = 0 at the bottom; ours is at the top)
15      set = right eye of a stereo pair
16-30   zero for a DVS128; anything else is another chip and is rejected, not mis-decoded
31      set = special (sync) event: not a pixel. Skipped, **counted** in ``meta["special_events"]``
======  =====================================================================================

>>> decode_addresses(np.array([0x00008F03], np.uint32))  # right eye, x 126, y 112, OFF
(array([1], dtype=uint8), array([126]), array([112]), array([0]))

A file whose pixel events all have bit 15 clear is a mono recording: opened alone it yields a
single-camera stream; two mono files (left, right) make a stereo recording. Timestamps that go
backwards (jAER's 32-bit clock wraps after 71.6 minutes and restarts when a recording is reset) raise an
error naming the byte offset; nothing is reordered.
"""

from __future__ import annotations

import datetime
import os
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.atomic import atomic_path
from cvstereo.io.files import open_regular, printable
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.events import EVENT_DTYPE, empty_events, validate_events
from cvstereo.model.recording import CAMERAS, Recording

MAGIC = b"#!AER-DAT2.0"
#: The DVS128 sensor size, fixed by the 7-bit address fields.
RESOLUTION = (128, 128)
#: Records per chunk (8 bytes each).
CHUNK_RECORDS = 1 << 16

RECORD_DTYPE = np.dtype([("addr", ">u4"), ("t", ">u4")])
SPECIAL_BIT = np.uint32(1 << 31)
RIGHT_EYE_BIT = np.uint32(1 << 15)
_FOREIGN_BITS = np.uint32(0x7FFF0000)  # bits 16-30: never set by a DVS128
_EYES = {None: None, "left": 0, "right": 1}


def decode_addresses(addresses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split DVS128 pixel addresses into eye, x, y and polarity (our convention; table above).

    Parameters
    ----------
    addresses : (N,) uint32 ndarray
        Pixel addresses (bit 31 clear).

    Returns
    -------
    eye : (N,) uint8 ndarray
        0 left (or mono), 1 right.
    x, y : (N,) int ndarray
        Column (0 = left as the sensor sees the scene) and row (0 = top).
    p : (N,) int ndarray
        1 ON, 0 OFF.
    """
    a = np.asarray(addresses, np.uint32).astype(np.int64)
    eye = ((a >> 15) & 1).astype(np.uint8)
    return eye, 127 - ((a >> 1) & 0x7F), 127 - ((a >> 8) & 0x7F), 1 - (a & 1)


def encode_addresses(events: np.ndarray, eye: np.ndarray | int = 0) -> np.ndarray:
    """The DVS128 addresses of events (inverse of :func:`decode_addresses`).

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        Coordinates within 128x128.
    eye : int or (N,) ndarray
        0 left (or mono), 1 right.

    Returns
    -------
    (N,) uint32 ndarray
    """
    x, y, p = (events[f].astype(np.uint32) for f in ("x", "y", "p"))
    return ((np.asarray(eye, np.uint32) << 15) | ((127 - y) << 8) | ((127 - x) << 1) | (1 - p)).astype(np.uint32)


@dataclass(frozen=True)
class AedatHeader:
    """The header of an AEDAT 2.0 file.

    Attributes
    ----------
    lines : tuple of str
        Header lines without line ends (the first is ``#!AER-DAT2.0``).
    data_offset : int
        Byte offset of the first record.
    records : int
        Number of complete 8-byte records after the header.
    """

    lines: tuple[str, ...]
    data_offset: int
    records: int


def read_aedat2_header(path: str | os.PathLike) -> AedatHeader:
    """Read the header and check that the records are whole.

    Raises
    ------
    FileNotFoundError
    CorruptFileError
        Not an AEDAT 2.0 file (another version says which), or a truncated last record (byte offset).
    """
    # Regular files only: the size is taken from the file system and the records are read in a second pass.
    with open_regular(path) as fh:
        first = fh.readline()
        if not first.startswith(MAGIC):
            if first.startswith(b"#!AER-DAT"):
                version = printable(first.strip().decode("latin-1")[2:82])
                raise CorruptFileError(
                    f"{path}: {version} is not supported, only AER-DAT2.0; convert it to AEDAT 2.0 with jAER "
                    "or DV, or to .npz with dv-processing."
                )
            raise CorruptFileError(f"{path}: not an AEDAT 2.0 file (the first line is not '#!AER-DAT2.0').")
        lines = [first]
        # Header lines are those that start with '#'; the first record follows the last of them. A DVS128
        # address starts with byte 0x00 or 0x80 (special), never '#', so this cannot swallow a record.
        while fh.peek(1)[:1] == b"#":
            lines.append(fh.readline())
        offset = fh.tell()
    size = os.path.getsize(path)
    records, rest = divmod(size - offset, RECORD_DTYPE.itemsize)
    if rest:
        raise CorruptFileError(
            f"{path}: truncated: the last record, at byte offset {offset + records * RECORD_DTYPE.itemsize}, has "
            f"{rest} of {RECORD_DTYPE.itemsize} bytes (the recording was cut short); the {records} whole records "
            "before it can be kept by cutting the file at that offset."
        )
    return AedatHeader(tuple(ln.rstrip(b"\r\n").decode("latin-1") for ln in lines), offset, records)


def _iter_records(path, header: AedatHeader, chunk_records: int) -> Iterator[tuple[np.ndarray, int]]:
    """Yield ``(records, index of the first)`` in chunks, checking for foreign (non-DVS128) addresses."""
    if chunk_records <= 0:
        raise ValueError(f"chunk_records must be positive, got {chunk_records}.")
    with open_regular(path) as fh:
        fh.seek(header.data_offset)
        done = 0
        while done < header.records:
            n = min(chunk_records, header.records - done)
            records = np.frombuffer(fh.read(n * RECORD_DTYPE.itemsize), RECORD_DTYPE)
            if records.size != n:
                raise CorruptFileError(f"{path}: ends early, at byte offset {_offset(header, done + records.size)}.")
            foreign = np.flatnonzero(((records["addr"] & SPECIAL_BIT) == 0) & ((records["addr"] & _FOREIGN_BITS) != 0))
            if foreign.size:
                k = done + int(foreign[0])
                raise CorruptFileError(
                    f"{path}: address 0x{int(records['addr'][foreign[0]]):08X} at byte offset {_offset(header, k)} "
                    "has bits 16-30 set, so it is not a DVS128 pixel; this reader decodes DVS128 / eDVS128 "
                    "recordings only (export other chips' events to another format)."
                )
            yield records, done
            done += n


def _offset(header: AedatHeader, record: int) -> int:
    return header.data_offset + record * RECORD_DTYPE.itemsize


@dataclass(frozen=True)
class AedatScan:
    """Counts from one pass over an AEDAT 2.0 file.

    Attributes
    ----------
    header : AedatHeader
    special : int
        Special (sync) events, skipped by the readers.
    left, right : int
        Pixel events with the right-eye bit clear / set.
    """

    header: AedatHeader
    special: int
    left: int
    right: int


def scan_aedat2(path: str | os.PathLike, *, chunk_records: int = CHUNK_RECORDS) -> AedatScan:
    """Count special and per-eye pixel events in one streaming pass."""
    header = read_aedat2_header(path)
    special = right = 0
    for records, _ in _iter_records(path, header, chunk_records):
        is_special = (records["addr"] & SPECIAL_BIT) != 0
        special += int(is_special.sum())
        right += int((~is_special & ((records["addr"] & RIGHT_EYE_BIT) != 0)).sum())
    return AedatScan(header, special, header.records - special - right, right)


def iter_aedat2_chunks(path: str | os.PathLike, *, eye: str | None = None,
                       chunk_records: int = CHUNK_RECORDS) -> Iterator[np.ndarray]:
    """Stream pixel events of an AEDAT 2.0 file, validated, with bounded memory.

    Parameters
    ----------
    path : path-like
    eye : {None, "left", "right"}, keyword-only
        None: every pixel event (a mono file). ``"left"`` / ``"right"``: the events with the right-eye
        bit clear / set (a stereo pair in one file).
    chunk_records : int, keyword-only
        Records read per chunk.

    Yields
    ------
    (N,) ndarray of EVENT_DTYPE
        Special events are skipped (count them with :func:`scan_aedat2`).

    Raises
    ------
    CorruptFileError
        Not AEDAT 2.0, truncated record, non-DVS128 address (each with the byte offset).
    EventFormatError
        A timestamp earlier than the one before (the byte offset is named).
    """
    if eye not in _EYES:
        raise ValueError(f"eye must be None, 'left' or 'right', got {eye!r}.")
    header = read_aedat2_header(path)
    check = ChunkChecker(resolution=RESOLUTION, source=str(path) if eye is None else f"{path} [{eye} eye]")
    for records, first in _iter_records(path, header, chunk_records):
        addr = records["addr"]
        keep = (addr & SPECIAL_BIT) == 0
        if eye is not None:
            keep &= ((addr & RIGHT_EYE_BIT) != 0) == (eye == "right")
        index = np.flatnonzero(keep)
        if not index.size:
            continue
        raw = np.empty(index.size, EVENT_DTYPE)
        _, raw["x"], raw["y"], raw["p"] = decode_addresses(addr[index])
        raw["t"] = records["t"][index]
        yield check(raw, locate=_ByteLocator(header, first + index))


class _ByteLocator:
    """``locate(i)`` for :class:`ChunkChecker`: the byte offset of row ``i``'s record."""

    def __init__(self, header: AedatHeader, records: np.ndarray):
        self.header, self.records = header, records

    def __call__(self, i: int) -> str:
        k = int(self.records[i])
        return (f"record {k} at byte offset {_offset(self.header, k)}; jAER timestamps wrap after 2**32 us and "
                "restart when a recording is reset: this reader does not reorder them, cut the file there")


def open_aedat2(path: str | os.PathLike, right: str | os.PathLike | None = None, *,
                chunk_records: int = CHUNK_RECORDS) -> RecordingStream:
    """Open AEDAT 2.0 recording(s) for streaming.

    Parameters
    ----------
    path : path-like
        A stereo pair in one file (the right-eye bit splits the cameras), a mono file, or, with
        ``right``, the left camera's mono file.
    right : path-like, optional
        The right camera's mono file.
    chunk_records : int, keyword-only

    Returns
    -------
    RecordingStream
        Stereo (cameras left, right) for a stereo file or two mono files; a single camera
        (``"mono"``) for one mono file. ``meta["special_events"]`` counts the skipped special events.

    Raises
    ------
    ValueError
        With ``right``: a file holding both eyes (give it alone).
    """
    paths = [path] if right is None else [path, right]
    scans = [scan_aedat2(p, chunk_records=chunk_records) for p in paths]
    meta = {"source": "jAER AEDAT 2.0", "special_events": sum(s.special for s in scans)}
    if right is None:
        stereo = scans[0].right > 0
        names, selection = (CAMERAS, [(path, "left"), (path, "right")]) if stereo else ((MONO,), [(path, None)])
    else:
        for p, s in zip(paths, scans, strict=True):
            if s.left and s.right:
                raise ValueError(
                    f"{p} holds both eyes of a stereo pair ({s.left} left, {s.right} right events); "
                    "open it alone, without a second file."
                )
        names, selection = CAMERAS, [(path, None), (right, None)]
    by_name = dict(zip(names, selection, strict=True))
    meta["stereo_in_one_file"] = right is None and len(names) == 2

    def open_chunks(camera: str) -> Iterator[Chunk]:
        p, eye = by_name[camera]
        for events in iter_aedat2_chunks(p, eye=eye, chunk_records=chunk_records):
            yield events, None

    return RecordingStream("aedat2", tuple(str(p) for p in paths), names, RESOLUTION, meta, False, open_chunks)


def read_aedat2(path: str | os.PathLike, right: str | os.PathLike | None = None, **options) -> Recording:
    """Read a stereo AEDAT 2.0 recording whole (one stereo file, or two mono files); see :func:`open_aedat2`."""
    return open_aedat2(path, right, **options).read()


def read_aedat2_events(path: str | os.PathLike, *, eye: str | None = None) -> np.ndarray:
    """Read the pixel events of one file whole, as a single camera (see :func:`iter_aedat2_chunks`).

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE
    """
    return np.concatenate([empty_events(), *iter_aedat2_chunks(path, eye=eye)])


def write_aedat2(path: str | os.PathLike, recording: Recording) -> None:
    """Write a stereo recording as one AEDAT 2.0 file, the right camera flagged by bit 15 (atomically)."""
    events = np.concatenate([recording.left, recording.right])
    eyes = np.repeat(np.array([0, 1], np.uint32), [recording.left.size, recording.right.size])
    # One clock, one stream: jAER expects the records of both eyes interleaved in time order.
    order = np.argsort(events["t"], kind="stable")
    _write(path, events[order], eyes[order], resolution=recording.resolution)


def write_aedat2_events(path: str | os.PathLike, events: np.ndarray, *, eye: str = "left") -> None:
    """Write one camera's events as a mono AEDAT 2.0 file (atomically).

    Parameters
    ----------
    eye : {"left", "right"}, keyword-only
        ``"right"`` sets bit 15 in every address (as the right eye of a stereo pair would).
    """
    if eye not in ("left", "right"):
        raise ValueError(f"eye must be 'left' or 'right', got {eye!r}.")
    _write(path, events, np.uint32(_EYES[eye]), resolution=RESOLUTION)


def _write(path, events: np.ndarray, eyes, *, resolution) -> None:
    if tuple(resolution) != RESOLUTION:
        raise ValueError(f"AEDAT 2.0 DVS128 addresses hold 128x128 pixels; this recording is "
                         f"{resolution[0]}x{resolution[1]}. Write .npz instead.")
    validate_events(events, resolution=RESOLUTION, source=f"writing {path}")
    t = events["t"]
    if t.size and (t[0] < 0 or t[-1] >= 2**32):
        raise ValueError(f"writing {path}: timestamps must lie in 0..2**32-1 us for AEDAT 2.0, got "
                         f"{int(t[0])}..{int(t[-1])}; shift them (events['t'] -= events['t'][0]).")
    records = np.empty(events.size, RECORD_DTYPE)
    records["addr"] = encode_addresses(events, eyes)
    records["t"] = t
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    header = [
        MAGIC.decode(),
        "# This is a raw AE data file created by cvstereo (DVS128 addresses; bit 15 = right eye)",
        "# Data format is int32 address, int32 timestamp (8 bytes total), repeated for each event",
        "# Timestamps tick is 1 us",
        f"# created {stamp}",
    ]
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write("".join(line + "\r\n" for line in header).encode("ascii"))
        fh.write(records.tobytes())


__all__ = ["MAGIC", "RECORD_DTYPE", "RESOLUTION", "AedatHeader", "AedatScan", "decode_addresses", "encode_addresses",
           "iter_aedat2_chunks", "open_aedat2", "read_aedat2", "read_aedat2_events", "read_aedat2_header",
           "scan_aedat2", "write_aedat2", "write_aedat2_events"]
