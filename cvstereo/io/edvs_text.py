"""eDVS text recordings: one event per line, read in chunks with bounded memory, and written.

Two layouts (formats.md):

``edvs-text``
    One file per camera, four columns ``t x y p``; a stereo recording is two files (left, right).
``edvs-merged``
    Both cameras in one file with a fifth column, the retina id (0/1), as in the TUM recordings;
    time order holds within each retina only, so each camera is streamed by its own pass over the file.

Columns are separated by whitespace or commas; ``t`` is integer microseconds; ``p`` is 1/0 or +1/-1;
lines starting with ``#`` are comments. Header comments before the first event may say
``# resolution W H``, ``# fields t x y p [retina]`` (tells the layout of a file without events) and
(merged files) ``# left_retina R``; the writers put all three there.

What a file cannot say is detected, and the decision is recorded in the stream's ``meta``:

- **one-based coordinates** (``one_based=None``): the file counts from 1 exactly when some coordinate
  equals the width or height (only a one-based file can hold ``x == W``). A one-based file whose events
  never reach the last column or row is indistinguishable from a zero-based one and is read as
  zero-based (shifted by one pixel): pass ``one_based=True`` for it. A file holding both a 0 and a W
  coordinate is rejected.
- **which retina is left** (``left_retina=None``, merged files): the left camera sees a scene point at
  the larger x, so the event images of the two retinas overlay best when retina 0's image is shifted by
  ``s = x_0 - x_1``; ``s > 0`` means retina 0 is left. The shift is found by normalised
  cross-correlation of the whole-recording event images (log counts, so hot pixels do not dominate)
  over ``|s| <= width // 3``. A best shift of 0 (no parallax) cannot decide and raises.
"""

from __future__ import annotations

import io
import itertools
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.events import DEFAULT_RESOLUTION, check_resolution, validate_events
from cvstereo.io._atomic import atomic_path
from cvstereo.io._checked import ChunkChecker
from cvstereo.io._source import open_regular, printable
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.overlay import overlay_shift
from cvstereo.recording import CAMERAS, Recording

#: Lines per parsed block: bounds memory and keeps np.loadtxt's per-call overhead negligible.
CHUNK_LINES = 1 << 16

_COLUMN_NAMES = {4: "t x y p", 5: "t x y p retina"}
_INTEGER = re.compile(rb"[+-]?\d+")
_RAW_DTYPE = np.dtype([("t", "<i8"), ("x", "<i8"), ("y", "<i8"), ("p", "<i8")])


# --------------------------------------------------------------------------------------------- parsing

@dataclass(frozen=True)
class TextHeader:
    """What the comment lines before the first event (and that event's line) say about a text file.

    Attributes
    ----------
    columns : int or None
        Column count of the first event line (4 single camera, 5 merged), else of the ``# fields``
        header; None for a file without either.
    resolution : (width, height) or None
        From ``# resolution W H``.
    left_retina : int or None
        From ``# left_retina R``.
    """

    columns: int | None
    resolution: tuple[int, int] | None = None
    left_retina: int | None = None


def read_text_header(path: str | os.PathLike) -> TextHeader:
    """Read the header comments and count the columns of the first event line.

    Raises
    ------
    FileNotFoundError, CorruptFileError
    """
    resolution = left_retina = fields = None
    with _open(path) as fh:
        for lineno, line in enumerate(fh, 1):
            stripped = line.strip()
            if lineno == 1 and stripped.startswith(b"#!AER-DAT"):
                raise CorruptFileError(f"{path}: this is a jAER AEDAT file, not text; read it as format 'aedat2'.")
            if not stripped:
                continue
            if not stripped.startswith(b"#"):
                return TextHeader(len(_split(stripped)), resolution, left_retina)
            words = stripped[1:].replace(b",", b" ").split()
            key = words[0].lower() if words else b""
            try:
                if key == b"resolution":
                    resolution = (int(words[1]), int(words[2]))
                    if min(resolution) <= 0:
                        raise ValueError
                    # Every buffer of the readers and matchers is sized by it: bound it before anything is.
                    check_resolution(resolution, source=f"{path}, line {lineno}: header resolution",
                                     error=CorruptFileError)
                elif key == b"fields":
                    fields = len(words) - 1
                elif key == b"left_retina":
                    left_retina = int(words[1])
                    if left_retina not in (0, 1):
                        raise ValueError
            except (IndexError, ValueError) as exc:
                if isinstance(exc, CorruptFileError):
                    raise
                raise CorruptFileError(
                    f"{path}, line {lineno}: header '{_show(line)}' is malformed; write '# resolution W H' "
                    "(positive integers) or '# left_retina 0|1'."
                ) from None
    return TextHeader(fields, resolution, left_retina)


