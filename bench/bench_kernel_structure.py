"""Old against new matchers in one process, interleaved: did a change of the kernels' structure keep their speed?

Issue 25 item 7 names the kernels' structure (named stream rows, named clock columns, named constants, the
polarity sign from one function); each change is kept only if the matcher it touches runs at least 0.97 times
as fast as before. This script measures that: it extracts the package as it was at ``--base`` (default fb04c6d)
into a temporary folder as ``cvstereo_old`` (its imports of ``cvstereo`` rewritten), so that both versions'
kernels compile side by side, then feeds the same simulated clip (2 s of 2arms-50cm) through the old and the new
class of each matcher, alternately, ``--runs`` times, after one untimed run each (compilation). The machine may
be shared: the load average is printed beside each pair, and the figure reported is the ratio old time / new
time (> 1: the new one is faster) of the medians, which a load shared by both halves of a pair cancels.

Run::

    .venv/bin/python bench/bench_kernel_structure.py                  # every touched matcher, 5 runs
    .venv/bin/python bench/bench_kernel_structure.py -m event-area --runs 9
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ["NUMBA_NUM_THREADS"] = "1"

import argparse  # noqa: E402
import importlib  # noqa: E402
import io  # noqa: E402
import re  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import tarfile  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

#: Matcher -> (module, class) in the package; the matchers whose kernels or shared helpers the change touched.
MATCHERS = {
    "event-area": ("matchers.event_area.matcher", "EventAreaMatcher"),
    "event-vector": ("matchers.event_vector.matcher", "EventVectorMatcher"),
    "event-time": ("matchers.event_time.matcher", "EventTimeMatcher"),
    "frame": ("matchers.frame.matcher", "FrameClusterMatcher"),
    "frame-area": ("matchers.frame_area.matcher", "FrameAreaMatcher"),
    "fused": ("matchers.fused.matcher", "FusedMatcher"),
}

_IMPORT = re.compile(r"^(\s*)(from|import)(\s+)cvstereo(?=[.\s])", re.MULTILINE)


def extract_old(base: str, into: Path) -> None:
    """The package at ``base`` as ``into/cvstereo_old``, every ``cvstereo`` import rewritten to it."""
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", base, "cvstereo"], check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(tar)) as archive:
        archive.extractall(into, filter="data")
    (into / "cvstereo").rename(into / "cvstereo_old")
    for path in (into / "cvstereo_old").rglob("*.py"):
        path.write_text(_IMPORT.sub(r"\1\2\3cvstereo_old", path.read_text()))


def run_once(cls, rec) -> float:
    matcher = cls(resolution=rec.resolution)
    start = time.perf_counter()
    matcher.feed(rec.left, rec.right)
    matcher.flush()
    return time.perf_counter() - start


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="fb04c6d", help="the old revision (default fb04c6d)")
    parser.add_argument("-m", "--method", action="append", choices=sorted(MATCHERS), help="default: all")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args(argv)
    from cvstereo.simulate import simulate_preset

    rec = simulate_preset("2arms-50cm", seconds=args.seconds, seed=0)
    with tempfile.TemporaryDirectory(prefix="bench_kernel_structure_") as tmp:
        extract_old(args.base, Path(tmp))
        sys.path.insert(0, tmp)
        for method in args.method or sorted(MATCHERS):
            module, name = MATCHERS[method]
            new = getattr(importlib.import_module(f"cvstereo.{module}"), name)
            old = getattr(importlib.import_module(f"cvstereo_old.{module}"), name)
            run_once(old, rec), run_once(new, rec)  # compile both
            times = {"old": [], "new": []}
            for r in range(args.runs):
                order = ("old", "new") if r % 2 == 0 else ("new", "old")
                for which in order:
                    times[which].append(run_once(old if which == "old" else new, rec))
                print(f"  {method} run {r + 1}: old {times['old'][-1]:.3f} s, new {times['new'][-1]:.3f} s, "
                      f"load {os.getloadavg()[0]:.1f}", flush=True)
            ratio = statistics.median(times["old"]) / statistics.median(times["new"])
            print(f"{method}: old/new time ratio of the medians {ratio:.3f} ({args.runs} runs each)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
