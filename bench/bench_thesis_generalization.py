"""The thesis' five matchers under ``adaptive`` on suite v2, per family and half, beside the baseline (issue 24 item 3).

Run: ``python bench/bench_thesis_generalization.py [--halves tune,eval] [--only NAME,...] [-o bench/results]``.
Every cell is one ``match(recording, method=m)`` (the method's default variant under the default set, as a user
runs it) and :func:`cvstereo.evaluation.metrics.evaluate` in this process, one after another (the machine is shared);
``--save-rows FILE`` keeps each cell as a JSON line as it is done, ``--rows FILE`` writes the tables from such a
file without matching. Writes ``thesis-generalization.md`` and ``.json``: per family and half the median bad2
(a recording without matches counts as bad2 = 1, as in ``bench_generalization.py``) and median coverage, before
(``generalization.json``: the suite v2 baseline) and after, and issue 24's goal per cell (median bad2 <= 0.15 and
coverage > 0.05).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

THESIS_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector")
FAMILIES = ("objects", "translate", "turn", "ground", "repetitive", "thin")
HALVES = ("tune", "eval")
#: Issue 24's goal for every thesis method's default under adaptive, per family.
GOAL_BAD2, GOAL_COVERAGE = 0.15, 0.05


def cell(path, name: str, method: str, **params) -> dict:
    """One recording x method: coverage and bad2 of the default under the default set (silence: bad2 = 1);
    ``params`` on top, as ``match()`` takes them."""
    from cvstereo.evaluation.metrics import evaluate
    from cvstereo.io.npz import read_recording_npz
    from cvstereo.run import match

    rec = read_recording_npz(path)
    result = match(rec, method=method, **params)
    figures = evaluate(rec, result)
    coverage, bad2 = figures["coverage"], figures["bad2"]
    silent = not coverage or bad2 is None or bad2 != bad2
    return {"recording": name, "method": method, "coverage": float(coverage or 0.0),
            "bad2": 1.0 if silent else float(bad2), "matches": int(result.matches.size)}


def medians(rows: list[dict]) -> dict:
    """(family, half, method) -> (median bad2, median coverage, recordings)."""
    out = {}
    for fam in FAMILIES:
        for half in HALVES:
            for m in THESIS_METHODS:
                sel = [r for r in rows if r["method"] == m and r["recording"].startswith(f"{fam}-{half}-")]
                if sel:
                    out[(fam, half, m)] = (statistics.median(r["bad2"] for r in sel),
                                           statistics.median(r["coverage"] for r in sel), len(sel))
    return out


def report(rows: list[dict], baseline: dict, note: str) -> str:
    after = medians(rows)
    lines = ["# Thesis matchers under `adaptive` on suite v2: per family and half, before and after", "", note, "",
             "Each cell: median bad2 (median coverage) over the family's recordings of that half, before (the suite v2 "
             "baseline, generalization.md) -> after; **met** where bad2 <= 0.15 and coverage > 0.05 (issue 24).", "",
             "| family | half | " + " | ".join(THESIS_METHODS) + " |", "|---|---|" + "---|" * len(THESIS_METHODS)]
    for fam in FAMILIES:
        for half in HALVES:
            cells = []
            for m in THESIS_METHODS:
                b = baseline.get(f"{fam}/{half}/{m}/adaptive")
                a = after.get((fam, half, m))
                before = f"{b['median_bad2']:.3f} ({b['median_coverage']:.2f})" if b else "-"
                now = f"{a[0]:.3f} ({a[1]:.2f})" if a else "not run"
                met = " **met**" if a and a[0] <= GOAL_BAD2 and a[1] > GOAL_COVERAGE else ""
                cells.append(f"{before} -> {now}{met}")
            lines.append(f"| {fam} | {half} | " + " | ".join(cells) + " |")
    lines += ["", "## Per recording (after)", "", "| recording | " + " | ".join(THESIS_METHODS) + " |",
              "|---|" + "---|" * len(THESIS_METHODS)]
    by = {(r["recording"], r["method"]): r for r in rows}
    for name in sorted({r["recording"] for r in rows}):
        lines.append(f"| {name} | " + " | ".join(
            f"{by[(name, m)]['coverage']:.2f} / {by[(name, m)]['bad2']:.2f}" if (name, m) in by else "-"
            for m in THESIS_METHODS) + " |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--halves", default=",".join(HALVES))
    parser.add_argument("--methods", default=",".join(THESIS_METHODS))
    parser.add_argument("--only", default=None, metavar="NAME,...", help="only these suite recordings")
    parser.add_argument("--rows", default=None, help="write the tables from these JSON lines, match nothing")
    parser.add_argument("--save-rows", default=None, help="append each cell as a JSON line here as it is done")
    args = parser.parse_args()
    out = Path(args.output)
    load = os.getloadavg()[0]
    if args.rows:
        rows = [json.loads(line) for line in Path(args.rows).read_text().splitlines() if line.strip()]
        note = f"Figures from the saved cells {Path(args.rows).name}."
    else:
        from cvstereo.simulate import suite_recordings

        halves = args.halves.split(",")
        only = args.only.split(",") if args.only else None
        paths = {n: p for n, p in suite_recordings("generalization", only=only) if n.split("-")[1] in halves}
        rows, start = [], time.perf_counter()
        for m in args.methods.split(","):
            for name, path in paths.items():
                rows.append(cell(path, name, m))
                if args.save_rows:
                    with open(args.save_rows, "a") as fh:
                        fh.write(json.dumps(rows[-1]) + "\n")
        note = (f"{len(rows)} cells in {time.perf_counter() - start:.0f} s, one process (load {load:.1f} before).")
    note += (f" Date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, 1-min load {os.getloadavg()[0]:.1f} "
             "when written.")
    baseline = json.loads((out / "generalization.json").read_text())["summary"]
    (out / "thesis-generalization.md").write_text(report(rows, baseline, note))
    (out / "thesis-generalization.json").write_text(json.dumps({"rows": rows}, indent=1))
    print(report(rows, baseline, note))


if __name__ == "__main__":
    main()