class _Block(NamedTuple):
    rows: np.ndarray   # (N, columns) int64
    lines: np.ndarray  # (N,) int64, 1-based line number of each row


def _iter_blocks(path, columns: int, chunk_lines: int) -> Iterator[_Block]:
    """Parse a text file into blocks of integer rows, each with the line numbers of its rows."""
    if chunk_lines <= 0:
        raise ValueError(f"chunk_lines must be positive, got {chunk_lines}.")
    with _open(path) as fh:
        done = 0
        while lines := list(itertools.islice(fh, chunk_lines)):
            block = _parse_block(path, lines, done, columns)
            done += len(lines)
            if block.rows.shape[0]:
                yield block


def _parse_block(path, lines: list[bytes], first: int, columns: int) -> _Block:
    keep = [i for i, line in enumerate(lines) if (s := line.lstrip()) and not s.startswith(b"#")]
    if not keep:
        return _Block(np.empty((0, columns), np.int64), np.empty(0, np.int64))
    data = b"".join([lines[i] for i in keep]).replace(b",", b" ")
    try:
        # np.loadtxt parses in C: the 2.4 MB TUM file takes well under a second.
        rows = np.loadtxt(io.BytesIO(data), dtype=np.int64, ndmin=2)
    except ValueError:
        rows = None
    if rows is None or rows.shape[1] != columns:
        raise _bad_line(path, lines, keep, first, columns)
    return _Block(rows, first + 1 + np.asarray(keep, np.int64))


def _bad_line(path, lines, keep, first, columns) -> CorruptFileError:
    # The fast parse failed somewhere in this block; find the first offending line to name it.
    for i in keep:
        tokens = _split(lines[i].split(b"#", 1)[0])
        if len(tokens) != columns:
            problem = f"has {len(tokens)} columns where the file's first event line has {columns}"
        elif not all(_INTEGER.fullmatch(tok) and abs(int(tok)) < 2**63 for tok in tokens):
            problem = "holds something other than integers"
        else:
            continue
        return CorruptFileError(
            f"{path}, line {first + i + 1}: '{_show(lines[i])}' {problem}; each event line must be "
            f"{columns} integers '{_COLUMN_NAMES.get(columns, '')}' (fix or comment out the line with '#')."
        )
    return CorruptFileError(f"{path}, lines {first + 1}-{first + len(lines)}: cannot be parsed as integers.")


def _split(text: bytes) -> list[bytes]:
    return text.replace(b",", b" ").split()


def _show(line: bytes, limit: int = 80) -> str:
    text = printable(line.decode("latin-1").strip())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _line_text(path, lineno: int) -> str:
    with _open(path) as fh:
        return _show(next(itertools.islice(fh, lineno - 1, None), b""))


def _open(path):
    # Regular files only: the readers take several passes (header, detection, one per camera).
    return open_regular(path)


# ------------------------------------------------------------------------------------- chunked reading

