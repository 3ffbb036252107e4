"""Prophesee / Metavision event files: EVT 2.0, 2.1 and 3.0 ``.raw`` and CD ``.dat`` (one camera per file).

A stereo recording is two files, the left camera's and the right camera's (``open_prophesee(left, right)``);
a file opened alone gives a single-camera stream. Every file starts with an ASCII header of ``% key value``
lines (ended by ``% end`` or by the first line that does not start with ``% ``) that names the encoding
(``% format EVT3;height=720;width=1280`` or ``% evt 3.0``) and the sensor size; a ``.dat`` header says
``% Data file containing CD events`` and is followed by an event type byte and an event size byte (8). The
format is told from this header, never from the extension: the TUM lab's eDVS text files are also named
``.dat`` (:func:`sniff_prophesee` returns None for them).

Decoding (the ``prophesee`` extra), chosen by measurement on byte-exact files (bench/results/prophesee.md):
EVT 3.0 through the ``evt3`` package (faery's and expelliarmus' EVT 3.0 times go wrong once the 24-bit clock
has wrapped), EVT 2.0 and ``.dat`` through faery; EVT 2.1, which no registry decoder reads (faery stops with
"not yet implemented"), by a vectorised numpy decoder here (:func:`decode_evt21`), which needs no extra.
Files are decoded chunk by chunk, so memory stays bounded. Times are the sensor's microseconds as stored;
polarity 1 is ON (an increase of light).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from cvstereo.errors import CorruptFileError, MissingExtraError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.files import open_regular
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.events import check_resolution
from cvstereo.model.recording import CAMERAS

__all__ = ["ENCODINGS", "PropheseeHeader", "decode_evt21", "open_prophesee", "read_prophesee_header",
           "sniff_prophesee"]

#: Format names (the table of :mod:`cvstereo.io`) -> what the file's header calls them.
ENCODINGS = {"evt2": "EVT 2.0", "evt21": "EVT 2.1", "evt3": "EVT 3.0", "prophesee-dat": "Prophesee DAT"}
#: Bytes of one word of each encoding (the data after the header is a whole number of them).
WORD_BYTES = {"evt2": 4, "evt21": 8, "evt3": 2, "prophesee-dat": 8}
#: How much of the file's start may hold the header (real headers are well under 1 KB).
HEADER_LIMIT = 1 << 16
#: `.dat` event type bytes of change-detection events (EventCD, and the generic Event2d of older files).
DAT_CD_TYPES = (0x0C, 0x00)
DAT_EVENT_BYTES = 8
#: EVT 2.1 word types (bits 63..60): OFF and ON vectors, the time's high bits; the others (external trigger,
#: extensions) carry no CD events. Every other type is reserved, so a word of one is damage.
EVT21_OFF, EVT21_ON, EVT21_TIME_HIGH = 0x0, 0x1, 0x8
EVT21_OTHER_TYPES = (0xA, 0xE)
#: Bytes at the start of the data looked at for a fill (a zeroed or erased region): no event stream is one
#: byte value repeated.
FILL_PROBE = 4096
#: 64-bit words decoded at a time (8 MB of file per chunk).
CHUNK_WORDS = 1 << 20
_PRINTABLE = re.compile(rb"^[\x20-\x7e\t]*$")


@dataclass(frozen=True)
class PropheseeHeader:
    """What a Prophesee file's header says.

    Attributes
    ----------
    format : str
        One of :data:`ENCODINGS`.
    resolution : (width, height) or None
        None when the header does not say.
    data_offset : int
        Byte offset of the first event word (after the ``.dat`` type and size bytes).
    legacy_order : bool
        EVT 2.1 only: the header says ``endianness=legacy`` (each 64-bit word stored as its high 32-bit half,
        then its low half, both little-endian, as IMX636 sensors send it).
    """

    format: str
    resolution: tuple[int, int] | None
    data_offset: int
    legacy_order: bool = False


def _header_lines(head: bytes) -> tuple[list[str], int]:
    """The ``% `` lines at the start of ``head`` and the offset just after them (after ``% end`` if present)."""
    lines, pos = [], 0
    while head.startswith(b"% ", pos):
        end = head.find(b"\n", pos)
        if end < 0:
            break
        line = head[pos + 2:end].rstrip(b"\r")
        pos = end + 1
        if not _PRINTABLE.match(line):
            break
        lines.append(line.decode("ascii"))
        if line.strip() == b"end":
            break
    return lines, pos


def sniff_prophesee(head: bytes) -> str | None:
    """The Prophesee format of a file whose first bytes are ``head``, or None when it is no Prophesee file.

    A ``% `` header naming an EVT encoding (``% format EVT...`` / ``% evt X.Y``) is a ``.raw`` file; one saying
    ``% Data file containing ...`` (or ``% Version`` without an encoding) and followed by binary data is a
    ``.dat`` file. eDVS text files, whose comments start with ``#``, are never taken for either.
    """
    lines, _ = _header_lines(head)
    if not lines:
        return None
    encoding = _encoding(lines)
    if encoding is not None:
        return encoding
    keys = {line.split(" ", 1)[0].lower() for line in lines}
    if any(line.lower().startswith("data file containing") for line in lines) or "version" in keys:
        return "prophesee-dat"
    return None


def _encoding(lines: list[str]) -> str | None:
    """The EVT encoding a ``.raw`` header names (``format EVT3;...`` or ``evt 3.0``), or None."""
    names = {"evt2": "evt2", "evt2.0": "evt2", "evt21": "evt21", "evt2.1": "evt21", "evt3": "evt3",
             "evt3.0": "evt3"}
    for line in lines:
        key, _, value = line.partition(" ")
        if key.lower() == "format":
            return names.get(value.split(";")[0].strip().lower().replace(" ", ""), f"unknown '{value.split(';')[0]}'")
        if key.lower() == "evt":
            return names.get("evt" + value.strip().lower(), f"unknown 'evt {value.strip()}'")
    return None


def read_prophesee_header(path: str | os.PathLike, expected: str | None = None) -> PropheseeHeader:
    """Read and check a Prophesee file's header.

    Parameters
    ----------
    path : path-like
    expected : str, optional
        The format the caller was told (``--format``); the header must not name another.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        Missing, a directory, or not a regular file.
    CorruptFileError
        No Prophesee header, an unknown encoding, a header naming another format than ``expected``, a sensor
        size outside 1..2048, a ``.dat`` event type that is not CD or size that is not 8, or data that is not a
        whole number of words (a truncated file), data that starts with one byte value repeated (zeroed or
        erased). The message names the file and the format.
    """
    with open_regular(path) as fh:
        head = fh.read(HEADER_LIMIT)
        size = os.fstat(fh.fileno()).st_size
    what = ENCODINGS.get(expected, "Prophesee")
    found = sniff_prophesee(head)
    if found is None:
        raise CorruptFileError(f"{path}: not {what} data (no Prophesee '% ' header naming the format); "
                               "give the --format the file is in.")
    if found.startswith("unknown"):
        raise CorruptFileError(f"{path}: the Prophesee header names an {found[8:]} encoding; cvstereo reads "
                               f"{', '.join(ENCODINGS.values())}.")
    if expected is not None and found != expected:
        raise CorruptFileError(f"{path}: the header says {ENCODINGS[found]}, not {what}; drop --format or give "
                               f"--format {found}.")
    lines, offset = _header_lines(head)
    resolution = _header_resolution(path, lines, ENCODINGS[found])
    legacy = found == "evt21" and any("endianness=legacy" in line.lower() for line in lines)
    if found == "prophesee-dat":
        if len(head) < offset + 2:
            raise CorruptFileError(f"{path}: Prophesee DAT file ends inside its header (no event type and size "
                                   "bytes); the file is truncated.")
        kind, event_bytes = head[offset], head[offset + 1]
        if kind not in DAT_CD_TYPES or event_bytes != DAT_EVENT_BYTES:
            raise CorruptFileError(f"{path}: Prophesee DAT event type 0x{kind:02x} of {event_bytes} bytes; cvstereo "
                                   f"reads CD events (type 0x0c, {DAT_EVENT_BYTES} bytes).")
        offset += 2
    probe = head[offset:offset + FILL_PROBE]
    if len(probe) >= 2 * WORD_BYTES[found] and probe.count(probe[:1]) == len(probe):
        raise CorruptFileError(f"{path}: {ENCODINGS[found]} data starts with {len(probe)} bytes of 0x{probe[0]:02x} "
                               "(a zeroed or erased region, no events); the file is damaged.")
    spare = (size - offset) % WORD_BYTES[found]
    if spare:
        raise CorruptFileError(f"{path}: {ENCODINGS[found]} data is not a whole number of "
                               f"{WORD_BYTES[found]}-byte words ({spare} bytes left over at the end); the file is "
                               "truncated.")
    return PropheseeHeader(found, resolution, offset, legacy)


def _header_resolution(path, lines: list[str], what: str) -> tuple[int, int] | None:
    """The sensor size the header states (``geometry WxH``, ``format ...;height=H;width=W``, ``Width``/``Height``)."""
    fields: dict[str, str] = {}
    for line in lines:
        key, _, value = line.partition(" ")
        key = key.lower()
        if key == "geometry" and "x" in value:
            fields["width"], _, fields["height"] = value.strip().partition("x")
        elif key == "format":
            for part in value.split(";")[1:]:
                name, _, number = part.partition("=")
                fields.setdefault(name.strip().lower(), number.strip())
        elif key in ("width", "height"):
            fields.setdefault(key, value.strip())
    if "width" not in fields or "height" not in fields:
        return None
    try:
        size = (int(fields["width"]), int(fields["height"]))
    except ValueError:
        raise CorruptFileError(f"{path}: {what} header gives the size '{fields['width']}x{fields['height']}', "
                               "not two whole numbers.") from None
    return check_resolution(size, source=f"{path}: {what} header size", error=CorruptFileError)


#: The registry package that decodes each format (the ``prophesee`` extra installs them).
DECODERS = {"evt2": "faery", "evt3": "evt3", "prophesee-dat": "faery", "evt21": None}


def _decoder_module(fmt: str):
    """The decoder package of format ``fmt``, or an error naming the extra that installs it."""
    name = DECODERS[fmt]
    try:
        return __import__(name)
    except ImportError as exc:
        raise MissingExtraError(f"reading {ENCODINGS[fmt]} files needs the package '{name}': "
                                "pip install 'cvstereo[prophesee]'") from exc


def _registry_columns(path, header: PropheseeHeader, resolution) -> Iterator[tuple]:
    """Events decoded by the format's registry package, as ``(t, x, y, p)`` column tuples, batch by batch."""
    module = _decoder_module(header.format)
    if header.format == "evt3":
        for batch in module.decode_file_batches(str(path)):
            yield batch.t, batch.x, batch.y, batch.p
        return
    if header.format == "prophesee-dat":
        decoder, field = module.dat.Decoder(path, resolution, "dat2"), "payload"
    else:
        decoder, field = module.evt.Decoder(path, resolution, "evt2"), "on"
    with decoder:
        for packet in decoder:
            # faery's EVT packets are dicts whose "events" entry is missing when a packet holds triggers only.
            events = packet.get("events") if isinstance(packet, dict) else packet
            if events is not None and events.size:
                yield events["t"], events["x"], events["y"], events[field]


