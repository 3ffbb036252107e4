"""Metavision CSV event files: one ``x,y,p,t`` line per event, one camera per file.

Metavision's tools write the columns in the order ``x,y,p,t`` (t in microseconds, p 1 = ON, 0 = OFF); other
orders are given as ``columns="t,x,y,p"`` (the CLI's ``--columns``) or by a first line that names them. Lines
starting with ``%`` are metadata; ``%geometry:W,H`` gives the sensor size, else ``resolution=`` must.
A stereo recording is two files (``open_metavision_csv(left, right)``). The file is read in blocks of lines,
so memory stays bounded.

Told from the TUM lab's eDVS text files (``t x y p``, also comma-separated at times) by content
(:func:`sniff_metavision_csv`): a ``%`` line or a names line first, or data whose third column is a polarity
(0/1) and whose fourth is a clock (not only -1/0/1, which would be eDVS text's polarity).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.files import open_regular, printable
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.events import check_resolution
from cvstereo.model.recording import CAMERAS

__all__ = ["DEFAULT_COLUMNS", "open_metavision_csv", "parse_columns", "sniff_metavision_csv"]

FORMAT = "metavision-csv"
#: The column order Metavision's CSV writer uses.
DEFAULT_COLUMNS = ("x", "y", "p", "t")
#: Lines parsed at a time.
BLOCK_LINES = 1 << 16
#: Data lines looked at to tell the format.
SNIFF_LINES = 64


def parse_columns(text: str | tuple[str, ...] | None, *, source: str = "columns") -> tuple[str, ...]:
    """The column order ``text`` (e.g. ``"t,x,y,p"``) names; None is Metavision's ``x,y,p,t``.

    Raises
    ------
    ValueError
        Not the four names x, y, p, t each once.
    """
    if text is None:
        return DEFAULT_COLUMNS
    names = tuple(n.strip().lower() for n in (text.split(",") if isinstance(text, str) else text))
    if sorted(names) != sorted(DEFAULT_COLUMNS):
        raise ValueError(f"{source} '{','.join(names)}' must name x, y, p and t once each, in the file's order "
                         "(Metavision writes x,y,p,t).")
    return names


def _first_lines(path) -> list[bytes]:
    with open_regular(path) as fh:
        return [line.strip() for line, _ in zip(fh, range(SNIFF_LINES + 4), strict=False) if line.strip()]


def is_comma_separated(path: str | os.PathLike) -> bool:
    """Whether a text file's first line that is not a comment (``#``, ``%``) separates its values by commas: eDVS
    text never does, so a file that detection took for eDVS text is a CSV of another column order."""
    lines = [line for line in _first_lines(path) if not line.startswith((b"#", b"%"))]
    return bool(lines) and b"," in lines[0]


def sniff_metavision_csv(path: str | os.PathLike) -> bool:
    """Whether a text file is Metavision CSV (see the module's description of the rule)."""
    lines = _first_lines(path)
    if not lines or lines[0].startswith(b"#"):
        return False
    if lines[0].startswith(b"%"):
        return True
    try:
        parse_columns(lines[0].decode("ascii"))
        return True
    except (ValueError, UnicodeDecodeError):
        pass
    try:
        rows = np.array([[int(v) for v in line.split(b",")] for line in lines], np.int64)
    except ValueError:
        return False
    if rows.ndim != 2 or rows.shape[1] != 4:
        return False
    p, t = rows[:, 2], rows[:, 3]
    return bool(np.isin(p, (0, 1)).all() and not np.isin(t, (-1, 0, 1)).all())


def _read_preamble(path, columns) -> tuple[tuple[int, int] | None, tuple[str, ...], int]:
    """The size of a ``%geometry:W,H`` line, the column order (a names line wins over the default), and the
    number of lines before the first event."""
    size, skip = None, 0
    for line in _first_lines(path):
        if line.startswith(b"%"):
            skip += 1
            key, _, value = line[1:].partition(b":")
            if key.strip().lower() == b"geometry":
                try:
                    size = tuple(int(v) for v in value.split(b","))
                    check_resolution(size, source=f"{path}: Metavision CSV '%geometry' size", error=CorruptFileError)
                except (ValueError, TypeError) as exc:
                    if isinstance(exc, CorruptFileError):
                        raise
                    raise CorruptFileError(f"{path}: Metavision CSV line {skip}: '{printable(line.decode('latin-1'))}'"
                                           " is not '%geometry:WIDTH,HEIGHT'.") from None
            continue
        try:
            named = parse_columns(line.decode("ascii"))
        except (ValueError, UnicodeDecodeError):
            return size, parse_columns(columns, source=f"{path}: columns"), skip
        if columns is not None and parse_columns(columns, source=f"{path}: columns") != named:
            raise ValueError(f"{path}: the file's first line names the columns {','.join(named)}, not {columns}.")
        return size, named, skip + 1
    return size, parse_columns(columns, source=f"{path}: columns"), skip


def _parse_block(path, lines: list[bytes], first_line: int) -> np.ndarray:
    """A block of data lines as an (N, 4) int64 array; a bad line is named by number and content."""
    try:
        rows = np.loadtxt(lines, delimiter=",", dtype=np.int64, ndmin=2)
        if rows.shape[1] == 4:
            return rows
    except ValueError:
        pass
    for i, line in enumerate(lines):
        fields = line.split(b",")
        try:
            if len(fields) != 4:
                raise ValueError
            [int(v) for v in fields]
        except ValueError:
            shown = printable(line.decode("latin-1").strip())[:80]
            raise CorruptFileError(f"{path}: Metavision CSV line {first_line + i}: '{shown}' is not four whole "
                                   "numbers separated by commas.") from None
    raise CorruptFileError(f"{path}: Metavision CSV lines {first_line}.. do not have four columns.")


def _camera_chunks(path: str, order: tuple[str, ...], skip: int, resolution, label: str) -> Iterator[Chunk]:
    check = ChunkChecker(resolution=resolution, source=f"{path} [Metavision CSV, {label}]")
    where = {name: order.index(name) for name in DEFAULT_COLUMNS}
    with open_regular(path) as fh:
        lineno = 0
        block: list[bytes] = []
        for line in fh:
            lineno += 1
            if lineno <= skip or not line.strip():
                continue
            if not block:
                start = lineno
            block.append(line)
            if len(block) == BLOCK_LINES:
                rows = _parse_block(path, block, start)
                block = []
                yield check.columns(*(rows[:, where[c]] for c in "txyp")), None
        if block:
            rows = _parse_block(path, block, start)
            yield check.columns(*(rows[:, where[c]] for c in "txyp")), None


def open_metavision_csv(path: str | os.PathLike, right: str | os.PathLike | None = None, *,
                        columns: str | None = None, resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open Metavision CSV files (the left and right cameras', or one camera's) for streaming.

    Parameters
    ----------
    path, right : path-like
        The left (or only) camera's file and the right camera's.
    columns : str, optional, keyword-only
        The column order, e.g. ``"t,x,y,p"`` (default ``x,y,p,t``, or the file's names line).
    resolution : (width, height), optional, keyword-only
        Needed where the files have no ``%geometry`` line; must agree where they do.

    Raises
    ------
    CorruptFileError, ValueError
        A line that is not four integers (named by number), events outside the sensor or going back in time,
        a bad ``columns``, files of different sizes, no size known.
    """
    files = (os.fspath(path),) + (() if right is None else (os.fspath(right),))
    preambles = [_read_preamble(f, columns) for f in files]
    sizes = {p[0] for p in preambles if p[0] is not None}
    if len(sizes) > 1:
        raise ValueError(f"{path}: the cameras' files have different sizes {sorted(sizes)}.")
    size = sizes.pop() if sizes else None
    if size is not None and resolution is not None and tuple(resolution) != size:
        raise ValueError(f"{path}: the file's '%geometry' says {size[0]}x{size[1]}, "
                         f"not {resolution[0]}x{resolution[1]}.")
    if size is None and resolution is None:
        raise ValueError(f"{path}: a Metavision CSV file without a '%geometry:W,H' line needs --resolution WxH.")
    from_file = size is not None
    size = size or tuple(resolution)
    cameras = CAMERAS if right is not None else (MONO,)
    by_camera = dict(zip(cameras, zip(files, preambles, strict=True), strict=True))
    meta = {"source": list(files), "format": FORMAT, "columns": ",".join(preambles[0][1]),
            "resolution_from": "header" if from_file else "given"}

    def open_chunks(camera: str) -> Iterator[Chunk]:
        file, (_, order, skip) = by_camera[camera]
        return _camera_chunks(file, order, skip, size, camera)

    return RecordingStream(FORMAT, files, cameras, size, meta, False, open_chunks)