def iter_text_chunks(path: str | os.PathLike, *, retina: int | None = None, one_based: bool | None = False,
                     resolution: tuple[int, int] | None = None,
                     chunk_lines: int = CHUNK_LINES) -> Iterator[np.ndarray]:
    """Stream one camera's events from a text file, validated, with bounded memory.

    Parameters
    ----------
    path : path-like
    retina : {None, 0, 1}, keyword-only
        None for a single-camera (4-column) file; the retina id to keep for a merged (5-column) file.
    one_based : bool or None, keyword-only
        Coordinates count from 1. None detects it with an extra pass (module docstring).
    resolution : (width, height) or None, keyword-only
        None: from the ``# resolution`` header, else 128x128.
    chunk_lines : int, keyword-only
        Lines parsed per block.

    Yields
    ------
    (N,) ndarray of EVENT_DTYPE
        Consecutive, time-ordered chunks (at most ``chunk_lines`` events each; blocks without events of
        this camera yield nothing).

    Raises
    ------
    CorruptFileError
        A line that is not integers, or has the wrong number of columns (file, line number and text).
    EventFormatError
        Bad polarity or retina id, coordinates out of range, time going backwards (file, field, index
        in this camera's stream, line number and text).
    """
    header = read_text_header(path)
    columns = 4 if retina is None else 5
    _require_columns(path, header, columns)
    resolution = _resolve_resolution(resolution, [(path, header)])[0]
    if one_based is None:
        one_based = detect_one_based([scan_text(path, resolution=resolution, chunk_lines=chunk_lines)])
    source = str(path) if retina is None else f"{path} [retina {retina}]"
    check = ChunkChecker(resolution=resolution, source=source)
    for block in _iter_blocks(path, columns, chunk_lines):
        rows, lines = block
        if retina is not None:
            _check_retina_ids(path, block)
            keep = rows[:, 4] == retina
            rows, lines = rows[keep], lines[keep]
            if not rows.shape[0]:
                continue
        raw = np.empty(rows.shape[0], _RAW_DTYPE)
        for k, name in enumerate(("t", "x", "y", "p")):
            raw[name] = rows[:, k]
        if one_based:
            raw["x"] -= 1
            raw["y"] -= 1
        yield check(raw, locate=_LineLocator(path, lines))


class _LineLocator:
    """``locate(i)`` for :class:`ChunkChecker`: the line number and text of row ``i`` of a block."""

    def __init__(self, path, lines: np.ndarray):
        self.path, self.lines = path, lines

    def __call__(self, i: int) -> str:
        lineno = int(self.lines[i])
        return f"line {lineno}: '{_line_text(self.path, lineno)}'"


def _check_retina_ids(path, block: _Block) -> None:
    bad = np.flatnonzero((block.rows[:, 4] != 0) & (block.rows[:, 4] != 1))
    if bad.size:
        lineno = int(block.lines[bad[0]])
        raise EventFormatError(
            f"{path}: field 'retina' at line {lineno} is {int(block.rows[bad[0], 4])}: '{_line_text(path, lineno)}'; "
            "the fifth column of a merged file must be 0 or 1."
        )


def _require_columns(path, header: TextHeader, columns: int) -> None:
    if header.columns is None or header.columns == columns:
        return
    if header.columns == 5:
        hint = "it is a merged two-camera file: read it as 'edvs-merged' (or choose a retina)"
    elif header.columns == 4:
        hint = "it is a single-camera file: read it as 'edvs-text' (with the other camera's file)"
    else:
        hint = "eDVS text files have 4 columns 't x y p' or 5 't x y p retina'"
    raise CorruptFileError(f"{path}: the first event line has {header.columns} columns, expected {columns}; {hint}.")


def _resolve_resolution(given, headers) -> tuple[tuple[int, int], str]:
    if given is not None:
        return check_resolution(given, source="resolution"), "given"
    stated = {h.resolution for _, h in headers if h.resolution is not None}
    if len(stated) > 1:
        names = ", ".join(f"{p}: {h.resolution[0]}x{h.resolution[1]}" for p, h in headers if h.resolution)
        raise ValueError(f"the files state different resolutions ({names}); give the resolution explicitly.")
    if stated:
        return stated.pop(), "header"
    return DEFAULT_RESOLUTION, "default"


# ------------------------------------------------------------------------------------------- detection

@dataclass(frozen=True, eq=False)
class TextScan:
    """Statistics of one pass over a text file, enough to decide what the file cannot say.

    Attributes
    ----------
    path : str
    resolution : (width, height)
    counts : tuple of int
        Events per retina (one entry for a single-camera file, two for a merged file).
    images : tuple of (H + 1, W + 1) int64 ndarray
        Events per raw (as written) pixel and retina; coordinates beyond W or H are left out.
    x_range, y_range : (int, int) or None
        Smallest and largest raw coordinate in the file; None without events.
    """

    path: str
    resolution: tuple[int, int]
    counts: tuple[int, ...]
    images: tuple[np.ndarray, ...]
    x_range: tuple[int, int] | None
    y_range: tuple[int, int] | None


