"""The default rig check's row offset on suite v2 against the suite's true rows: the overlay alone, and with the
rows by matching where the overlay is unsure (issue 24 item 4).

For every recording of the chosen halves, the prefix check of :func:`cvstereo.match` runs as ``match()`` runs it
(:class:`cvstereo.rigcheck.prefix.PrefixRigCheck` on the stream's packets); the table gives the true row offset
(the suite's rig: ``-vertical_offset_px``), the overlay's estimate and confidence, the rows by matching where they
ran (offset, prominence, the span matched, their seconds), and what is applied now and what the overlay's gate
alone applied (its confident row, else none), with how far each leaves the truth. The prominence gate
(:data:`cvstereo.rigcheck.prefix.MATCHING_MIN_PROMINENCE`) was chosen on the tuning half; the evaluation half is
reported as it came.

Run: ``.venv/bin/python bench/bench_rig_rows.py [--halves tune,eval] [-o bench/results]``. Writes ``rig-rows.md``
and ``rig-rows.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from cvstereo.io import read_recording
from cvstereo.model.events import iter_stereo_packets
from cvstereo.rigcheck.prefix import PrefixRigCheck
from cvstereo.simulate import suite_recordings

ROOT = Path(__file__).resolve().parent.parent


def check_one(rec) -> dict:
    """The prefix check on ``rec``'s stream, and its rows beside the truth."""
    check = PrefixRigCheck(rec.resolution)
    start = time.perf_counter()
    next(check.stream(iter_stereo_packets(rec.left, rec.right)))  # the check runs before the first packet
    seconds = time.perf_counter() - start
    found = check.describe()
    if found["skipped"]:
        raise RuntimeError(f"the prefix check did not run: {found['skipped']}")
    # The suite's rig in the recording's order; the check's rows refer to the order used (after a swap).
    true = -float(rec.meta["rig"]["vertical_offset_px"]) * (-1 if found["applied"]["swap"] else 1)
    sign = -1 if found["applied"]["swap"] != found.get("swap", False) else 1
    overlay = sign * round(found["row_offset"]) if found["row_offset_confidence"] >= check.row_min_confidence else 0
    by_matching = found["rows_by_matching"]
    return {"true": round(true, 2), "overlay": round(found["row_offset"], 2),
            "overlay_confidence": round(found["row_offset_confidence"], 3),
            "swap": found["applied"]["swap"], "matching": by_matching,
            "applied": found["applied"]["row_offset"], "overlay_only": overlay,
            "error": round(abs(true - found["applied"]["row_offset"]), 2),
            "overlay_error": round(abs(true - overlay), 2),
            "seconds": round(seconds, 2)}


def summary(rows: list[dict]) -> str:
    e_new, e_old = (np.array([r[k] for r in rows]) for k in ("error", "overlay_error"))
    return (f"mean |error| {e_old.mean():.2f} -> {e_new.mean():.2f} rows; 1.5 rows or more off: "
            f"{int((e_old >= 1.5).sum())} -> {int((e_new >= 1.5).sum())} of {len(rows)}")


def markdown(results: dict) -> str:
    lines = ["# The default rig check's rows on suite v2: the overlay alone, and with the rows by matching", "",
             __doc__.split("\n\n")[1].replace("\n", " "), "",
             "Rows: to add to the right camera's y. `overlay only`: what the check applied before the rows by matching "
             "(the overlay's row where its confidence reaches 0.3, else none); `applied`: now. Errors against the "
             "truth in rows; the seconds are the whole prefix check's (the matching's share in its span column's run)."]
    for half, rows in results["halves"].items():
        lines += ["", f"## {half} half: {summary(list(rows.values()))}", "",
                  "| recording | true | overlay (confidence) | by matching: row, prominence, span ms | overlay only | "
                  "applied | error before -> after | check s |", "|---|---:|---|---|---:|---:|---|---:|"]
        for name, r in rows.items():
            m = r["matching"]
            by = "-" if m is None else f"{m['offset']:+d}, {m['prominence']:.3f}, {m['span_us'] / 1000:.0f}"
            lines.append(f"| {name} | {r['true']:+.2f} | {r['overlay']:+.2f} ({r['overlay_confidence']:.2f}) | {by} | "
                         f"{r['overlay_only']:+d} | {r['applied']:+d} | {r['overlay_error']:.2f} -> {r['error']:.2f} | "
                         f"{r['seconds']:.2f} |")
    lines += ["", results["machine"], ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--halves", default="tune,eval")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "bench" / "results")
    args = parser.parse_args()
    import os

    results = {"halves": {}}
    for half in args.halves.split(","):
        rows = results["halves"][half] = {}
        for name, path in suite_recordings("generalization", half=half, seconds=1.5, progress=True):
            rows[name] = check_one(read_recording(path))
            print(name, rows[name], flush=True)
    results["machine"] = (f"{os.cpu_count()} CPUs, 1-min load average {os.getloadavg()[0]:.1f} at the end, "
                          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.")
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "rig-rows.json").write_text(json.dumps(results, indent=1))
    (args.output / "rig-rows.md").write_text(markdown(results))
    print(markdown(results))


if __name__ == "__main__":
    main()
