"""Sweep speed-up: the same grid on a LocalCluster with 1 and with 2 workers (``cvstereo.sweep``).

Run: ``python bench/bench_sweep.py [-o bench/results]``. Prints wall-clock seconds per worker count, the
ratio, and the load average before and after each run (a loaded machine cannot look like a slow sweep);
writes ``sweep.md`` and ``sweep.json``. Each run starts from an empty output folder, so nothing is reused.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from cvstereo.sweep import Grid, resolve_recordings, run_sweep

#: Six presets cut to 2 s, every variant of the event-time and frame matchers, two thresholds each:
#: 6 x (4 x 2 + 4 x 2) = 96 cells of similar size, enough to keep two workers busy.
RECORDINGS = [f"preset:{n}:2" for n in ("1arm-50cm", "1arm-100cm", "1arm-150cm", "2arms-50cm", "2arms-100cm",
                                         "2arms-150cm")]
GRIDS = [Grid(("event-time",), ("all",), (("threshold", (0.6, 0.8)),)),
         Grid(("frame",), ("all",), (("threshold", (1.0, 1.2)),))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="bench/results", help="folder for sweep.md / sweep.json")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    recordings = resolve_recordings(RECORDINGS, progress=True)
    cells = [c for g in GRIDS for c in g.cells(recordings)]
    runs = []
    for n in args.workers:
        load_before = os.getloadavg()[0]
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            result = run_sweep(cells, tmp, workers=n)
            wall = time.perf_counter() - start
        load_after = os.getloadavg()[0]
        runs.append({"workers": n, "cells": len(cells), "wall_s": wall, "failed": result.failed,
                     "load_before": load_before, "load_after": load_after})
        print(f"{n} worker(s): {len(cells)} cells in {wall:.1f} s (load {load_before:.2f} -> {load_after:.2f})")
    base = runs[0]["wall_s"]
    lines = ["# Sweep speed-up (cvstereo.sweep on a LocalCluster)", "",
             f"{len(cells)} cells (match + evaluate): event-time and frame, every variant, two thresholds, on six "
             "presets cut to 2 s. Machine: "
             f"{os.cpu_count()} cores. Date: {time.strftime('%Y-%m-%d %H:%M')}.", "",
             "| workers | wall s | speed-up | load before | load after |", "|---:|---:|---:|---:|---:|"]
    for r in runs:
        r["speedup"] = base / r["wall_s"]
        lines.append(f"| {r['workers']} | {r['wall_s']:.1f} | {r['speedup']:.2f}x | {r['load_before']:.2f} | "
                     f"{r['load_after']:.2f} |")
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep.md").write_text("\n".join(lines) + "\n")
    (out / "sweep.json").write_text(json.dumps(runs, indent=2))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