def scan_text(path: str | os.PathLike, *, resolution: tuple[int, int] | None = None,
              chunk_lines: int = CHUNK_LINES) -> TextScan:
    """One streaming pass over a text file collecting :class:`TextScan` statistics (bounded memory).

    Raises
    ------
    FileNotFoundError, CorruptFileError, EventFormatError (bad retina id)
    """
    header = read_text_header(path)
    columns = header.columns or 4
    width, height = _resolve_resolution(resolution, [(path, header)])[0]
    retinas = 2 if columns == 5 else 1
    images = [np.zeros((height + 1) * (width + 1), np.int64) for _ in range(retinas)]
    lo, hi = np.full(2, np.iinfo(np.int64).max), np.full(2, np.iinfo(np.int64).min)
    for block in _iter_blocks(path, columns, chunk_lines):
        if columns == 5:
            _check_retina_ids(path, block)
        x, y = block.rows[:, 1], block.rows[:, 2]
        lo = np.minimum(lo, [x.min(), y.min()])
        hi = np.maximum(hi, [x.max(), y.max()])
        inside = (x >= 0) & (x <= width) & (y >= 0) & (y <= height)
        retina = block.rows[:, 4] if columns == 5 else np.zeros(len(x), np.int64)
        for r in range(retinas):
            sel = inside & (retina == r)
            images[r] += np.bincount(y[sel] * (width + 1) + x[sel], minlength=images[r].size)
    counts = tuple(int(im.sum()) for im in images)
    empty = lo[0] > hi[0]
    return TextScan(
        str(path), (width, height), counts, tuple(im.reshape(height + 1, width + 1) for im in images),
        None if empty else (int(lo[0]), int(hi[0])), None if empty else (int(lo[1]), int(hi[1])),
    )


def detect_one_based(scans: list[TextScan]) -> bool:
    """Decide whether coordinates count from 1 (rule in the module docstring), jointly over files.

    Raises
    ------
    EventFormatError
        Coordinates that reach both 0 and the width/height: neither convention fits the resolution.
    """
    touches_zero = touches_size = False
    for scan in scans:
        (width, height), xr, yr = scan.resolution, scan.x_range, scan.y_range
        if xr is None:
            continue
        touches_zero |= xr[0] == 0 or yr[0] == 0
        touches_size |= xr[1] == width or yr[1] == height
    if touches_zero and touches_size:
        raise EventFormatError(
            f"{', '.join(s.path for s in scans)}: coordinates reach both 0 and the sensor size "
            f"{scans[0].resolution[0]}x{scans[0].resolution[1]}; that fits neither zero- nor one-based "
            "counting: give the right resolution."
        )
    return touches_size