def decode_evt21(words: np.ndarray, time_high: int | None) -> tuple[tuple[np.ndarray, ...], int | None, int]:
    """Decode EVT 2.1 words (little-endian ``uint64``) into event columns.

    Parameters
    ----------
    words : (N,) uint64 ndarray
    time_high : int or None
        The time's high bits (``t >> 6``) carried over from the previous chunk; None before the first
        ``EVT_TIME_HIGH`` word.

    Returns
    -------
    (t, x, y, p), time_high, bad
        Event columns in file order (within a vector word, x ascending: bit i is pixel ``x + i``); the time's
        high bits after the last word; the index of the first word of a reserved type, or -1 (every word valid).
        CD words before the first ``EVT_TIME_HIGH`` have no time and are dropped, as the format describes.
    """
    kind = (words >> np.uint64(60)).astype(np.int64)
    valid = np.isin(kind, (EVT21_OFF, EVT21_ON, EVT21_TIME_HIGH, *EVT21_OTHER_TYPES))
    bad = int(np.argmin(valid)) if not valid.all() else -1
    is_high = kind == EVT21_TIME_HIGH
    # The time's high bits in force at each word: the last EVT_TIME_HIGH at or before it, else the carried value.
    last = np.maximum.accumulate(np.where(is_high, np.arange(words.size), -1))
    highs = ((words >> np.uint64(32)) & np.uint64(0xFFFFFFF)).astype(np.int64)
    high_at = np.where(last >= 0, highs[np.maximum(last, 0)], -1 if time_high is None else time_high)
    cd = ((kind == EVT21_OFF) | (kind == EVT21_ON)) & (high_at >= 0)
    w = words[cd]
    t = high_at[cd] << 6 | ((w >> np.uint64(54)) & np.uint64(0x3F)).astype(np.int64)
    base = ((w >> np.uint64(43)) & np.uint64(0x7FF)).astype(np.int64)
    y = ((w >> np.uint64(32)) & np.uint64(0x7FF)).astype(np.int64)
    mask = (w & np.uint64(0xFFFFFFFF)).astype(np.int64)
    bits = np.unpackbits(mask.astype("<u4").view(np.uint8).reshape(-1, 4), axis=1, bitorder="little")
    row, bit = np.divmod(np.flatnonzero(bits), 32)  # one flat scan: faster than nonzero on two axes
    columns = (t[row], base[row] + bit, y[row], kind[cd][row] == EVT21_ON)
    new_high = int(high_at[-1]) if words.size and high_at[-1] >= 0 else time_high
    return columns, new_high, bad


