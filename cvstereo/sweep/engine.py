"""Running a sweep: cell keys, one cell (match + evaluate), the resumable run on Dask or here."""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from cvstereo._signals import held_stop_signals
from cvstereo.matchers.registry import ENTRY_POINT_GROUP
from cvstereo.sweep.cells import CELLS, FIGURE_COLUMNS, TIMING_COLUMNS, empty_row, error_text, read_cell, write_cell
from cvstereo.sweep.grid import Cell

__all__ = ["Score", "SweepResult", "cell_key", "check_output_folder", "file_digest", "recording_digest", "run_cell",
           "run_sweep", "source_digest"]

if TYPE_CHECKING:
    from cvstereo.model.matches import MatchResult
    from cvstereo.model.recording import Recording

#: Bytes read per block when hashing a recording.
_DIGEST_BLOCK = 1 << 20


def file_digest(path: str | os.PathLike) -> str:
    """sha256 of a regular file's bytes (hex), read in 1 MiB blocks up to the size it had when opened.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        As the readers do for what is no regular file: a FIFO would block, ``/dev/zero`` never end.
    """
    from cvstereo.io.files import open_regular

    h = hashlib.sha256()
    with open_regular(path) as fh:
        left = os.fstat(fh.fileno()).st_size
        while left > 0 and (block := fh.read(min(_DIGEST_BLOCK, left))):
            h.update(block)
            left -= len(block)
    return h.hexdigest()


def recording_digest(recording: Recording) -> str:
    """sha256 of an in-memory recording's events, ground truth and sensor size (hex)."""
    import numpy as np

    h = hashlib.sha256(json.dumps(list(recording.resolution)).encode())
    for array in (recording.left, recording.right, recording.left_disparity, recording.right_disparity):
        if array is None:
            h.update(b"\0none")
            continue
        array = np.ascontiguousarray(array)
        h.update(f"\0{array.dtype.str}{array.shape}".encode())
        h.update(array.tobytes())
    return h.hexdigest()


def source_digest() -> str:
    """sha256 over the package's Python source files (cvstereo and the matcher packages it finds).

    Part of every cell key, so that a changed matcher never reuses a stale result although the version
    number stays the same.
    """
    import cvstereo

    roots = {Path(cvstereo.__file__).parent}
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        spec = importlib.util.find_spec(ep.value.split(":")[0].split(".")[0])
        if spec is not None and spec.origin is not None:
            roots.add(Path(spec.origin).parent)
    h = hashlib.sha256()
    for root in sorted(roots):
        for file in sorted(root.rglob("*.py")):
            h.update(file.relative_to(root.parent).as_posix().encode())
            h.update(b"\0")
            h.update(file.read_bytes())
    return h.hexdigest()


#: ``score(cell, recording, result) -> figures``: extra figures of a cell beside :data:`FIGURE_COLUMNS`.
Score = Callable[[Cell, "Recording", "MatchResult"], dict]


