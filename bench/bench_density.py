"""Density sweep (issue 12): how the matchers' coverage and accuracy follow the events per edge.

``ArmsScene(arms=1, distance_m=1.0)``, 3 s, seed 7, seen by the thesis' rig with both sensors' ON and OFF
contrast thresholds multiplied by k (events per edge fall roughly as 1/k), for k in 0.5, 1, 2, 3. Every
method's default variant runs on each recording, beside OpenCV's StereoBM and SGBM and dv-processing's
semi-dense matcher (a method whose optional extra is not installed is skipped, with a note). Coverage and
bad2 (share of matches more than 2 px off) come from :func:`cvstereo.evaluation.metrics.evaluate`.

``--param-set thesis|adaptive`` is passed to :func:`calibration_free.match` for the thesis' five methods when
the installed ``match()`` has a ``param_set`` parameter; otherwise the thesis constants run and the output
says so. Results go to ``bench/results/density.json`` and ``.md``, one section per parameter set actually
run (a run replaces its own set's section and keeps the others).

Run::

    .venv/bin/python bench/bench_density.py --param-set thesis
    .venv/bin/python bench/bench_density.py --param-set adaptive --ks 1 3
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from calibration_free import match
from cvstereo.evaluation.metrics import evaluate, format_figure, to_json
from cvstereo.matchers.registry import METHODS, available_methods
from cvstereo.simulate import EDVS1_RIGHT, EDVS2_LEFT, ArmsScene, Rig, simulate

RESULTS = Path(__file__).resolve().parent / "results"

#: The thesis' five methods (they take a parameter set); the others are baselines.
THESIS_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector")
BASELINES = ("stereobm", "sgbm", "dv-semidense", "fused")
DEFAULT_KS = (0.5, 1.0, 2.0, 3.0)
SECONDS = 3.0
SEED = 7


def density_rig(k: float) -> Rig:
    """The thesis' rig with both sensors' ON and OFF thresholds multiplied by ``k``."""
    def scaled(sensor):
        return dataclasses.replace(sensor, on_threshold=sensor.on_threshold * k,
                                   off_threshold=sensor.off_threshold * k)

    return Rig(left=scaled(EDVS2_LEFT), right=scaled(EDVS1_RIGHT))


def run_sweep(ks, param_set: str, methods, *, log=print) -> dict:
    """Simulate each k, run every method, evaluate; a JSON-ready dict."""
    rows = {}
    for k in ks:
        start = time.perf_counter()
        rec = simulate(ArmsScene(arms=1, distance_m=1.0), rig=density_rig(k), seconds=SECONDS, seed=SEED)
        sim_s = time.perf_counter() - start
        row = {"events": {"left": int(rec.left.size), "right": int(rec.right.size)}, "simulate_s": round(sim_s, 2),
               "methods": {}}
        for method in methods:
            kwargs = {"param_set": param_set} if method in THESIS_METHODS else {}
            result = match(rec, method=method, **kwargs)
            fig = evaluate(rec, result)
            row["methods"][method] = {"variant": result.meta.get("variant"), "coverage": fig["coverage"],
                                      "bad2": fig["bad2"], "matches": fig["matches"],
                                      "false_rate": fig["false_rate"], "elapsed_s": round(result.meta["elapsed_s"], 2)}
            log(f"k={k:g} {method}/{result.meta.get('variant')}: "
                f"coverage {format_figure('coverage', fig['coverage'])}, bad2 {format_figure('bad2', fig['bad2'])}, "
                f"{fig['matches']} matches")
        rows[f"{k:g}"] = row
    return {"param_set": param_set, "rows": rows}


def _cell(name: str, value) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-" if name == "bad2" else "0.00"
    return f"{value:.2f}"


def section_markdown(run: dict, methods) -> str:
    """Two tables (coverage, bad2) for one parameter set: rows k, columns methods."""
    first = next(iter(run["rows"].values()))["methods"]
    labels = [f"{m}/{first[m]['variant']}" if m in first else m for m in methods]
    parts = [f"## param_set = {run['param_set']}\n"]
    for figure in ("coverage", "bad2"):
        lines = [f"| {figure} | " + " | ".join(labels) + " | events L / R |",
                 "|---|" + "---:|" * (len(labels) + 1)]
        for k, row in run["rows"].items():
            cells = [_cell(figure, row["methods"].get(m, {}).get(figure)) for m in methods]
            events = f"{row['events']['left']} / {row['events']['right']}"
            lines.append(f"| k = {k} | " + " | ".join(cells) + f" | {events} |")
        parts.append("\n".join(lines) + "\n")
    return "\n".join(parts)


def write_results(run: dict, methods, skipped, info: dict) -> tuple[Path, Path]:
    """Merge this run into density.json (replacing its parameter set's section) and rewrite density.md."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    json_path, md_path = RESULTS / "density.json", RESULTS / "density.md"
    data = json.loads(json_path.read_text()) if json_path.exists() else {"runs": {}}
    data["runs"][run["param_set"]] = {**run, "info": info, "methods": list(methods), "skipped": list(skipped)}
    json_path.write_text(to_json(data, indent=1) + "\n")
    head = ("# Density sweep\n\nGenerated by `bench/bench_density.py`: `ArmsScene(arms=1, distance_m=1.0)`, "
            f"{SECONDS:g} s, seed {SEED}, both sensors' ON and OFF thresholds x k (events per edge fall roughly "
            "as 1/k). Each method's default variant; coverage and bad2 (share of matches > 2 px off) from "
            "`cvstereo.evaluation.metrics` (\"-\": no match to score). Issue 12's target for `adaptive`: "
            "coverage at k = 0.5, 2, 3 at least half of k = 1, bad2 at most 0.05 above k = 1.\n")
    sections = []
    for name in ("thesis", "adaptive"):
        r = data["runs"].get(name)
        if r is None:
            continue
        i = r["info"]
        sections.append(section_markdown(r, r["methods"]) +
                        f"\n{i['cpus']} CPUs, 1-min load average {i['load_avg_1min_start']:.1f} at the start and "
                        f"{i['load_avg_1min_end']:.1f} at the end, {i['wall_s']:.0f} s in all, {i['date']}"
                        + (f"; skipped (extra not installed): {', '.join(r['skipped'])}" if r["skipped"] else "")
                        + ".\n")
    md_path.write_text(head + "\n" + "\n".join(sections))
    return json_path, md_path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--param-set", choices=("thesis", "adaptive"), default="adaptive",
                        help="parameter set of the thesis' methods (default adaptive; needs match(param_set=))")
    parser.add_argument("--ks", type=float, nargs="+", default=list(DEFAULT_KS), help="threshold factors")
    parser.add_argument("--methods", nargs="+", choices=list(METHODS), default=None,
                        help="methods to run (default: the thesis' five and the baselines)")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    wanted = args.methods or [*THESIS_METHODS, *BASELINES]
    installed = set(available_methods())
    methods = [m for m in wanted if m in installed]
    skipped = [m for m in wanted if m not in installed]
    if skipped:
        print(f"skipped (extra not installed): {', '.join(skipped)}")
    load_start = os.getloadavg()[0]
    start = time.perf_counter()
    run = run_sweep(args.ks, args.param_set, methods)
    info = {"machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "load_avg_1min_start": load_start, "load_avg_1min_end": os.getloadavg()[0],
            "wall_s": time.perf_counter() - start, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    print(section_markdown(run, methods))
    if not args.no_write:
        for path in write_results(run, methods, skipped, info):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
