"""Speed of every matcher at 128x128, 346x260 and 640x480, on one core, optionally beside an older commit.

Cases (simulated; the disparity range follows the sensor width, as the library's default does, because
the rig's focal length scales with it): the robustness suite's ``base`` (128x128, 64 px), the motorcycle
scene (128x128), ``sensor-346x260`` (173 px) and ``sensor-640x480`` (320 px), and ``sensor-640x480`` with
a 128 px range (issue 16's targets are stated for that range; it is each matcher's default range for a
256 px wide sensor: 128 px for the thesis' five, 127 for OpenCV's count of 128, 94 for fused, whose 128 px
default is 47; dv-semidense keeps its fixed range). Matchers: frame, frame-area, event-time,
event-area, event-vector (each default variant under the ``thesis`` and the ``adaptive`` set), fused,
stereobm, sgbm and dv-semidense (where installed).

Each measurement runs in a child process pinned to one CPU (``NUMBA_NUM_THREADS=1``,
``cv2.setNumThreads(1)``, ``sched_setaffinity``), on the recording already in memory, after a warm-up run
on its first 0.2 s (compile time is not matching time). A figure is the matcher's own time (``elapsed_s``
of :func:`cvstereo.run.match`), or with ``--clock cpu`` the child's CPU time around that call, which
the other processes of a loaded machine inflate far less; repeated until two runs agree within 10 %
(:mod:`cvstereo.benchmark.timing`, at most 6 runs), with the 1-minute load average before and after. With
``--baseline COMMIT`` a second child runs the same cells on a temporary ``git worktree`` of that commit (on
``PYTHONPATH``), one run of old and new in turn per cell, and the table gains the old figure and the ratio
new/old.

Run: ``.venv/bin/python bench/bench_speed.py [--quick] [--only METHOD ...] [--baseline COMMIT]``. Writes
``bench/results/speed.md`` and ``speed.json`` (``-o`` for another folder); needs the robustness suite
(generated into the cache on first use; ``CVSTEREO_CACHE=/work/cache`` has it).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cvstereo.benchmark.timing import TOLERANCE, Agreement  # noqa: E402

#: Matchers (method, parameter set; None: the method has no sets), in table order.
THESIS_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector")
COMBOS = (*((m, s) for m in THESIS_METHODS for s in ("thesis", "adaptive")),
          ("fused", None), ("stereobm", None), ("sgbm", None), ("dv-semidense", None))
#: Cases: name -> (recording, disparity range rule). The rule is the sensor width whose default range is
#: wanted: None, the recording's own width (the library's default); 256: twice the 128 px default, a 128 px
#: range for the thesis' matchers (64 px x 256 / 128).
CASES = {
    "128x128": ("suite:base", None),
    "motorcycle 128x128": ("motorcycle", None),
    "346x260": ("suite:sensor-346x260", None),
    "640x480": ("suite:sensor-640x480", None),
    "640x480, 128 px": ("suite:sensor-640x480", 256),
}
#: Issue 16's targets, input events per second on one core at 640x480 with a 128 px range (both sets), and
#: event-vector on the motorcycle scene.
TARGETS = {("640x480, 128 px", m): 5e6 for m in ("frame", "frame-area", "event-time")}
TARGETS |= {("640x480, 128 px", m): 2e6 for m in ("event-area", "event-vector")}
TARGETS |= {("motorcycle 128x128", "event-vector"): 3e6}
#: --same-work: the parameters that switch off, in this tree, the work issue 24 added on purpose (the border rule
#: of the adaptive set, fused and the OpenCV baselines; fused's partner test; dv-semidense's range scaled with the
#: width), so that a comparison with a tree from before it measures the code's cost on the same work: by method
#: ("*": every method that has the parameter). The table's `same` column says whether the matches then equal the
#: old tree's.
SAME_WORK = {"*": {"border_horizon_us": 0}, "fused": {"border_rows": -1}, "dv-semidense": {"max_disparity": 47}}
#: Length of every clip with --quick (first seconds of each recording).
QUICK_SECONDS = 1.0
WARM_UP_US = 200_000

# --------------------------------------------------------------------------------------------- child

#: The child: reads JSON requests on stdin, answers one timed run each on stdout. It only uses APIs that
#: older commits have too (match, read_recording, matcher_class), since it also runs their code.
_CHILD = r"""
import json, os, sys, time
cpu, warm_up_us, tree = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {cpu})
# The matchers by name come from the measured tree's own pyproject.toml, not from the installed distribution's
# metadata: the venv's cvstereo names this tree's classes, which an older tree does not have (0.2 found its
# matchers only through entry points; 0.3 has a built-in table and merges entry points into it).
import importlib.metadata, tomllib
with open(os.path.join(tree, "pyproject.toml"), "rb") as f:
    _own = (tomllib.load(f)["project"].get("entry-points") or {}).get("cvstereo.matchers", {})
