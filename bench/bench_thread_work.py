"""Work and serial share of event-area and event-vector on 1 and 2 threads (issue 28 item 1), for a loaded machine.

On a shared machine wall-time speed-ups say little; what a change to the row bands can be judged by is the work
(process CPU time) of the 2-band run against the 1-band run, and the serial share (the time outside the kernel).
Run it pinned to one core (``taskset -c 0``): both threads then share it, so that the CPU time is the work and
not the speed. Cells: bench/bench_threads.py's case ``640x480, 128 px`` (the whole recording), ``--rounds``
rounds of ``match()`` per thread count in turn (``rig_check=False``: the matcher's work only), the medians of:
``elapsed_s``, process CPU time, the kernel's CPU time (the band kernel's calls, all threads) and the CPU time
outside it (on 2 threads that includes the merges, which run on both threads; on 1 thread it is the serial part).
The matches of both counts are checked equal.

Run: ``taskset -c 0 .venv/bin/python bench/bench_thread_work.py [--rounds 3] [METHOD ...]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import bench_threads  # noqa: E402
import numpy as np  # noqa: E402

from cvstereo.matchers.registry import matcher_class  # noqa: E402
from cvstereo.run import match  # noqa: E402

COUNTS = (1, 2)


def timed_kernels(cls, spent: list[float]) -> tuple:
    """The class's kernels wrapped so that each call adds its process CPU time to ``spent[0]``."""
    def wrap(kernel):
        def call(*args):
            start = time.process_time()
            out = kernel(*args)
            spent[0] += time.process_time() - start
            return out
        return call
    return tuple(wrap(k) for k in cls.kernels)


def measure(rec, method: str, rounds: int) -> dict[int, dict[str, float]]:
    cls = matcher_class(method)
    params = bench_threads.range_params(bench_threads.SPEED_CASE, method)
    kernels, spent = cls.kernels, [0.0]
    cls.kernels = timed_kernels(cls, spent)
    try:
        for n in COUNTS:  # compiling is not work
            match(bench_threads._first(rec, bench_threads.WARM_UP_US), method=method, threads=n, rig_check=False,
                  **params)
        rows: dict[int, list[tuple[float, float, float]]] = {n: [] for n in COUNTS}
        first: dict[int, np.ndarray] = {}
        for r in range(rounds):
            for n in COUNTS[r % 2:] + COUNTS[:r % 2]:
                spent[0] = 0.0
                cpu = time.process_time()
                result = match(rec, method=method, threads=n, rig_check=False, **params)
                rows[n].append((result.meta["elapsed_s"], time.process_time() - cpu, spent[0]))
                first.setdefault(n, result.matches)
    finally:
        cls.kernels = kernels
    if not np.array_equal(first[1], first[2]):
        raise SystemExit(f"{method}: the matches of 2 threads differ from 1 thread's")
    out = {}
    for n, runs in rows.items():
        elapsed, cpu, kernel = (statistics.median(r[i] for r in runs) for i in range(3))
        out[n] = {"elapsed_s": elapsed, "cpu_s": cpu, "kernel_cpu_s": kernel, "outside_cpu_s": cpu - kernel}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("methods", nargs="*", default=["event-area", "event-vector"])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    rec = bench_threads.recordings({bench_threads.SPEED_CASE}, quick=False)[bench_threads.SPEED_CASE]
    print("| matcher | threads | elapsed s | CPU s | kernel CPU s | outside CPU s | outside share |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for method in args.methods:
        for n, m in measure(rec, method, args.rounds).items():
            print(f"| {method} | {n} | {m['elapsed_s']:.3f} | {m['cpu_s']:.3f} | {m['kernel_cpu_s']:.3f} | "
                  f"{m['outside_cpu_s']:.3f} | {m['outside_cpu_s'] / m['cpu_s']:.0%} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
