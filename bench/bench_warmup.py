"""No compile stalls (issue 28 item 2): after ``cvstereo warm-up`` ran in another process, the first ``match()`` of
each method's default in a fresh process is within 10 % of the second.

The script runs ``cvstereo warm-up`` in a process of its own, then for every available method a fresh process
that reads the 1 s ``2arms-50cm`` clip (simulated once, cached under ``.cache/presets``) and calls ``match()``
on it twice, after importing the matcher's modules (timed apart: a fresh process pays its imports whatever the
cache holds). It prints, per method and as the median of ``--repeat`` fresh processes, the matching time
``match()`` reports (``elapsed_s``) of each call, the wall-clock time of each call (the first also builds the
matcher: loading its kernels from numba's cache and running them once on the built-in clip,
:func:`cvstereo._compile_watch.prepare`), the imports' time, the seconds spent compiling (0 when the cache held every
kernel) and whether the first ``elapsed_s`` is within 10 % of the second; with the load average before and after,
since the machine's load moves every figure.

``.venv/bin/python bench/bench_warmup.py [--method M ...] [--seconds S] [--repeat N]``; writes nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The done criterion: the first call's time over the second's.
TOLERANCE = 0.10

CHILD = """
import json, sys, time
import cvstereo as cvs
from cvstereo._compile_watch import compile_seconds, watch_compiles
watch_compiles()
rec = cvs.read_recording(sys.argv[1])
start = time.perf_counter()
import cvstereo.run
from cvstereo.matchers.registry import matcher_class
matcher_class(sys.argv[2])
out = {"imports_s": time.perf_counter() - start}
for call in ("first", "second"):
    start = time.perf_counter()
    result = cvs.match(rec, method=sys.argv[2])
    out[call] = {"wall_s": time.perf_counter() - start, "elapsed_s": result.meta["elapsed_s"]}
out["compile_s"] = compile_seconds()
print(json.dumps(out))
"""


def _run(argv: list[str]) -> str:
    done = subprocess.run([sys.executable, *argv], capture_output=True, text=True, cwd=ROOT, env=os.environ.copy())
    if done.returncode:
        raise SystemExit(f"{' '.join(argv[:3])} failed: {done.stderr.strip().splitlines()[-1:]}")
    return done.stdout


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", action="append", default=None, help="only this method (repeatable)")
    parser.add_argument("--seconds", type=float, default=1.0, help="length of the 2arms-50cm clip")
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per method (medians reported)")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from cvstereo.matchers.registry import available_methods
    from cvstereo.simulate.presets import cached_preset

    clip = cached_preset("2arms-50cm", seconds=args.seconds)
    methods = args.method or available_methods()
    load_before = os.getloadavg()[0]
    print(_run(["-m", "cvstereo", "warm-up", *[f"--method={m}" for m in methods]]).strip().splitlines()[-1])
    rows, ok = [], True
    for method in methods:
        runs = [json.loads(_run(["-c", CHILD, str(clip), method]).strip().splitlines()[-1])
                for _ in range(args.repeat)]

        def median(key, call=None, runs=runs):
            return statistics.median(r[call][key] if call else r[key] for r in runs)

        first, second = median("elapsed_s", "first"), median("elapsed_s", "second")
        within = first <= second * (1 + TOLERANCE)
        ok &= within
        rows.append(f"| {method} | {first:.3f} | {second:.3f} | {median('wall_s', 'first'):.3f} | "
                    f"{median('wall_s', 'second'):.3f} | {median('imports_s'):.2f} | "
                    f"{max(r['compile_s'] for r in runs):.2f} | {'yes' if within else 'NO'} |")
    print(f"\n2arms-50cm, {args.seconds:g} s, medians of {args.repeat} fresh processes; load average "
          f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after\n")
    print("| method | first elapsed_s | second elapsed_s | first wall s | second wall s | imports s | compiling s "
          "(max) | within 10 % |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