_own = importlib.metadata.EntryPoints(importlib.metadata.EntryPoint(n, v, "cvstereo.matchers") for n, v in _own.items())
_installed_entry_points = importlib.metadata.entry_points
def _tree_entry_points(**selection):
    if selection.get("group") == "cvstereo.matchers":
        return _own
    return _installed_entry_points(**selection)
importlib.metadata.entry_points = _tree_entry_points
import cv2
cv2.setNumThreads(1)
import cvstereo
from cvstereo.io import read_recording
from cvstereo.pipeline import match  # the 0.2 names: older trees have them, 0.3 answers them (cvstereo._compat)
from cvstereo.registry import available_methods, matcher_class

import inspect
# The default rig check of 0.3 (issue 24) is left out: the speed compared is the matcher's on the same events in
# both trees (the check may shift a camera's rows; its cost is bench/results/rig-shift.md's).
if "rig_check" in inspect.signature(match).parameters:
    match = __import__("functools").partial(match, rig_check=False)
recordings, warm = {}, set()
print(json.dumps({"ready": True, "cvstereo": os.path.dirname(cvstereo.__file__),
                  "methods": list(available_methods())}), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    key = (req["path"], req["seconds"])
    if key not in recordings:
        rec = read_recording(req["path"])
        if req["seconds"]:
            t0 = int(min(rec.left["t"][0], rec.right["t"][0]))
            rec = rec.slice_time(t0, t0 + int(req["seconds"] * 1e6))
        recordings[key] = rec
    rec = recordings[key]
    kwargs = {"param_set": req["param_set"]} if req["param_set"] else {}
    fields = matcher_class(req["method"]).Params.__dataclass_fields__
    if req["range_width"] and "max_disparity" in fields:  # dv-semidense has a fixed range
        kwargs["max_disparity"] = matcher_class(req["method"]).max_disparity_for(
            fields["max_disparity"].default, req["range_width"], {})
    overrides = req.get("overrides", {})
    kwargs.update({k: v for k, v in {**overrides.get("*", {}), **overrides.get(req["method"], {})}.items()
                   if k in fields})
    wkey = (req["method"], req["param_set"], key, req["range_width"])
    if wkey not in warm:
        t0 = int(min(rec.left["t"][0], rec.right["t"][0]))
        match(rec.slice_time(t0, t0 + warm_up_us), method=req["method"], **kwargs)
        warm.add(wkey)
    best, calls, spent = None, 0, 0.0
    # A run is the least of `repeat` calls back to back, and of as many as fill `min_seconds` (timeit's rule):
    # a 10 ms call is at the mercy of one slow scheduling slice, the least of fifty is not.
    while calls < req.get("repeat", 1) or spent < req.get("min_seconds", 0.0):
        cpu_start = time.process_time()
        result = match(rec, method=req["method"], **kwargs)
        cpu_s = time.process_time() - cpu_start
        seconds = cpu_s if req.get("clock") == "cpu" else result.meta["elapsed_s"]
        best = seconds if best is None else min(best, seconds)
        calls, spent = calls + 1, spent + seconds
    print(json.dumps({"seconds": best,
                      "input_events": result.meta["input_events"], "duration_s": rec.duration_s,
                      "matches": len(result),
                      "max_disparity": (result.meta.get("params") or {}).get("max_disparity")}), flush=True)
"""


class Child:
    """A measuring child process running the code in ``code_dir`` on one CPU."""

    def __init__(self, code_dir: Path, cpu: int, overrides: dict | None = None):
        self.overrides = overrides or {}
        env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
               "PYTHONPATH": os.pathsep.join([str(code_dir), os.environ.get("PYTHONPATH", "")])}
        # cwd outside any tree, so that only PYTHONPATH decides which code is imported.
        self.proc = subprocess.Popen([sys.executable, "-c", _CHILD, str(cpu), str(WARM_UP_US), str(code_dir)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                                     cwd=tempfile.gettempdir())
        hello = self._read()
        self.code = hello["cvstereo"]
        self.methods = set(hello["methods"])

    def _read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the measuring child for {self.code if hasattr(self, 'code') else 'a tree'} "
                               "stopped (see its error above).")
        return json.loads(line)

    def run(self, **request) -> dict:
        """One run of ``request`` (with this child's parameter overrides, those its matcher has)."""
        self.proc.stdin.write(json.dumps({**request, "overrides": self.overrides}) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


@contextmanager
def baseline_tree(commit: str | None):
    """A temporary ``git worktree`` of ``commit`` (None: nothing), removed afterwards."""
    if commit is None:
        yield None
        return
    with tempfile.TemporaryDirectory(prefix="cvstereo-baseline-") as tmp:
        tree = Path(tmp) / "tree"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree), commit], check=True)
        try:
            yield tree
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)