def cell_key(cell: Cell, recording_digest: str, code_digest: str, score: Score | None = None) -> str:
    """The cell's identity: recording content, method, variant, parameters, source code and the ``score``
    function adding figures, if any (hex, 24)."""
    text = json.dumps({"recording": recording_digest, "method": cell.method, "variant": cell.variant,
                       **({"param_set": cell.param_set} if cell.param_set else {}),
                       **({"score": _function_name(score)} if score is not None else {}),
                       "params": [[k, v] for k, v in cell.params], "code": code_digest}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _function_name(fn) -> str:
    return f"{fn.__module__}.{fn.__qualname__}"


def run_cell(cell: Cell, score: Score | None = None, recording: Recording | None = None) -> dict:
    """Match and evaluate one cell; never raises for a bad cell (the error is in the row).

    Parameters
    ----------
    cell : Cell
    score : callable, optional
        ``score(cell, recording, result) -> dict`` of further figures for the row (a module-level function,
        so that Dask can send it to the workers); its figures are added after :data:`FIGURE_COLUMNS`.

    Returns
    -------
    dict
        :data:`FIGURE_COLUMNS`, :data:`TIMING_COLUMNS`, ``error`` (None when the cell ran) and the figures of
        ``score``.
    recording : Recording, optional
        The recording in memory (in-process runs); None: read from ``cell.recording``, a path.
    """
    row = empty_row(worker=f"{os.uname().nodename}:{os.getpid()}")
    start = time.perf_counter()
    try:
        from cvstereo.evaluation.metrics import evaluate
        from cvstereo.geometry.source import as_matched
        from cvstereo.io import read_recording
        from cvstereo.run import match

        extra = {"param_set": cell.param_set} if cell.param_set else {}
        # One thread per cell: cells run side by side, one per worker process (docs/guide/threads.md).
        result = match(cell.recording if recording is None else recording, method=cell.method,
                       variant=cell.variant, threads=1, **extra, **dict(cell.params))
        if recording is None:
            recording = read_recording(cell.recording)
        figures = evaluate(as_matched(recording, result.meta), result)  # in the order the rig check left the cameras
        for name in (*FIGURE_COLUMNS, "events_per_s", "realtime_x"):
            row[name] = _plain(figures.get(name))
        if score is not None:
            row.update((name, _plain(value)) for name, value in score(cell, recording, result).items())
    except Exception as exc:  # a failing cell is recorded, never fatal to the sweep
        row["error"] = error_text(exc)
    row["elapsed_s"] = time.perf_counter() - start
    return row


def _plain(value):
    """JSON-safe scalar: NaN -> None, numpy numbers -> Python numbers."""
    if value is None:
        return None
    value = value.item() if hasattr(value, "item") else value
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@dataclass
class SweepResult:
    """Rows in grid order, and what the run did.

    Attributes
    ----------
    rows : list of dict
        One per cell: ``key``, ``recording``, ``method``, ``variant``, ``params`` (JSON), one
        ``param.NAME`` column per swept parameter, the figures, timing columns and ``error``.
    computed, reused, failed : int
        Cells run now, cells taken from an earlier run of the same sweep, cells with an error.
    recomputed : int
        Cells whose file from an earlier run was not a whole row of the cell (:func:`cvstereo.sweep.cells.trusted`),
        run again (counted in ``computed`` too).
    """

    rows: list[dict] = field(default_factory=list)
    computed: int = 0
    reused: int = 0
    failed: int = 0
    recomputed: int = 0


def run_sweep(cells: Sequence[Cell], out_dir: str | os.PathLike, *, workers: int | None = None,
              scheduler: str | None = None, progress: bool = False,
              on_row: Callable[[Cell, dict], None] | None = None, score: Score | None = None,
              recordings: Mapping[str, Recording] | None = None,
              log: Callable[[str], None] | None = None) -> SweepResult:
    """Run every cell not already in ``out_dir`` and return all rows in grid order.

    Parameters
    ----------
    cells : sequence of Cell
    out_dir : path-like
        Output folder (made by the first finished cell, none before); ``cells/`` inside it keeps one JSON
        file per finished cell. A cell file that is not a whole row of its cell is recomputed.
    workers : int, optional, keyword-only
        Worker processes of the local cluster (default: one per core); 0 runs the cells here, one after
        another, without Dask.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler (``tcp://host:8786``); then ``workers`` is ignored.
    progress : bool, keyword-only
        Progress bar with cells done / failed / remaining.
    on_row : callable, optional
        Called with (cell, row) as each cell finishes (rows of earlier runs are not reported).
    score : callable, optional
        Further figures per cell, see :func:`run_cell` (part of the cell key).
    recordings : mapping, optional
        Recordings in memory, by the name the cells give as ``recording`` (their key hashes their arrays);
        only with ``workers=0``, since workers read recordings from paths.
    log : callable, optional, keyword-only
        Called with a line of text at the slow steps (a local cluster starting).

    Raises
    ------
    ValueError
        In-memory recordings with workers or a scheduler.
    NotADirectoryError
        ``out_dir`` or its ``cells/`` exists and is not a folder.
    FileNotFoundError, IsADirectoryError, OSError
        A recording that is no regular file, or a cell file that is no regular file.

    Returns
    -------
    SweepResult
    """
    in_memory = dict(recordings or {})
    if in_memory and (workers != 0 or scheduler is not None):
        raise ValueError("recordings in memory are matched in this process only (workers=0): workers read "
                         "recordings from paths, so give the cells file paths to run them on workers.")
    out = Path(out_dir)
    check_output_folder(out, what="out_dir")
    code = source_digest()
    digests: dict[str, str] = {}
    keys = []
    for cell in cells:
        if cell.recording not in digests:
            rec = in_memory.get(cell.recording)
            digests[cell.recording] = file_digest(cell.recording) if rec is None else recording_digest(rec)
        keys.append(cell_key(cell, digests[cell.recording], code, score))
    done, untrusted = {}, 0
    for key in dict.fromkeys(keys):
        row, bad = read_cell(out, key)
        untrusted += bad
        if row is not None:
            done[key] = row
    todo = [(k, c) for k, c in dict(zip(keys, cells, strict=True)).items() if k not in done]
    result = SweepResult(reused=len(done), recomputed=untrusted)
    bar = _bar(progress, total=len(todo), reused=len(done))

    def finished(key: str, cell: Cell, row: dict) -> None:
        (out / CELLS).mkdir(parents=True, exist_ok=True)  # made by the first result: a failed start leaves none
        with held_stop_signals():  # a stop while a result is written keeps it: the cell is done
            write_cell(out, key, row)
        done[key] = row
        result.computed += 1
        if on_row is not None:
            on_row(cell, row)
        if bar is not None:
            bar.update()
            bar.set_postfix(failed=sum(r.get("error") is not None for r in done.values()))

    try:
        if todo and workers == 0 and scheduler is None:
            for key, cell in todo:
                finished(key, cell, run_cell(cell, score, in_memory.get(cell.recording)))
        elif todo:
            from cvstereo.sweep.dask_run import run_on_dask

            run_on_dask(todo, finished, run=run_cell, workers=workers, scheduler=scheduler, score=score, log=log)
    finally:
        if bar is not None:
            bar.close()
    out.mkdir(parents=True, exist_ok=True)  # for the table, also of a grid without cells
    result.rows = [_table_row(cell, key, done[key]) for cell, key in zip(cells, keys, strict=True)]
    result.failed = sum(r["error"] is not None for r in result.rows)
    return result


def check_output_folder(out: str | os.PathLike, *, what: str) -> None:
    """Refuse an output folder that exists as something else (a file, ``/dev/null``, a FIFO), or whose
    ``cells/`` does, naming it as ``what`` (``-o``, ``out_dir``); an absent one is fine (it is made)."""
    for path in (Path(out), Path(out) / CELLS):
        if os.path.exists(path) and not os.path.isdir(path):
            raise NotADirectoryError(f"{what} {path}: exists and is not a folder; a sweep writes results.parquet, "
                                     "summary.md and cells/ into a folder.")


def _bar(enabled: bool, *, total: int, reused: int):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="cell", desc=f"sweep ({reused} done before)" if reused else "sweep", leave=False)


def _table_row(cell: Cell, key: str, row: dict) -> dict:
    out = {"key": key, "recording": cell.recording, "method": cell.method, "variant": cell.variant or "default",
           "param_set": cell.param_set or "default",
           "params": json.dumps(dict(cell.params), sort_keys=True)}
    out.update({f"param.{k}": v for k, v in cell.params})
    out.update({name: row.get(name) for name in (*FIGURE_COLUMNS, *TIMING_COLUMNS, "error")})
    # Figures of a score function (run_cell), after the standard columns.
    out.update({name: value for name, value in row.items() if name not in out})
    return out