def _evt21_columns(path, header: PropheseeHeader) -> Iterator[tuple]:
    """EVT 2.1 events decoded here, chunk by chunk, as ``(t, x, y, p)`` column tuples."""
    time_high, index = None, 0
    with open_regular(path) as fh:
        fh.seek(header.data_offset)
        while block := fh.read(CHUNK_WORDS * 8):
            words = np.frombuffer(block, "<u8")
            if header.legacy_order:  # high half first: swap the two 32-bit halves back
                words = words.view("<u4").reshape(-1, 2)[:, ::-1].copy().view("<u8").ravel()
            columns, time_high, bad = decode_evt21(words, time_high)
            if bad >= 0:
                at = index + bad
                raise CorruptFileError(f"{path}: EVT 2.1 word {at} (byte {header.data_offset + 8 * at}) "
                                       f"has the reserved type 0x{int(words[bad]) >> 60:x}; the file is damaged or "
                                       "not EVT 2.1.")
            index += words.size
            yield columns


def _camera_chunks(path: str, header: PropheseeHeader, resolution, label: str) -> Iterator[Chunk]:
    """One file's events, checked (inside the sensor, in time order) chunk by chunk."""
    check = ChunkChecker(resolution=resolution, source=f"{path} [{ENCODINGS[header.format]}, {label}]")
    columns = _evt21_columns(path, header) if header.format == "evt21" else _registry_columns(path, header, resolution)
    try:
        for t, x, y, p in columns:
            yield check.columns(t, x, y, np.asarray(p, np.int8)), None
    except (KeyboardInterrupt, SystemExit, GeneratorExit, MissingExtraError):
        raise
    except (CorruptFileError, ValueError, OSError):
        raise
    except BaseException as exc:  # the decoders' Rust panics are BaseExceptions
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CorruptFileError(f"{path}: the {ENCODINGS[header.format]} decoder ({DECODERS[header.format]}) failed "
                               f"at event {check.count} [{message}]; the file is damaged.") from None


