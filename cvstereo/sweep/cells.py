"""Cell files: one JSON file per finished cell in ``OUT/cells/``, trusted only when it holds a whole row.

A resumed sweep takes a cell file's row instead of running the cell, so a file that is not a complete row of
*that* cell (cut short, emptied by hand, copied from another cell, edited into NaN) would put a wrong or empty
line in the table. Such a file is recomputed, and the sweep counts it; a path there that is not a regular
file (a FIFO would block the read) is refused.
"""

from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path

__all__ = ["CELLS", "FIGURE_COLUMNS", "MAX_CELL_BYTES", "TIMING_COLUMNS", "cell_path", "empty_row", "error_text",
           "read_cell", "trusted", "write_cell"]

#: Figures of :func:`cvstereo.evaluation.metrics.evaluate` kept per cell.
FIGURE_COLUMNS = ("matches", "coverage", "bad1", "bad2", "mae", "rmse", "median_ae", "false_rate", "mean", "std",
                  "truth_mean")
#: Columns that depend on the machine and the moment, not on the grid.
TIMING_COLUMNS = ("elapsed_s", "events_per_s", "realtime_x", "worker")
#: The folder of the cell files inside a sweep's output folder.
CELLS = "cells"
#: A cell file is a few hundred bytes; one larger than this is no cell file of ours (and is not read whole).
MAX_CELL_BYTES = 1 << 20


def empty_row(*, worker: str = "", error: str | None = None) -> dict:
    """A row with every column and no figures yet: :func:`cvstereo.sweep.engine.run_cell` fills them in, or
    ``error`` says why there are none (:func:`error_text`)."""
    row: dict = dict.fromkeys(FIGURE_COLUMNS)
    row.update(dict.fromkeys(TIMING_COLUMNS), worker=worker, elapsed_s=0.0, error=error)
    return row


def error_text(exc: BaseException) -> str:
    """A failed cell's ``error``: ``TYPE: message`` on one line."""
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def cell_path(out: Path, key: str) -> Path:
    return out / CELLS / f"{key}.json"


def write_cell(out: Path, key: str, row: dict) -> None:
    """Write a finished cell's row, with its key (so that a file copied to another cell's name is told apart)."""
    from cvstereo.io.atomic import write_text_atomic

    write_text_atomic(cell_path(out, key), json.dumps({**row, "key": key}, sort_keys=True))


def read_cell(out: Path, key: str) -> tuple[dict | None, bool]:
    """The row of a finished cell, and whether a file was there but could not be trusted (:func:`trusted`).

    Returns
    -------
    row : dict or None
        None: no file, or one that is not a whole row of this cell (recompute it).
    untrusted : bool
        A file was there and was not taken.

    Raises
    ------
    OSError
        The path is a directory, FIFO, device or socket.
    """
    path = cell_path(out, key)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return None, False
    if not stat.S_ISREG(mode):
        raise OSError(f"{path}: not a regular file, where the sweep keeps a finished cell; remove it and run the "
                      "sweep again.")
    with open(path, "rb") as fh:
        data = fh.read(MAX_CELL_BYTES + 1)
    try:
        row = json.loads(data.decode("utf-8")) if len(data) <= MAX_CELL_BYTES else None
    except ValueError:  # JSONDecodeError and UnicodeDecodeError
        row = None
    return (row, False) if trusted(row, key) else (None, True)


def trusted(row, key: str) -> bool:
    """Whether ``row`` is a whole row of the cell ``key``: its key, every figure and timing column with a value
    of its type (finite numbers or None; an int count of matches where the cell ran), an error that is None or
    text, and any further figures (of a score function) JSON scalars."""
    if not isinstance(row, dict) or row.get("key") != key:
        return False
    if not all(name in row for name in (*FIGURE_COLUMNS, *TIMING_COLUMNS, "error")):
        return False
    if not (row["error"] is None or isinstance(row["error"], str)) or not isinstance(row["worker"], str):
        return False
    if row["error"] is None and not (_number(row["matches"]) and row["matches"] == int(row["matches"]) >= 0):
        return False
    if not (_number(row["elapsed_s"]) and row["elapsed_s"] >= 0):
        return False
    figures = {*FIGURE_COLUMNS, *TIMING_COLUMNS} - {"worker"}
    return all(value is None or _number(value) or (name not in figures and isinstance(value, bool | str))
               for name, value in row.items() if name not in ("key", "error", "worker"))


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