# ------------------------------------------------------------------------------------------- measure

def case_paths(names: list[str]) -> dict[str, str]:
    """Recording path of each case (the suite's recordings and the bench's motorcycle scene, cached)."""
    from cvstereo.benchmark.harness import EXTRA_SECONDS, _cached_simulation
    from cvstereo.simulate import MotorcycleScene, simulate, suite_recordings

    wanted = {CASES[n][0].partition(":")[2] for n in names if CASES[n][0].startswith("suite:")}
    suite = dict(suite_recordings("robustness", only=sorted(wanted), progress=True)) if wanted else {}
    out = {}
    for name in names:
        spec = CASES[name][0]
        if spec == "motorcycle":
            out[name] = str(_cached_simulation(f"motorcycle-{EXTRA_SECONDS}s", lambda: simulate(
                MotorcycleScene(), seconds=EXTRA_SECONDS, seed=0)))
        else:
            out[name] = str(suite[spec.partition(":")[2]])
    return out


def measure_cell(children: dict[str, Child], request: dict, rounds: int = 0) -> dict:
    """One cell on every code version, one run of each in turn, until each has two runs within 10 % and at
    least ``rounds`` runs: then round ``i`` is run ``i`` of every version, taken back to back, so that
    ``old / new`` per round compares the two under the same load (``ratios``)."""
    agreements = {v: Agreement() for v in children}
    last = {}
    for a in agreements.values():
        a.start()

    def wanted(version: str) -> bool:
        return not agreements[version].done or len(agreements[version].seconds) < rounds

    while any(wanted(v) for v in children):
        for version, child in children.items():
            if wanted(version):
                last[version] = child.run(**request)
                agreements[version].add(last[version]["seconds"])
    out = {}
    for version, a in agreements.items():
        t = a.result()
        info = last[version]
        out[version] = {**t.to_dict(), "events_per_s": info["input_events"] / t.seconds,
                        "realtime_x": info["duration_s"] / t.seconds, "input_events": info["input_events"],
                        "duration_s": info["duration_s"], "matches": info["matches"],
                        "max_disparity": info["max_disparity"]}
    if rounds and {"new", "old"} <= set(out):
        paired = zip(agreements["old"].seconds[:rounds], agreements["new"].seconds[:rounds], strict=True)
        out["ratios"] = [old_s / new_s for old_s, new_s in paired]
    return out


def label(method: str, param_set: str | None) -> str:
    return method if param_set is None else f"{method} ({param_set})"


