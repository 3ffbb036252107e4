"""Parameter sweeps over many recordings on Dask distributed: what ``cvstereo sweep`` runs.

A sweep is a grid of *cells*, one per recording x method x variant x combination of parameter values; a
cell is one :func:`match` plus :func:`cvstereo.evaluate.evaluate`. Cells run on a Dask cluster: a
``LocalCluster`` with one single-threaded worker process per core by default (nothing to set up), or an
existing cluster given by its scheduler address. Workers get the recording's *path*, never its events, and
stream it themselves, so nothing large travels through the scheduler.

Every finished cell is written at once to ``OUT/cells/KEY.json``; the key hashes the recording's content,
the method, variant and parameters, and the package's source files (the version number does not change
when the code does). A sweep started again with the same output folder therefore only runs the cells that
are missing: an interrupted sweep resumes, and a changed matcher recomputes. A cell that fails (a corrupt
file, a bug) is stored with its error and never stops the others. The table is assembled in grid order, so
the same grid gives the same table whatever the number of workers (timing columns aside:
:data:`TIMING_COLUMNS`).

>>> grid = Grid(methods=("event-area",), params=(("threshold", (1.5, 2.5)),))
>>> [c.label for c in grid.cells(["a.npz"])]  # doctest: +SKIP
['event-area/gaussian [threshold=1.5] on a.npz', 'event-area/gaussian [threshold=2.5] on a.npz']
"""

from __future__ import annotations

import glob
import hashlib
import importlib.metadata
import importlib.util
import itertools
import json
import math
import os
import time
import tomllib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from cvstereo.registry import ENTRY_POINT_GROUP

