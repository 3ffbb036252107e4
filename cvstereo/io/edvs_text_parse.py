"""eDVS text files, the parsing layer: header comments, blocks of lines parsed into arrays, chunked iteration.

:mod:`cvstereo.io.edvs_text` builds the readers (layout detection, one-based and retina decisions, streams)
on these; the formats themselves are described there.
"""


import io
import itertools
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io.files import open_regular, printable
from cvstereo.model.events import DEFAULT_RESOLUTION, check_resolution

__all__ = ["CHUNK_LINES", "RAW_DTYPE", "LineLocator", "TextHeader", "check_retina_ids", "iter_blocks",
           "read_text_header", "require_columns", "resolve_resolution"]

CHUNK_LINES = 1 << 16

_COLUMN_NAMES = {4: "t x y p", 5: "t x y p retina"}
_INTEGER = re.compile(rb"[+-]?\d+")
RAW_DTYPE = np.dtype([("t", "<i8"), ("x", "<i8"), ("y", "<i8"), ("p", "<i8")])


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


def iter_blocks(path, columns: int, chunk_lines: int) -> Iterator[_Block]:
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

class LineLocator:
    """``locate(i)`` for :class:`ChunkChecker`: the line number and text of row ``i`` of a block."""

    def __init__(self, path, lines: np.ndarray):
        self.path, self.lines = path, lines

    def __call__(self, i: int) -> str:
        lineno = int(self.lines[i])
        return f"line {lineno}: '{_line_text(self.path, lineno)}'"


def check_retina_ids(path, block: _Block) -> None:
    bad = np.flatnonzero((block.rows[:, 4] != 0) & (block.rows[:, 4] != 1))
    if bad.size:
        lineno = int(block.lines[bad[0]])
        raise EventFormatError(
            f"{path}: field 'retina' at line {lineno} is {int(block.rows[bad[0], 4])}: '{_line_text(path, lineno)}'; "
            "the fifth column of a merged file must be 0 or 1."
        )


def require_columns(path, header: TextHeader, columns: int) -> None:
    if header.columns is None or header.columns == columns:
        return
    if header.columns == 5:
        hint = "it is a merged two-camera file: read it as 'edvs-merged' (or choose a retina)"
    elif header.columns == 4:
        hint = "it is a single-camera file: read it as 'edvs-text' (with the other camera's file)"
    else:
        hint = "eDVS text files have 4 columns 't x y p' or 5 't x y p retina'"
    raise CorruptFileError(f"{path}: the first event line has {header.columns} columns, expected {columns}; {hint}.")


def resolve_resolution(given, headers) -> tuple[tuple[int, int], str]:
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