def run(args, save) -> dict:
    """Measure every case and combo; ``save(results)`` after each cell, so that an interrupted run keeps
    what it measured."""
    cases = [c for c in CASES if args.cases is None or c in args.cases]
    paths = case_paths(cases)
    cpu = args.cpu if args.cpu is not None else max(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
        else 0
    results = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "cpu": cpu, "nice": os.nice(0),
               "quick": args.quick, "clock": args.clock, "repeat": args.repeat,
               "min_seconds": args.min_seconds, "same_work": args.same_work,
               "baseline": args.baseline, "rounds": args.rounds if args.baseline else 0, "cells": []}
    with baseline_tree(args.baseline) as base:
        children = {"new": Child(ROOT, cpu, SAME_WORK if args.same_work else None)}
        if base is not None:
            children["old"] = Child(base, cpu)
        try:
            installed = set.intersection(*(c.methods for c in children.values()))
            combos = [(m, s) for m, s in COMBOS if (not args.only or m in args.only) and m in installed]
            results["missing"] = [m for m, _ in COMBOS if (not args.only or m in args.only) and m not in installed]
            for case in cases:
                for method, param_set in combos:
                    request = {"path": paths[case], "seconds": QUICK_SECONDS if args.quick else None,
                               "method": method, "param_set": param_set, "range_width": CASES[case][1],
                               "clock": args.clock, "repeat": args.repeat,
                               "min_seconds": args.min_seconds}
                    cell = {"case": case, "method": method, "param_set": param_set,
                            **measure_cell(children, request, args.rounds if base is not None else 0)}
                    results["cells"].append(cell)
                    print(cell_line(cell), flush=True)
                    save(results)
        finally:
            for child in children.values():
                child.close()
    return results


# -------------------------------------------------------------------------------------------- report

def _mev(x: float) -> str:
    return f"{x / 1e6:.2f} M"


def _note(r: dict) -> str:
    flag = "" if r["agreed"] else " *"
    return f"{r['runs']}{flag}, {r['load_before']:.1f}->{r['load_after']:.1f}"


def cell_line(cell: dict) -> str:
    new = cell["new"]
    text = (f"{cell['case']:20s} {label(cell['method'], cell['param_set']):26s} {_mev(new['events_per_s'])} ev/s "
            f"{new['realtime_x']:6.1f}x RT ({_note(new)})")
    if "old" in cell:
        old = cell["old"]
        text += (f" | old {_mev(old['events_per_s'])} ev/s ({_note(old)}), "
                 f"new/old {old['seconds'] / new['seconds']:.2f}x")
    return text