def open_prophesee(path: str | os.PathLike, right: str | os.PathLike | None = None, *, format: str | None = None,
                   resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open a Prophesee recording (one file per camera) for streaming.

    Parameters
    ----------
    path : path-like
        The left camera's file, or a single camera's.
    right : path-like, optional
        The right camera's file, of the same format and sensor size.
    format : str, optional, keyword-only
        One of :data:`ENCODINGS`; the header must agree. Default: what the header says.
    resolution : (width, height), optional, keyword-only
        The sensor size where the header does not state it; where it does, they must agree.

    Returns
    -------
    RecordingStream
        ``meta`` holds ``source``, ``format`` and ``resolution_from`` (``header`` or ``given``).

    Raises
    ------
    CorruptFileError, ValueError
        See :func:`read_prophesee_header`; the two files in different formats or sizes; no size known.
    MissingExtraError
        The format's decoder package (:data:`DECODERS`) is not installed.
    """
    files = (os.fspath(path),) + (() if right is None else (os.fspath(right),))
    headers = [read_prophesee_header(files[0], format)]
    if right is not None:
        headers.append(read_prophesee_header(files[1], headers[0].format))
    sizes = {h.resolution for h in headers if h.resolution is not None}
    if len(sizes) > 1:
        raise ValueError(f"{path}: the cameras' files have different sensor sizes {sorted(sizes)}; cvstereo matches "
                         "cameras of one size.")
    from_file = bool(sizes)
    size = sizes.pop() if sizes else None
    what = ENCODINGS[headers[0].format]
    if size is not None and resolution is not None and tuple(resolution) != size:
        raise ValueError(f"{path}: the {what} header says {size[0]}x{size[1]}, not {resolution[0]}x{resolution[1]}.")
    if size is None and resolution is None:
        raise ValueError(f"{path}: the {what} header does not state the sensor size; give --resolution WxH.")
    size = size or tuple(resolution)
    if DECODERS[headers[0].format] is not None:
        _decoder_module(headers[0].format)  # say what is missing before any event is read
    cameras = CAMERAS if right is not None else (MONO,)
    by_camera = dict(zip(cameras, zip(files, headers, strict=True), strict=True))
    meta = {"source": list(files), "format": headers[0].format,
            "resolution_from": "header" if from_file else "given"}

    def open_chunks(camera: str) -> Iterator[Chunk]:
        file, header = by_camera[camera]
        return _camera_chunks(file, header, size, camera)

    return RecordingStream(headers[0].format, files, cameras, size, meta, False, open_chunks)