def detect_left_retina(scan: TextScan) -> tuple[int, int, float]:
    """Which retina of a merged file is the left camera (rule in the module docstring).

    Returns
    -------
    left_retina : int
    shift : int
        ``x_0 - x_1`` at the best overlay (positive: retina 0 is left).
    score : float
        Its normalised cross-correlation.

    Raises
    ------
    ValueError
        A retina without events, or no parallax (best overlay at shift 0): give ``left_retina``.
    """
    if len(scan.images) != 2 or min(scan.counts) == 0:
        raise ValueError(
            f"{scan.path}: cannot tell which retina is the left camera without events from both; "
            "give left_retina (--left-retina 0 or 1)."
        )
    # cvstereo.overlay's convention: x_0 = x_1 + shift, positive when retina 0 is the left camera.
    shift, score = overlay_shift(scan.images[0], scan.images[1], max_shift=scan.resolution[0] // 3)
    if shift == 0:
        raise ValueError(
            f"{scan.path}: the two retinas' event images overlay best without shift, so the data cannot tell "
            "which retina is the left camera; give left_retina (--left-retina 0 or 1)."
        )
    return (0 if shift > 0 else 1), shift, score


# --------------------------------------------------------------------------------------------- opening

def open_edvs_text(left: str | os.PathLike, right: str | os.PathLike | None = None, *,
                   one_based: bool | None = None, resolution: tuple[int, int] | None = None,
                   chunk_lines: int = CHUNK_LINES) -> RecordingStream:
    """Open one-file-per-camera text recordings for streaming.

    Parameters
    ----------
    left : path-like
        The left camera's file (or the only file, for a single-camera stream).
    right : path-like, optional
        The right camera's file. Without it the stream holds one camera named ``"mono"``.
    one_based : bool or None, keyword-only
        None detects it jointly over both files (module docstring).
    resolution : (width, height) or None, keyword-only
        None: from the files' headers (which must agree), else 128x128.
    chunk_lines : int, keyword-only

    Returns
    -------
    RecordingStream
    """
    paths = [left] if right is None else [left, right]
    headers = [(p, read_text_header(p)) for p in paths]
    for p, h in headers:
        _require_columns(p, h, 4)
    res, res_from = _resolve_resolution(resolution, headers)
    meta = {"source": "eDVS text", "resolution_from": res_from}
    one_based, meta["one_based_from"] = _decide_one_based(
        one_based, lambda: [scan_text(p, resolution=res, chunk_lines=chunk_lines) for p in paths])
    meta["one_based"] = one_based
    names = CAMERAS if right is not None else (MONO,)
    by_name = dict(zip(names, paths, strict=True))

    def open_chunks(camera: str) -> Iterator[Chunk]:
        for events in iter_text_chunks(by_name[camera], one_based=one_based, resolution=res,
                                       chunk_lines=chunk_lines):
            yield events, None

    return RecordingStream("edvs-text", tuple(str(p) for p in paths), names, res, meta, False, open_chunks)


def open_edvs_merged(path: str | os.PathLike, *, left_retina: int | None = None, one_based: bool | None = None,
                     resolution: tuple[int, int] | None = None, chunk_lines: int = CHUNK_LINES) -> RecordingStream:
    """Open a merged two-camera text file (``t x y p retina``) for streaming.

    Each camera is streamed by its own pass over the file, keeping one retina's lines, because such
    files need not interleave the cameras in time (the TUM Fan file lists one retina after the other).

    Parameters
    ----------
    path : path-like
    left_retina : {None, 0, 1}, keyword-only
        Retina id of the left camera. None: the ``# left_retina`` header if present, else detected from
        the data (module docstring).
    one_based : bool or None, keyword-only
        None: detected (module docstring).
    resolution : (width, height) or None, keyword-only
        None: the ``# resolution`` header, else 128x128.
    chunk_lines : int, keyword-only

    Returns
    -------
    RecordingStream
        ``meta`` records ``left_retina`` / ``left_retina_from`` (given, header, detected), the overlay
        shift when detected, and ``one_based`` / ``one_based_from``.
    """
    header = read_text_header(path)
    _require_columns(path, header, 5)
    res, res_from = _resolve_resolution(resolution, [(path, header)])
    if left_retina is not None and left_retina not in (0, 1):
        raise ValueError(f"left_retina must be 0 or 1, got {left_retina!r}.")
    meta: dict = {"source": "eDVS merged text", "resolution_from": res_from}
    scan: list[TextScan] = []

    def scanned() -> list[TextScan]:
        # One scan serves both detections; it is skipped when nothing needs detecting.
        if not scan:
            scan.append(scan_text(path, resolution=res, chunk_lines=chunk_lines))
        return scan

    if left_retina is not None:
        meta["left_retina_from"] = "given"
    elif header.left_retina is not None:
        left_retina, meta["left_retina_from"] = header.left_retina, "header"
    else:
        left_retina, shift, score = detect_left_retina(scanned()[0])
        meta.update(left_retina_from="detected", overlay_shift_px=abs(shift), overlay_score=round(score, 4))
    meta["left_retina"] = int(left_retina)
    one_based, meta["one_based_from"] = _decide_one_based(one_based, scanned)
    meta["one_based"] = one_based
    retina_of = {"left": int(left_retina), "right": 1 - int(left_retina)}

    def open_chunks(camera: str) -> Iterator[Chunk]:
        for events in iter_text_chunks(path, retina=retina_of[camera], one_based=one_based, resolution=res,
                                       chunk_lines=chunk_lines):
            yield events, None

    return RecordingStream("edvs-merged", (str(path),), CAMERAS, res, meta, False, open_chunks)


def _decide_one_based(one_based, scans) -> tuple[bool, str]:
    if one_based is not None:
        return bool(one_based), "given"
    return detect_one_based(scans()), "detected"


def read_edvs_text(left: str | os.PathLike, right: str | os.PathLike, **options) -> Recording:
    """Read a one-file-per-camera stereo recording whole (options of :func:`open_edvs_text`)."""
    return open_edvs_text(left, right, **options).read()


def read_edvs_merged(path: str | os.PathLike, **options) -> Recording:
    """Read a merged two-camera text file whole (options of :func:`open_edvs_merged`).

    Examples
    --------
    The TUM fan (retina 1 is left; detected):

    >>> rec = read_edvs_merged("Fan_disp8.dat")  # doctest: +SKIP
    >>> rec.meta["left_retina"], rec.left.size, rec.right.size  # doctest: +SKIP
    (1, 72746, 63487)
    """
    return open_edvs_merged(path, **options).read()


# --------------------------------------------------------------------------------------------- writing

def write_edvs_text(path: str | os.PathLike, events: np.ndarray, *,
                    resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> None:
    """Write one camera's events as a four-column text file (atomically).

    Parameters
    ----------
    path : path-like
    events : (N,) ndarray of EVENT_DTYPE
    resolution : (width, height), keyword-only
        Stated in the ``# resolution`` header.
    """
    validate_events(events, resolution=resolution, source=f"writing {path}")
    _write_rows(path, ["fields t x y p", "t in microseconds, p 1 = ON, 0 = OFF", _resolution_line(resolution)],
                [events["t"], events["x"], events["y"], events["p"]])


def write_edvs_pair(left_path: str | os.PathLike, right_path: str | os.PathLike, recording: Recording) -> None:
    """Write a stereo recording as two single-camera text files (each atomically)."""
    write_edvs_text(left_path, recording.left, resolution=recording.resolution)
    write_edvs_text(right_path, recording.right, resolution=recording.resolution)


def write_edvs_merged(path: str | os.PathLike, recording: Recording, *, left_retina: int = 0) -> None:
    """Write a stereo recording as one merged five-column text file (atomically), in time order.

    Parameters
    ----------
    path : path-like
    recording : Recording
    left_retina : {0, 1}, keyword-only
        Retina id given to the left camera; stated in the ``# left_retina`` header so readers need not
        detect it.
    """
    if left_retina not in (0, 1):
        raise ValueError(f"left_retina must be 0 or 1, got {left_retina!r}.")
    both = np.concatenate([recording.left, recording.right])
    retina = np.repeat(np.array([left_retina, 1 - left_retina], np.int8), [recording.left.size, recording.right.size])
    order = np.argsort(both["t"], kind="stable")
    both, retina = both[order], retina[order]
    _write_rows(path, ["fields t x y p retina", "t in microseconds, p 1 = ON, 0 = OFF, retina = camera id",
                       _resolution_line(recording.resolution), f"left_retina {left_retina}"],
                [both["t"], both["x"], both["y"], both["p"], retina])


def _resolution_line(resolution) -> str:
    return f"resolution {int(resolution[0])} {int(resolution[1])}"


def _write_rows(path, header: list[str], columns: list[np.ndarray], chunk_rows: int = CHUNK_LINES) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write("".join(f"# {line}\n" for line in ["eDVS text recording written by cvstereo", *header]))
        n = len(columns[0])
        for start in range(0, n, chunk_rows):
            block = np.column_stack([np.asarray(c[start:start + chunk_rows], np.int64) for c in columns])
            np.savetxt(fh, block, fmt="%d")


__all__ = [
    "CHUNK_LINES",
    "TextHeader",
    "TextScan",
    "detect_left_retina",
    "detect_one_based",
    "iter_text_chunks",
    "open_edvs_merged",
    "open_edvs_text",
    "overlay_shift",
    "read_edvs_merged",
    "read_edvs_text",
    "read_text_header",
    "scan_text",
    "write_edvs_merged",
    "write_edvs_pair",
    "write_edvs_text",
]
