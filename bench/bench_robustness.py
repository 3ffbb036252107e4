"""Robustness table: every method's default on every recording of the robustness suite v1, both parameter sets.

Run: ``python bench/bench_robustness.py [--workers N] [-o bench/results]``. The cells (recording x method x
parameter set) run through ``cvstereo.sweep`` on a local Dask cluster and are kept in
``bench/results/robustness-cells/``, so a second run only computes what changed. Writes
``robustness.md`` (per recording: coverage, bad2 and false rate of each method under ``thesis`` and
``adaptive``, beside StereoBM, SGBM and dv-semidense; then per method: recordings answered and the median
bad2, a recording where a set answers nothing counting as bad2 = 1 against it) and ``robustness.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path

from cvstereo.matchers.registry import available_methods
from cvstereo.sweep import Grid, resolve_recordings, run_sweep

THESIS_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector")
PEERS = ("stereobm", "sgbm", "dv-semidense", "fused")
SETS = ("thesis", "adaptive")


def _cell(row: dict | None) -> str:
    if row is None:
        return "-"
    if row["error"] is not None:
        return "error"
    cov = row["coverage"] or 0.0
    if not cov:
        return "0"
    return f"{cov:.2f} / {row['bad2']:.2f} / {row['false_rate']:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    parser.add_argument("--only", default=None, metavar="NAME,...", help="only these suite recordings")
    args = parser.parse_args()
    out = Path(args.output)
    from cvstereo.simulate import suite_recordings

    suite = suite_recordings("robustness", progress=True, only=args.only.split(",") if args.only else None)
    recordings = resolve_recordings([os.fspath(p) for _, p in suite])
    name_of = {os.fspath(p): n for n, p in suite}
    installed = set(available_methods())
    peers = tuple(m for m in PEERS if m in installed)
    grids = [Grid(THESIS_METHODS, (), (), SETS), Grid(peers)]
    cells = [c for g in grids for c in g.cells(recordings)]
    load = os.getloadavg()[0]
    start = time.perf_counter()
    result = run_sweep(cells, out / "robustness-cells", workers=args.workers, progress=True)
    wall = time.perf_counter() - start
    names = [name_of[r] for r in recordings]
    by = {(name_of[r["recording"]], r["method"], r["param_set"]): r for r in result.rows}
    columns = [(m, s) for m in THESIS_METHODS for s in SETS] + [(m, "default") for m in peers]
    lines = ["# Robustness suite v1: every method's default, both parameter sets", "",
             f"{len(recordings)} recordings of `cvstereo simulate --suite robustness` (2.5 s each, around the "
             "1arm-100cm preset, one factor at a time, plus joint draws and the fan). Each cell: coverage / bad2 / "
             "false rate (evaluation.md); `0`: no match. Method = its default variant under that set. "
             f"{len(cells)} cells on {args.workers or os.cpu_count()} Dask workers in {wall:.0f} s "
             f"(load {load:.2f} before; {result.reused} cells from an earlier run, {result.failed} failed). "
             f"Date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.", "",
             "| recording | " + " | ".join(f"{m} ({s})" if s != "default" else m for m, s in columns) + " |",
             "|---|" + "---|" * len(columns)]
    for name in names:
        lines.append(f"| {name} | " + " | ".join(_cell(by.get((name, m, s))) for m, s in columns) + " |")
    lines += ["", "## Per method", "",
              "Answered: recordings with coverage > 0. Median bad2 over all recordings, a recording without "
              "matches counting as 1 (issue 12: it counts against the set that is silent there).", "",
              "| method | set | answered | median bad2 | median coverage |", "|---|---|---:|---:|---:|"]
    summary = {}
    for m, s in columns:
        rows = [by.get((n, m, s)) for n in names]
        ok = [r for r in rows if r is not None and r["error"] is None]
        answered = [r for r in ok if (r["coverage"] or 0) > 0]
        bad2 = sorted((r["bad2"] if r in answered and r["bad2"] is not None else 1.0) for r in ok)
        cover = sorted((r["coverage"] or 0.0) for r in ok)
        med = statistics.median(bad2) if bad2 else math.nan
        medc = statistics.median(cover) if cover else math.nan
        summary[f"{m}/{s}"] = {"answered": len(answered), "recordings": len(names), "median_bad2": med,
                               "median_coverage": medc}
        lines.append(f"| {m} | {s} | {len(answered)}/{len(names)} | {med:.3f} | {medc:.3f} |")
    out.mkdir(parents=True, exist_ok=True)
    (out / "robustness.md").write_text("\n".join(lines) + "\n")
    (out / "robustness.json").write_text(json.dumps({"summary": summary, "rows": result.rows}, indent=1,
                                                    default=str))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
