"""The results of a sweep as a Parquet table and a markdown summary of the best parameters."""

from __future__ import annotations

import json
import math
import os
import statistics
from collections.abc import Sequence

from cvstereo.sweep.cells import FIGURE_COLUMNS

__all__ = ["LOWER_IS_BETTER", "check_figure", "summary_markdown", "write_table"]

#: Figures where smaller is better (the others, e.g. coverage, are better larger).
LOWER_IS_BETTER = frozenset({"bad1", "bad2", "mae", "rmse", "median_ae", "false_rate", "std"})


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
    from cvstereo.io.atomic import atomic_path

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


def check_figure(figure: str, *, where: str = "figure") -> str:
    """``figure`` if the summary can rank by it (one of :data:`FIGURE_COLUMNS`); else a ValueError naming
    ``where`` and the figures, so that a sweep refuses it before running rather than after."""
    if figure not in FIGURE_COLUMNS:
        raise ValueError(f"{where} {figure!r} is not one of {', '.join(FIGURE_COLUMNS)}.")
    return figure


def summary_markdown(rows: Sequence[dict], *, figure: str = "bad2") -> str:
    """Best parameters per method and variant by the median of ``figure`` over the recordings.

    A configuration that failed on some recording, or whose figure is undefined there (no matches), is
    ranked after those defined on every recording.
    """
    check_figure(figure)
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
            med = statistics.median(values) if values else None
            rank = (not complete, math.inf if med is None else sign * med)
            scored.append((rank, params, med, statistics.median(cover) if cover else None, len(cell_rows), failed))
        rank, params, med, cover, n, failed = min(scored, key=lambda s: s[0])
        lines.append(f"| {method} | {variant} | {param_set} | {_params_text(params)} | {_fmt(med)} | {_fmt(cover)} | "
                     f"{n} | "
                     f"{failed} |")
    return "\n".join(lines) + "\n"


def _fmt(value) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def _params_text(params_json: str) -> str:
    params = json.loads(params_json)
    return ", ".join(f"{k}={v}" for k, v in params.items()) or "defaults"