#: Figures of :func:`cvstereo.evaluate.evaluate` kept per cell.
FIGURE_COLUMNS = ("matches", "coverage", "bad1", "bad2", "mae", "rmse", "median_ae", "false_rate", "mean", "std")
#: Columns that depend on the machine and the moment, not on the grid.
TIMING_COLUMNS = ("elapsed_s", "events_per_s", "realtime_x", "worker")
#: Figures where smaller is better (the others, e.g. coverage, are better larger).
LOWER_IS_BETTER = frozenset({"bad1", "bad2", "mae", "rmse", "median_ae", "false_rate", "std"})


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a matcher configuration on one recording.

    Attributes
    ----------
    recording : str
        Path of the recording file (workers read it themselves).
    method : str
        Matcher name (formats.md).
    variant : str or None
        Variant name; None: the method's default.
    params : tuple of (name, value)
        Parameter overrides, sorted by name.
    param_set : str or None
        The parameter set (``thesis``, ``adaptive``) the overrides apply to; None: the default set.
    """

    recording: str
    method: str
    variant: str | None
    params: tuple[tuple[str, object], ...] = ()
    param_set: str | None = None

    @property
    def label(self) -> str:
        """``method/variant [k=v,...] on FILE``, as progress and errors show it."""
        extra = ",".join(f"{k}={v}" for k, v in self.params)
        config = f"{self.method}/{self.variant or 'default'}" + (f" [{extra}]" if extra else "")
        if self.param_set:
            config += f" ({self.param_set} set)"
        return f"{config} on {Path(self.recording).name}"


@dataclass(frozen=True)
class Grid:
    """Methods x variants x parameter values, expanded over recordings by :meth:`cells`.

    Attributes
    ----------
    methods : tuple of str
    variants : tuple of str, optional
        Variants to run for every method; empty: each method's default variant; ``("all",)``: every variant.
    params : tuple of (name, values)
        Each parameter with the values to try. A parameter applies to the methods whose parameter class
        has it; a name that no chosen method knows is an error.
    param_sets : tuple of str or None
        Parameter sets to run each configuration under (``thesis``, ``adaptive``); ``(None,)``: the default.
        Applied to the methods that have sets (the thesis' five), others run once.
    """

    methods: tuple[str, ...]
    variants: tuple[str, ...] = ()
    params: tuple[tuple[str, tuple], ...] = ()
    param_sets: tuple[str | None, ...] = (None,)

    def cells(self, recordings: Sequence[str]) -> list[Cell]:
        """Every cell, in a fixed order: recording, then method, variant and parameter values.

        Raises
        ------
        ValueError
            Unknown method, a variant a method does not have, or a parameter no method has.
        """
        from cvstereo.registry import matcher_class

        used: set[str] = set()
        configs = []
        for method in self.methods:
            cls = matcher_class(method)
            fields = set(cls.Params.__dataclass_fields__)
            if self.variants == ("all",):
                variants = list(cls.variants)
            elif self.variants:
                bad = [v for v in self.variants if v not in cls.variants]
                if bad:
                    raise ValueError(f"method '{method}' has no variant {', '.join(bad)}; it has: "
                                     f"{', '.join(cls.variants)}.")
                variants = list(self.variants)
            else:
                variants = [None]  # the method's default variant
            mine = [(k, vals) for k, vals in self.params if k in fields]
            used.update(k for k, _ in mine)
            names = [k for k, _ in mine]
            for variant in variants:
                for values in itertools.product(*(vals for _, vals in mine)):
                    for param_set in (self.param_sets if _has_param_sets(method) else (None,)):
                        configs.append((method, variant, tuple(sorted(zip(names, values, strict=True))),
                                        param_set))
        unknown = [k for k, _ in self.params if k not in used]
        if unknown:
            raise ValueError(f"parameter(s) {', '.join(unknown)} belong to none of the methods "
                             f"{', '.join(self.methods)}; see `cvstereo match --list-methods`.")
        return [Cell(os.fspath(r), m, v, p, ps) for r in recordings for m, v, p, ps in configs]


def _has_param_sets(method: str) -> bool:
    """Whether a method has the thesis/adaptive parameter sets (the thesis' five do, the peers do not)."""
    try:
        from cvstereo.param_sets import PARAM_SETS
    except ImportError:
        return False
    from cvstereo.registry import matcher_class

    return "threshold_mode" in matcher_class(method).Params.__dataclass_fields__ and bool(PARAM_SETS)


def read_grid_file(path: str | os.PathLike) -> tuple[list[Grid], list[str], dict]:
    """Read a TOML grid file.

    The file has optional top-level ``recordings`` (list of specs, see :func:`resolve_recordings`) and
    ``figure``, and one ``[[grid]]`` table per block of methods::

        recordings = ["preset:1arm-100cm:2", "data/*.npz"]
        figure = "bad2"

        [[grid]]
        methods = ["event-area", "event-vector"]
        variants = ["all"]
        params = { threshold = [1.5, 2.5] }

    Returns
    -------
    grids : list of Grid
    recordings : list of str
    options : dict
        The other top-level keys (e.g. ``figure``).
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not a valid TOML grid file: {exc}") from None
    blocks = data.pop("grid", None)
    if not isinstance(blocks, list) or not blocks:
        raise ValueError(f"{path}: needs at least one [[grid]] table with `methods = [...]`.")
    grids = []
    for i, block in enumerate(blocks):
        methods = block.get("methods", [block["method"]] if "method" in block else None)
        if not methods:
            raise ValueError(f"{path}: [[grid]] number {i + 1} has no `methods`.")
        params = block.get("params", {})
        grids.append(Grid(tuple(methods), tuple(block.get("variants", ())),
                          tuple((k, tuple(v if isinstance(v, list) else [v])) for k, v in params.items()),
                          tuple(block.get("param_sets", (None,)))))
    recordings = data.pop("recordings", [])
    return grids, list(recordings), data


def resolve_recordings(specs: Iterable[str], *, progress: bool = False) -> list[str]:
    """Turn recording specs into file paths, in the order given (duplicates dropped).

    A spec is a path, a glob (``data/*.npz``), ``preset:NAME`` or ``preset:NAME:SECONDS`` (a simulated
    preset, generated once and cached, see :func:`cvstereo.simulate.presets.cached_preset`), or
    ``suite:NAME`` (every recording of a simulated suite, where the simulator has one).

    Raises
    ------
    FileNotFoundError
        A path or glob that matches nothing.
    """
    out: list[str] = []
    for spec in specs:
        if spec.startswith("preset:"):
            from cvstereo.simulate.presets import cached_preset

            _, name, *rest = spec.split(":")
            seconds = float(rest[0]) if rest else None
            out.append(os.fspath(cached_preset(name, seconds=seconds, progress=progress)))
        elif spec.startswith("suite:"):
            out.extend(_suite_paths(spec.partition(":")[2], progress=progress))
        elif any(ch in spec for ch in "*?["):
            found = sorted(glob.glob(spec))
            if not found:
                raise FileNotFoundError(f"recording pattern '{spec}' matches no file.")
            out.extend(found)
        else:
            if not Path(spec).exists():
                raise FileNotFoundError(f"recording '{spec}' does not exist.")
            out.append(spec)
    return list(dict.fromkeys(out))


def _suite_paths(name: str, *, progress: bool) -> list[str]:
    from cvstereo.simulate import suite_recordings

    return [os.fspath(path) for _, path in suite_recordings(name, progress=progress)]


def file_digest(path: str | os.PathLike) -> str:
    """sha256 of a file's bytes (hex), read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
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


def cell_key(cell: Cell, recording_digest: str, code_digest: str) -> str:
    """The cell's identity: recording content, method, variant, parameters and source code (hex, 24)."""
    text = json.dumps({"recording": recording_digest, "method": cell.method, "variant": cell.variant,
                       **({"param_set": cell.param_set} if cell.param_set else {}),
                       "params": [[k, v] for k, v in cell.params], "code": code_digest}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def run_cell(cell: Cell) -> dict:
    """Match and evaluate one cell; never raises for a bad cell (the error is in the row).

    Returns
    -------
    dict
        :data:`FIGURE_COLUMNS`, :data:`TIMING_COLUMNS` and ``error`` (None when the cell ran).
    """
    row: dict = dict.fromkeys(FIGURE_COLUMNS)
    row.update(dict.fromkeys(TIMING_COLUMNS), error=None, worker=f"{os.uname().nodename}:{os.getpid()}")
    start = time.perf_counter()
    try:
        from cvstereo.evaluate import evaluate
        from cvstereo.io import read_recording
        from cvstereo.pipeline import match

        extra = {"param_set": cell.param_set} if cell.param_set else {}
        result = match(cell.recording, method=cell.method, variant=cell.variant, **extra, **dict(cell.params))
        figures = evaluate(read_recording(cell.recording), result)
        for name in (*FIGURE_COLUMNS, "events_per_s", "realtime_x"):
            row[name] = _plain(figures.get(name))
    except Exception as exc:  # a failing cell is recorded, never fatal to the sweep
        row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
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
    """

    rows: list[dict] = field(default_factory=list)
    computed: int = 0
    reused: int = 0
    failed: int = 0


def run_sweep(cells: Sequence[Cell], out_dir: str | os.PathLike, *, workers: int | None = None,
              scheduler: str | None = None, progress: bool = False,
              on_row: Callable[[Cell, dict], None] | None = None) -> SweepResult:
    """Run every cell not already in ``out_dir`` and return all rows in grid order.

    Parameters
    ----------
    cells : sequence of Cell
    out_dir : path-like
        Output folder; ``cells/`` inside it keeps one JSON file per finished cell.
    workers : int, optional, keyword-only
        Worker processes of the local cluster (default: one per core); 0 runs the cells here, one after
        another, without Dask.
    scheduler : str, optional, keyword-only
        Address of an existing Dask scheduler (``tcp://host:8786``); then ``workers`` is ignored.
    progress : bool, keyword-only
        Progress bar with cells done / failed / remaining.
    on_row : callable, optional
        Called with (cell, row) as each cell finishes (rows of earlier runs are not reported).

    Returns
    -------
    SweepResult
    """
    out = Path(out_dir)
    (out / "cells").mkdir(parents=True, exist_ok=True)
    code = source_digest()
    digests: dict[str, str] = {}
    keys = []
    for cell in cells:
        if cell.recording not in digests:
            digests[cell.recording] = file_digest(cell.recording)
        keys.append(cell_key(cell, digests[cell.recording], code))
    done = {k: _read_cell(out, k) for k in dict.fromkeys(keys) if (out / "cells" / f"{k}.json").exists()}
    todo = [(k, c) for k, c in dict(zip(keys, cells, strict=True)).items() if k not in done]
    result = SweepResult(reused=len(done))
    bar = _bar(progress, total=len(todo), reused=len(done))

    def finished(key: str, cell: Cell, row: dict) -> None:
        _write_cell(out, key, row)
        done[key] = row
        result.computed += 1
        if on_row is not None:
            on_row(cell, row)
        if bar is not None:
            bar.update()
            bar.set_postfix(failed=sum(r.get("error") is not None for r in done.values()))

    if todo:
        if workers == 0 and scheduler is None:
            for key, cell in todo:
                finished(key, cell, run_cell(cell))
        else:
            _run_on_dask(todo, finished, workers=workers, scheduler=scheduler)
    if bar is not None:
        bar.close()
    result.rows = [_table_row(cell, key, done[key]) for cell, key in zip(cells, keys, strict=True)]
    result.failed = sum(r["error"] is not None for r in result.rows)
    return result


def _run_on_dask(todo, finished, *, workers: int | None, scheduler: str | None) -> None:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ImportError("cvstereo sweep needs Dask: pip install 'cvstereo[sweep]'.") from None
    cluster = None
    if scheduler is None:
        n = workers or os.cpu_count() or 1
        # One single-threaded process per worker: the matchers are single-threaded numba/numpy code, and
        # processes keep each cell's memory apart. No dashboard: it needs bokeh and a free port.
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futures = {client.submit(run_cell, cell, key=f"cell-{key}", pure=False): (key, cell) for key, cell in todo}
        for future in as_completed(futures):
            key, cell = futures[future]
            finished(key, cell, future.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _bar(enabled: bool, *, total: int, reused: int):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="cell", desc=f"sweep ({reused} done before)" if reused else "sweep", leave=False)


def _write_cell(out: Path, key: str, row: dict) -> None:
    from cvstereo.io._atomic import write_text_atomic

    write_text_atomic(out / "cells" / f"{key}.json", json.dumps(row, sort_keys=True))


def _read_cell(out: Path, key: str) -> dict:
    path = out / "cells" / f"{key}.json"
    try:
        return json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError):
        raise ValueError(f"{path}: not a sweep cell file; delete it to recompute that cell.") from None


def _table_row(cell: Cell, key: str, row: dict) -> dict:
    out = {"key": key, "recording": cell.recording, "method": cell.method, "variant": cell.variant or "default",
           "param_set": cell.param_set or "default",
           "params": json.dumps(dict(cell.params), sort_keys=True)}
    out.update({f"param.{k}": v for k, v in cell.params})
    out.update({name: row.get(name) for name in (*FIGURE_COLUMNS, *TIMING_COLUMNS, "error")})
    return out


def write_table(rows: Sequence[dict], path: str | os.PathLike) -> None:
    """Write the rows as one Parquet table (pyarrow), atomically.

    Parameter columns that only some methods have are null elsewhere; parameters whose values mix types
    across methods are stored as text.
    """
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise ImportError("writing the sweep table needs pyarrow: pip install 'cvstereo[sweep]'.") from None
    from cvstereo.io._atomic import atomic_path

    names = list(dict.fromkeys(k for r in rows for k in r))
    columns = {}
    for name in names:
        values = [r.get(name) for r in rows]
        kinds = {type(v) for v in values if v is not None}
        if name.startswith("param.") and len(kinds - {int, float}) and len(kinds) > 1:
            values = [None if v is None else str(v) for v in values]
        elif kinds <= {int, float} and float in kinds:
            values = [None if v is None else float(v) for v in values]
        columns[name] = values
    table = pa.table(columns)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def summary_markdown(rows: Sequence[dict], *, figure: str = "bad2") -> str:
    """Best parameters per method and variant by the median of ``figure`` over the recordings.

    A configuration that failed on some recording, or whose figure is undefined there (no matches), is
    ranked after those defined on every recording.
    """
    if figure not in FIGURE_COLUMNS:
        raise ValueError(f"figure '{figure}' is not one of {', '.join(FIGURE_COLUMNS)}.")
    sign = 1.0 if figure in LOWER_IS_BETTER else -1.0
    groups: dict[tuple[str, str, str], dict[str, list[dict]]] = {}
    for r in rows:
        key = (r["method"], r["variant"], r.get("param_set", "default"))
        groups.setdefault(key, {}).setdefault(r["params"], []).append(r)
    lines = [f"# Sweep summary: best parameters by median {figure} "
             f"({'lower' if sign > 0 else 'higher'} is better)", "",
             f"| method | variant | set | parameters | median {figure} | median coverage | recordings | failed |",
             "|---|---|---|---|---:|---:|---:|---:|"]
    for (method, variant, param_set), by_params in groups.items():
        scored = []
        for params, cell_rows in by_params.items():
            values = [r[figure] for r in cell_rows if r["error"] is None and r[figure] is not None]
            cover = [r["coverage"] for r in cell_rows if r["error"] is None and r["coverage"] is not None]
            failed = sum(r["error"] is not None for r in cell_rows)
            complete = len(values) == len(cell_rows)
            med = _median(values)
            rank = (not complete, math.inf if med is None else sign * med)
            scored.append((rank, params, med, _median(cover), len(cell_rows), failed))
        rank, params, med, cover, n, failed = min(scored, key=lambda s: s[0])
        lines.append(f"| {method} | {variant} | {param_set} | {_params_text(params)} | {_fmt(med)} | {_fmt(cover)} | "
                     f"{n} | "
                     f"{failed} |")
    return "\n".join(lines) + "\n"


def _median(values: list) -> float | None:
    if not values:
        return None
    s = sorted(values)
    mid = len(s) // 2
    return float(s[mid]) if len(s) % 2 else (s[mid - 1] + s[mid]) / 2.0


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def _params_text(params_json: str) -> str:
    params = json.loads(params_json)
    return ", ".join(f"{k}={v}" for k, v in params.items()) or "defaults"
