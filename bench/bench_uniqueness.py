"""A block matcher's uniqueness ratio, chosen on tuning recordings: per family, median bad2 and coverage per value.

For each recording of suite v2's tuning half and the extra tuning draws of ``bench_row_field.py`` (every one passed
through ``require_tuning``), ``match(recording, method=M, uniqueness=u)`` as a user runs it (the default set, the
default rig check) for every value u, scored against the recording's truth. The table gives per family the median
bad2 and coverage of each value, and how many families meet issue 24's goal (median bad2 <= 0.15, coverage > 0.05);
the value is chosen from it, and the evaluation half is then scored once with ``bench_thesis_generalization.py``.

Run: ``.venv/bin/python bench/bench_uniqueness.py [--method frame-area] [--values 0,0.1,0.2,0.3] [--workers 2]
[-o bench/results]``. Writes ``uniqueness-<method>.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_row_field import extra_tuning_recordings
from bench_thesis_generalization import FAMILIES, GOAL_BAD2, GOAL_COVERAGE, cell

from cvstereo.simulate import require_tuning, suite_recordings


def one(args: tuple) -> dict:
    """One recording x value (a worker process: one thread, as bench cells run)."""
    name, path, method, value = args
    require_tuning(path)
    row = cell(path, name, method, uniqueness=value, threads=1)
    return {**row, "uniqueness": value}


def family_of(name: str) -> str:
    return name.split("-")[0]


def table(rows: list[dict], values: list[float], method: str, note: str) -> str:
    lines = [f"# {method}: the uniqueness ratio on tuning recordings", "", note, "",
             "Each cell: median bad2 (median coverage) over the family's tuning recordings (suite v2's tuning half and "
             "the extra tuning draws); **met** where bad2 <= 0.15 and coverage > 0.05 (issue 24's goal, which the "
             "evaluation half is held to).", "",
             "| family | recordings | " + " | ".join(f"uniqueness {v:g}" for v in values) + " |",
             "|---|---:|" + "---|" * len(values)]
    met = dict.fromkeys(values, 0)
    overall = {}
    for fam in FAMILIES:
        cells = []
        n = 0
        for v in values:
            sel = [r for r in rows if r["uniqueness"] == v and family_of(r["recording"]) == fam]
            n = len(sel)
            bad2 = statistics.median(r["bad2"] for r in sel)
            cov = statistics.median(r["coverage"] for r in sel)
            ok = bad2 <= GOAL_BAD2 and cov > GOAL_COVERAGE
            met[v] += ok
            cells.append(f"{bad2:.3f} ({cov:.2f}){' **met**' if ok else ''}")
        lines.append(f"| {fam} | {n} | " + " | ".join(cells) + " |")
    for v in values:
        sel = [r for r in rows if r["uniqueness"] == v]
        overall[v] = (statistics.median(r["bad2"] for r in sel), statistics.median(r["coverage"] for r in sel))
    lines.append("| all | {} | ".format(len([r for r in rows if r["uniqueness"] == values[0]]))
                 + " | ".join(f"{overall[v][0]:.3f} ({overall[v][1]:.2f})" for v in values) + " |")
    lines.append("| families met | | " + " | ".join(str(met[v]) for v in values) + " |")
    kept = [kept_answers(rows, values[0], v) for v in values]
    lines.append(f"| right / wrong answers kept (vs {values[0]:g}) | | "
                 + " | ".join(f"{r:.2f} / {w:.2f}" for r, w in kept) + " |")
    lines += ["", "Answers kept: per recording the matches with truth within 2 px (right) and further (wrong) at each "
              "value over those at the first, the median over recordings."]
    return "\n".join(lines) + "\n"


def kept_answers(rows: list[dict], base: float, value: float) -> tuple[float, float]:
    """Median over recordings of the right and the wrong answers at ``value`` over those at ``base``."""
    by = {(r["recording"], r["uniqueness"]): r for r in rows}
    right, wrong = [], []
    for name in sorted({r["recording"] for r in rows}):
        a, b = by[(name, base)], by[(name, value)]
        if a["matches"] * (1 - a["bad2"]) > 0:
            right.append(b["matches"] * (1 - b["bad2"]) / (a["matches"] * (1 - a["bad2"])))
        if a["matches"] * a["bad2"] > 0:
            wrong.append(b["matches"] * b["bad2"] / (a["matches"] * a["bad2"]))
    return statistics.median(right), statistics.median(wrong)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--method", default="frame-area")
    parser.add_argument("--values", default="0,0.1,0.2,0.3")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    values = [float(v) for v in args.values.split(",")]
    recordings = [*suite_recordings("generalization", half="tune"), *extra_tuning_recordings()]
    jobs = [(name, str(path), args.method, v) for name, path in recordings for v in values]
    load, start = os.getloadavg()[0], time.perf_counter()
    rows = []
    with ProcessPoolExecutor(args.workers) as pool:
        for row in pool.map(one, jobs):
            rows.append(row)
            print(f"{row['recording']:28s} u={row['uniqueness']:<4g} bad2 {row['bad2']:.3f} coverage "
                  f"{row['coverage']:.3f}", flush=True)
    note = (f"Generated by `bench/bench_uniqueness.py --method {args.method}` on "
            f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: {len(rows)} cells in "
            f"{time.perf_counter() - start:.0f} s on {args.workers} processes (1-min load {load:.1f} before, "
            f"{os.getloadavg()[0]:.1f} after; accuracy only, no timing).")
    write(rows, values, args.method, note, Path(args.output))


def write(rows: list[dict], values: list[float], method: str, note: str, out: Path) -> None:
    """The table and the cells, to ``uniqueness-<method>.md`` and ``.json``."""
    text = table(rows, values, method, note)
    (out / f"uniqueness-{method}.md").write_text(text)
    (out / f"uniqueness-{method}.json").write_text(json.dumps({"values": values, "note": note, "rows": rows},
                                                               indent=1))
    print(text)


if __name__ == "__main__":
    main()
