"""The fused kernel's work inflation: CPU time of the parallel build (split passes) on ONE thread, one chunk, over
the serial build (fused passes), on the same windows.

Two threads can at best speed the kernel up by 2 / inflation, and the CPU time of one thread is a figure a shared
machine disturbs far less than a wall-clock speed-up (run it under ``taskset -c 0``). The windows' inputs are
captured from a one-thread run of the whole recording (every ``--every``-th window, so that memory stays small),
then both builds are replayed on them, alternately, ``--rounds`` times; the answers of the two are compared too.

Run::

    taskset -c 0 .venv/bin/python bench/bench_fused_work.py                     # both cases of bench_threads
    taskset -c 0 .venv/bin/python bench/bench_fused_work.py --case "346x260, 1 M events/s" --every 4
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # --threads N needs N

import argparse
import statistics
import time

import numpy as np

import cvstereo.matchers.fused.matcher as fused_matcher
from cvstereo.benchmark.timing import load_average
from cvstereo.matchers.fused._kernels import match_features, match_features_parallel
from cvstereo.matchers.fused._parallel import chunks_for
from cvstereo.run import match


def capture(rec, params: dict, every: int) -> tuple[list, object]:
    """Every ``every``-th window's kernel arguments (copies) from a one-thread run, and the matcher's scratch."""
    windows, seen = [], [0]
    original = fused_matcher.match_features

    def spy(fl, fr, counts, active, recent, prior, prm, scratch, split, chunks):
        if seen[0] % every == 0:
            windows.append((fl.copy(), fr.copy(), counts.astype(np.int32), active.copy(), recent.copy(),
                            prior.astype(np.float32), prm, int(active.sum())))
        seen[0] += 1
        return original(fl, fr, counts, active, recent, prior, prm, scratch, split, chunks)

    fused_matcher.match_features = spy
    try:
        match(rec, method="fused", threads=1, **params)
    finally:
        fused_matcher.match_features = original
    return windows


def cached_capture(case: str, recs, params: dict, every: int, cache: str | None) -> list:
    """:func:`capture`, kept in ``cache`` (a folder) between runs when given."""
    import pickle

    name = "".join(c if c.isalnum() else "-" for c in case)
    path = Path(cache) / f"fused-work-{name}-{every}.pkl" if cache else None
    if path is not None and path.exists():
        return pickle.loads(path.read_bytes())
    windows = capture(recs[case](), params, every)
    if path is not None:
        path.write_bytes(pickle.dumps(windows))
    return windows


def replay(windows: list, kernel, split: bool, scratch, chunks: int = 1, clock=time.process_time) -> tuple[float, list]:
    """``clock`` seconds (process CPU time unless given) of ``kernel`` over every window, in ``chunks`` chunks
    (arguments restored to their dtypes outside the clock)."""
    args = [(fl, fr, counts.astype(np.int64), active, recent, prior.astype(np.float64), prm)
            for fl, fr, counts, active, recent, prior, prm, _ in windows]
    answers = []
    t0 = clock()
    for fl, fr, counts, active, recent, prior, prm in args:
        answers.append(kernel(fl, fr, counts, active, recent, prior, prm, scratch, split, chunks))
    return clock() - t0, answers


def main() -> int:
    import bench_threads

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append", choices=[bench_threads.SPEED_CASE, bench_threads.DENSE_CASE])
    parser.add_argument("--every", type=int, default=3, help="capture every n-th window")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1,
                        help="N > 1: the parallel build's WALL time on N threads (NUMBA_NUM_THREADS=N in the "
                             "environment) over the serial build's, rather than its work on one")
    parser.add_argument("--chunks", type=int, help="chunks of the parallel build (default: 1, or the threads')")
    parser.add_argument("--against", metavar="REV",
                        help="also the parallel build of revision REV, interleaved (a load shared by both cancels)")
    parser.add_argument("--cache", help="a folder to keep the captured windows in between runs")
    args = parser.parse_args()
    cases = args.case or [bench_threads.SPEED_CASE, bench_threads.DENSE_CASE]
    recs = {case: (lambda case=case: bench_threads.recordings({case}, quick=False)[case]) for case in cases}
    resolution = {bench_threads.SPEED_CASE: (640, 480), bench_threads.DENSE_CASE: (346, 260)}
    old_parallel = None
    if args.against:
        import importlib
        import tempfile

        before = dict(os.environ)  # bench_kernel_structure sets NUMBA_NUM_THREADS=1 for its own runs
        from bench_kernel_structure import extract_old

        os.environ.clear()
        os.environ.update(before)

        into = Path(tempfile.mkdtemp(prefix="fused-work-"))
        extract_old(args.against, into)
        sys.path.insert(0, str(into))
        old_parallel = importlib.import_module("cvstereo_old.matchers.fused._kernels").match_features_parallel
    for case in cases:
        params = bench_threads.range_params(case, "fused")
        windows = cached_capture(case, recs, params, args.every, args.cache)
        # The scratch for the range the run used (match() scales it to the sensor's width).
        scratch = fused_matcher.Scratch(resolution[case], windows[0][6].max_d + 1).kernel_for(
            max(w[-1] for w in windows))
        serial_s, parallel_s = [], []
        replay(windows[:2], match_features, False, scratch)  # compile / load
        replay(windows[:2], match_features_parallel, True, scratch)
        if old_parallel is not None:
            replay(windows[:2], old_parallel, True, scratch)
        old_s = []
        if args.threads > 1:
            import numba

            numba.set_num_threads(args.threads)
        chunks = args.chunks or (chunks_for(args.threads) if args.threads > 1 else 1)
        clock = time.perf_counter if args.threads > 1 else time.process_time
        load = load_average()
        same = True
        for _ in range(args.rounds):
            s, a = replay(windows, match_features, False, scratch, 1, clock)
            p, b = replay(windows, match_features_parallel, True, scratch, chunks, clock)
            serial_s.append(s)
            if old_parallel is not None:
                old_s.append(replay(windows, old_parallel, True, scratch, chunks, clock)[0])
            parallel_s.append(p)
            same = same and all(all(np.array_equal(u, v, equal_nan=u.dtype.kind == "f")
                                    for u, v in zip(x, y, strict=True)) for x, y in zip(a, b, strict=True))
        s, p = statistics.median(serial_s), statistics.median(parallel_s)
        ratio = f"speed-up {s / p:.2f}x" if args.threads > 1 else f"inflation {p / s:.2f}x"
        print(f"{case}: {len(windows)} windows, serial {s:.3f} s, split on {args.threads} thread(s) in {chunks} "
              f"chunks {p:.3f} s, {ratio}, same answers: {same}, load {load:.1f} -> {load_average():.1f}", flush=True)
        if old_s:
            print(f"    {args.against}'s split {statistics.median(old_s):.3f} s: new/old per round "
                  + ", ".join(f"{q / o:.2f}" for q, o in zip(parallel_s, old_s, strict=True)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
