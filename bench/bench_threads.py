"""Speed of every matcher on 1, 2 and N threads (N: the cores this process may use): issue 28 item 1.

Cells: every matcher's default (the adaptive set's default variant; fused, the OpenCV baselines and dv-semidense
as they come) on ``sensor-640x480`` with a 128 px range (bench/bench_speed.py's case ``640x480, 128 px``: its
recording and its range rule), and fused on the 346x260 recording of about 1 M events/s of
bench/results/fused-suite.md (bench/bench_fused.py's speed recording). Another cell is one line in :data:`CELLS`.

Each cell: a warm-up on the first 0.2 s at every thread count (compiling is not matching), then ``--rounds``
rounds (at least 3); a round runs ``match()`` once per thread count, in turn, the order rotated from round to
round so that no count always runs first. A figure is the median over the rounds of the matcher's own wall time
(``elapsed_s``: a parallel run's gain is wall time; its CPU time adds the threads'), the speed-up is the median
one-thread time over the median N-thread time, and the 1-minute load average before -> after stands beside each
cell: on a shared machine the figures mean little, the speed-ups less. The matches of every thread count are
checked equal to one thread's (a cell whose matches differ is marked, and the run exits 1).

Run: ``.venv/bin/python bench/bench_threads.py [--quick] [--only METHOD ...] [--rounds 3]``. Writes
``bench/results/threads.md`` and ``threads.json`` (``-o`` for another folder).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import bench_speed  # noqa: E402
import numba  # noqa: E402  (before bench_fused, which sets NUMBA_NUM_THREADS=1 for its own one-core runs)
import numpy as np  # noqa: E402

from cvstereo._threads import available_cores, pool_size, threading_layer  # noqa: E402
from cvstereo.benchmark.timing import load_average  # noqa: E402
from cvstereo.matchers.registry import available_methods, matcher_class  # noqa: E402
from cvstereo.run import match  # noqa: E402

#: bench_speed's case at 640x480 with a 128 px range, and the fused speed recording of fused-suite.md.
SPEED_CASE = "640x480, 128 px"
DENSE_CASE = "346x260, 1 M events/s"
#: The cells: (case, method). One line per cell.
CELLS = [
    *((SPEED_CASE, m) for m in (*bench_speed.THESIS_METHODS, "fused", "stereobm", "sgbm", "dv-semidense")),
    (DENSE_CASE, "fused"),
]
#: Issue 28's targets: speed-up from 1 to 2 threads (median of the rounds).
TARGETS = {(SPEED_CASE, "event-area"): 1.7, (SPEED_CASE, "event-vector"): 1.7, (SPEED_CASE, "fused"): 1.7,
           (DENSE_CASE, "fused"): 1.7}
QUICK_SECONDS = 1.0
WARM_UP_US = 200_000


def _import_bench_fused():
    """bench_fused, imported without keeping the environment it sets for its own one-core runs (numba would read
    NUMBA_NUM_THREADS=1 at its next configuration check and refuse it, its pool being started)."""
    before = dict(os.environ)
    import bench_fused

    os.environ.clear()
    os.environ.update(before)
    return bench_fused


def recordings(cases: set[str], quick: bool) -> dict:
    """Case -> Recording in memory (cut to QUICK_SECONDS with ``--quick``)."""
    from cvstereo.io import read_recording

    out = {}
    if SPEED_CASE in cases:
        out[SPEED_CASE] = read_recording(bench_speed.case_paths([SPEED_CASE])[SPEED_CASE])
    if DENSE_CASE in cases:
        out[DENSE_CASE] = _import_bench_fused().dense_346x260()
    if quick:
        out = {name: _first(rec, int(QUICK_SECONDS * 1e6)) for name, rec in out.items()}
    return out


def _first(rec, span_us: int):
    t0 = int(min(rec.left["t"][0], rec.right["t"][0]))
    return rec.slice_time(t0, t0 + span_us)


def range_params(case: str, method: str) -> dict:
    """bench_speed's range rule for the case: the default range of a sensor ``range_width`` px wide."""
    width = bench_speed.CASES[case][1] if case in bench_speed.CASES else None
    fields = matcher_class(method).Params.__dataclass_fields__
    if width is None or "max_disparity" not in fields:  # dv-semidense has a fixed range
        return {}
    return {"max_disparity": matcher_class(method).max_disparity_for(fields["max_disparity"].default, width, {})}


