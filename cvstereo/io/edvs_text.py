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

import os
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.geometry.overlay import overlay_shift
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.edvs_text_parse import (
    CHUNK_LINES,
    RAW_DTYPE,
    LineLocator,
    TextHeader,
    check_retina_ids,
    iter_blocks,
    read_text_header,
    require_columns,
    resolve_resolution,
)
from cvstereo.io.edvs_text_write import write_edvs_merged, write_edvs_pair, write_edvs_text
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.recording import CAMERAS, Recording


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
    width, height = resolve_resolution(resolution, [(path, header)])[0]
    retinas = 2 if columns == 5 else 1
    images = [np.zeros((height + 1) * (width + 1), np.int64) for _ in range(retinas)]
    lo, hi = np.full(2, np.iinfo(np.int64).max), np.full(2, np.iinfo(np.int64).min)
    for block in iter_blocks(path, columns, chunk_lines):
        if columns == 5:
            check_retina_ids(path, block)
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
    # cvstereo.geometry.overlay's convention: x_0 = x_1 + shift, positive when retina 0 is the left camera.
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
        require_columns(p, h, 4)
    res, res_from = resolve_resolution(resolution, headers)
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
    require_columns(path, header, 5)
    res, res_from = resolve_resolution(resolution, [(path, header)])
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
    require_columns(path, header, columns)
    resolution = resolve_resolution(resolution, [(path, header)])[0]
    if one_based is None:
        one_based = detect_one_based([scan_text(path, resolution=resolution, chunk_lines=chunk_lines)])
    source = str(path) if retina is None else f"{path} [retina {retina}]"
    check = ChunkChecker(resolution=resolution, source=source)
    for block in iter_blocks(path, columns, chunk_lines):
        rows, lines = block
        if retina is not None:
            check_retina_ids(path, block)
            keep = rows[:, 4] == retina
            rows, lines = rows[keep], lines[keep]
            if not rows.shape[0]:
                continue
        raw = np.empty(rows.shape[0], RAW_DTYPE)
        for k, name in enumerate(("t", "x", "y", "p")):
            raw[name] = rows[:, k]
        if one_based:
            raw["x"] -= 1
            raw["y"] -= 1
        yield check(raw, locate=LineLocator(path, lines))


__all__ = ["CHUNK_LINES", "TextHeader", "TextScan", "detect_left_retina", "detect_one_based", "iter_text_chunks",
           "open_edvs_merged", "open_edvs_text", "overlay_shift", "read_edvs_merged", "read_edvs_text",
           "read_text_header", "scan_text", "write_edvs_merged", "write_edvs_pair", "write_edvs_text"]