def markdown(results: dict) -> str:
    base, nice, rounds = results["baseline"], results.get("nice"), results.get("rounds", 0)
    cpu_clock = results.get("clock") == "cpu"
    repeat, min_seconds = results.get("repeat", 1), results.get("min_seconds", 0.0)
    clock = "the measuring process's CPU time" if cpu_clock else "the matcher's own clock"
    lines = ["# Matcher speed at three sensor sizes, one core", "",
             f"Generated by `bench/bench_speed.py{' --quick' if results['quick'] else ''}"
             f"{f' --baseline {base}' if base else ''}{' --clock cpu' if cpu_clock else ''}"
             f"{f' --repeat {repeat}' if repeat > 1 else ''}"
             f"{f' --min-seconds {min_seconds:g}' if min_seconds else ''}"
             f"{' --same-work' if results.get('same_work') else ''}` on {results['date']}, "
             f"pinned to CPU {results['cpu']} of "
             f"{os.cpu_count()}{f', at nice {nice}' if nice else ''}. "
             "Input events per second and times real time of `match()` on the recording in "
             f"memory ({clock}, after a warm-up); "
             + (f"a run is the least time of {repeat} calls back to back"
                + (f" or of as many as take {min_seconds:g} s" if min_seconds else "") + "; "
                if repeat > 1 or min_seconds else "")
             + "each figure is the faster of the first two runs "
             f"within {TOLERANCE * 100:g} % of each other (at most 6 runs); `runs` gives their number (`*`: no "
             "two agreed, the fastest shown) and the 1-minute load average before -> after. "
             + (f"`old` is commit `{base}` measured in the same run, one run of old and new in turn per cell; "
                "`new/old` is the speed ratio." if base else "")
             + (f" Each version also ran at least {rounds} times, in turn; round i is run i of old and of new, back "
                "to back, and the last column gives the median and the least of old/new time per round." if rounds
                else ""), ""]
    if results.get("missing"):
        lines += [f"Not installed here, not measured: {', '.join(results['missing'])}.", ""]
    for case in dict.fromkeys(c["case"] for c in results["cells"]):
        cells = [c for c in results["cells"] if c["case"] == case]
        first = cells[0]["new"]
        lines += [f"## {case}: {first['input_events']:,} events, {first['duration_s']:.2f} s", "",
                  "| matcher | range px | events/s | x real time | runs, load |"
                  + (" old events/s | old runs, load | new/old |" if base else "")
                  + (" median, least new/old per round |" if rounds else ""),
                  "|---|---:|---:|---:|---|" + ("---:|---|---:|" if base else "") + ("---:|" if rounds else "")]
        for c in cells:
            new = c["new"]
            row = (f"| {label(c['method'], c['param_set'])} | {new['max_disparity'] or 'default'} | "
                   f"{_mev(new['events_per_s'])} | {new['realtime_x']:.1f} | {_note(new)} |")
            if base:
                old = c["old"]
                row += f" {_mev(old['events_per_s'])} | {_note(old)} | {old['seconds'] / new['seconds']:.2f}x |"
            if rounds:
                ratios = c.get("ratios") or [math.nan]
                row += f" {statistics.median(ratios):.2f}x, {min(ratios):.2f}x |"
            lines.append(row)
        lines.append("")
    target_rows = [c for c in results["cells"] if (c["case"], c["method"]) in TARGETS]
    if target_rows:
        lines += ["## Issue 16's targets (one core)", "",
                  "| case | matcher | target | events/s | met |" + (" old events/s |" if base else ""),
                  "|---|---|---:|---:|---|" + ("---:|" if base else "")]
        for c in target_rows:
            target, fig = TARGETS[(c["case"], c["method"])], c["new"]["events_per_s"]
            lines.append(f"| {c['case']} | {label(c['method'], c['param_set'])} | {_mev(target)} | {_mev(fig)} | "
                         f"{'met' if fig >= target else 'missed'} |"
                         + (f" {_mev(c['old']['events_per_s'])} |" if base else ""))
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default=str(ROOT / "bench" / "results"), help="folder for speed.md/.json")
    parser.add_argument("--quick", action="store_true", help=f"the first {QUICK_SECONDS:g} s of each recording")
    parser.add_argument("--only", nargs="+", metavar="METHOD", default=None, help="only these methods")
    parser.add_argument("--cases", nargs="+", metavar="CASE", default=None, choices=list(CASES),
                        help="only these cases (default: all)")
    parser.add_argument("--baseline", metavar="COMMIT", default=None,
                        help="also measure this commit (a temporary git worktree), interleaved with this tree")
    parser.add_argument("--rounds", type=int, default=3, metavar="N",
                        help="with --baseline: at least N runs of each version per cell, in turn, and the median and "
                             "least new/old per round in the table (default 3)")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                        help="time match() by the wall clock (its own elapsed_s, default) or by the child's CPU time "
                             "(on a shared machine: time taken by others is not counted, cache contention still is)")
    parser.add_argument("--repeat", type=int, default=1, metavar="K",
                        help="each run is the least time of K calls back to back (default 1): a host's transient "
                             "slowdowns (other virtual machines, frequency) lengthen single calls, not the least")
    parser.add_argument("--min-seconds", type=float, default=0.0, metavar="S",
                        help="each run also calls match() until its calls took S seconds in all (default 0): short "
                             "runs are then the least of many calls")
    parser.add_argument("--same-work", action="store_true",
                        help="run this tree with the work issue 24 added switched off (SAME_WORK), for a comparison "
                             "with --baseline on the same work")
    parser.add_argument("--cpu", type=int, default=None, help="CPU to pin the children to (default: the last)")
    args = parser.parse_args()
    known = {m for m, _ in COMBOS}
    bad = [m for m in args.only or () if m not in known]
    if bad:
        parser.error(f"--only {' '.join(bad)}: not measured here; choose from {', '.join(sorted(known))}")
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)

    def save(results: dict) -> None:
        (out / "speed.md").write_text(markdown(results))
        (out / "speed.json").write_text(json.dumps(results, indent=1))

    results = run(args, save)
    save(results)
    print(markdown(results))


if __name__ == "__main__":
    main()