def measure_cell(rec, method: str, params: dict, counts: list[int], rounds: int) -> dict:
    """Median wall time per thread count over ``rounds`` interleaved rounds, and whether the matches agree.

    The default rig check is left out (``rig_check=False``), as in bench_speed: its time is not the matcher's
    (``elapsed_s`` never counted it) and at 640x480 it took longer than the matching it preceded."""
    params = {**params, "rig_check": False}
    for n in counts:
        match(_first(rec, WARM_UP_US), method=method, threads=n, **params)
    seconds: dict[int, list[float]] = {n: [] for n in counts}
    matches: dict[int, np.ndarray] = {}
    load_before = load_average()
    for r in range(rounds):
        for n in counts[r % len(counts):] + counts[: r % len(counts)]:
            result = match(rec, method=method, threads=n, **params)
            seconds[n].append(result.meta["elapsed_s"])
            matches.setdefault(n, result.matches)
    medians = {n: statistics.median(s) for n, s in seconds.items()}
    return {"seconds": {str(n): s for n, s in seconds.items()}, "median_s": {str(n): m for n, m in medians.items()},
            "speedup": {str(n): medians[1] / medians[n] for n in counts},
            "same_matches": all(np.array_equal(matches[n], matches[1]) for n in counts),
            "events": int(rec.left.size + rec.right.size), "duration_s": rec.duration_s,
            "matches": len(matches[1]), "load_before": load_before, "load_after": load_average()}


def markdown(results: dict) -> str:
    counts = results["counts"]
    lines = ["# Matchers on 1, 2 and N threads", "",
             f"Generated by `bench/bench_threads.py{' --quick' if results['quick'] else ''}` on {results['date']}: "
             f"{results['cores']} cores usable, numba's threading layer `{results['layer']}`, numba's pool "
             f"{results['pool']}. Each figure: the median over {results['rounds']} interleaved rounds of `match()`'s "
             "own wall time on the recording in memory, after a warm-up at every thread count; speed-up: the "
             "threads=1 median over the threads=N one; the 1-minute load average before -> after each cell beside "
             "(on a loaded machine the figures mean little). `same`: the matches of every thread count equal "
             "threads=1's.", "",
             "| case | matcher | events | " + " | ".join(f"threads={n} s" for n in counts) + " | "
             + " | ".join(f"{n} vs 1" for n in counts[1:]) + " | target 2 vs 1 | same | load |",
             "|---|---|---:|" + "---:|" * len(counts) + "---:|" * (len(counts) - 1) + "---|---|---|"]
    for c in results["cells"]:
        target = TARGETS.get((c["case"], c["method"]))
        met = "-" if target is None or "2" not in c["speedup"] else \
            f"{target:g}x {'met' if c['speedup']['2'] >= target else 'missed'}"
        lines.append(f"| {c['case']} | {c['method']} | {c['events']:,} | "
                     + " | ".join(f"{c['median_s'][str(n)]:.3f}" for n in counts) + " | "
                     + " | ".join(f"{c['speedup'][str(n)]:.2f}x" for n in counts[1:])
                     + f" | {met} | {'yes' if c['same_matches'] else '**no**'} | "
                     f"{c['load_before']:.1f} -> {c['load_after']:.1f} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=str(ROOT / "bench" / "results"), help="folder for threads.md/.json")
    parser.add_argument("--quick", action="store_true", help=f"the first {QUICK_SECONDS:g} s of each recording")
    parser.add_argument("--only", nargs="+", metavar="METHOD", default=None, help="only these methods")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds per cell (at least 3)")
    args = parser.parse_args()
    if args.rounds < 3:
        parser.error("--rounds: at least 3 (a median of fewer says little)")
    cores = available_cores()
    counts = sorted({1, 2, cores})
    installed = set(available_methods())
    cells = [(case, m) for case, m in CELLS if m in installed and (args.only is None or m in args.only)]
    recs = recordings({case for case, _ in cells}, args.quick)
    results = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "quick": args.quick, "cores": cores,
               "pool": pool_size(), "numba": numba.__version__, "rounds": args.rounds, "counts": counts,
               "cells": []}
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    for case, method in cells:
        cell = {"case": case, "method": method,
                **measure_cell(recs[case], method, range_params(case, method), counts, args.rounds)}
        results["layer"] = threading_layer()  # the layer that ran, once a parallel kernel started it
        results["cells"].append(cell)
        print(f"{case:22s} {method:14s} " + "  ".join(f"threads={n} {cell['median_s'][str(n)]:.3f} s"
                                                      for n in counts)
              + f"  2 vs 1 {cell['speedup'].get('2', float('nan')):.2f}x  same {cell['same_matches']}  "
              f"load {cell['load_before']:.1f}->{cell['load_after']:.1f}", flush=True)
        (out / "threads.md").write_text(markdown(results))
        (out / "threads.json").write_text(json.dumps(results, indent=1))
    print(markdown(results))
    return 0 if all(c["same_matches"] for c in results["cells"]) else 1


if __name__ == "__main__":
    sys.exit(main())
