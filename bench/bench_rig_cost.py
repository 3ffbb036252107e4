"""The light rig check's report and seconds on suite v2's prefixes and the real TUM files, to compare two trees.

Run once per tree (``PYTHONPATH=WORKTREE`` for an older one), then compare::

    .venv/bin/python bench/bench_rig_cost.py --save old.json      # in the old tree's worktree
    .venv/bin/python bench/bench_rig_cost.py --save new.json
    .venv/bin/python bench/bench_rig_cost.py --compare old.json new.json

Each input: ``check_rig(prefix, LIGHT_PARAMS)`` (the default prefix check's options) on the first 0.5 s of every
recording of suite v2 (both halves; the check's figures are not tuned here) and on each real file whole, the
transforms on ``--threads`` threads. ``--compare`` says whether the reports agree (time offset to 0.1 us, its
confidence and the row offset to 3 decimals, whether the time offset applies) and prints the seconds by sensor size.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import scipy.fft

from cvstereo.io import read_recording
from cvstereo.rigcheck.check import check_rig
from cvstereo.rigcheck.prefix import LIGHT_PARAMS, PREFIX_MIN_US
from cvstereo.simulate import suite_recordings

ROOT = Path(__file__).resolve().parent.parent
SIZES = ("128x128", "240x180", "346x260", "640x480")


def measure(threads: int) -> dict:
    """name -> (time offset, its confidence, applicable, row offset, seconds)."""
    inputs = [(name, path, True) for name, path in suite_recordings("generalization", seconds=1.5)]
    inputs += [(p.name, p, False) for p in sorted((ROOT.parent / "shared" / "data" / "tum-stereo").glob("*.dat"))]
    out = {}
    for name, path, prefix in inputs:
        rec = read_recording(path)
        t0 = min(int(rec.left["t"][0]), int(rec.right["t"][0]))
        checked = rec.slice_time(t0, t0 + PREFIX_MIN_US + 1) if prefix else rec
        with scipy.fft.set_workers(threads):
            start = time.perf_counter()
            r = check_rig(checked, LIGHT_PARAMS)
            seconds = time.perf_counter() - start
        out[name] = (round(r.time_offset_us, 1), round(r.time_offset_confidence, 3), bool(r.time_offset_applicable()),
                     round(r.row_offset, 3), round(seconds, 2))
        print(name, out[name], flush=True)
    return out


def _span(figures: dict, names: list[str]) -> str:
    seconds = [figures[k][-1] for k in names]
    return f"{min(seconds):.2f}-{max(seconds):.2f}"


def compare(old: dict, new: dict) -> str:
    differ = [k for k in old if old[k][:4] != new[k][:4]]
    lines = [f"reports differing: {len(differ)} of {len(old)} {differ}", "",
             "| inputs | old s (range) | new s (range) | old total | new total |", "|---|---:|---:|---:|---:|"]
    for size in (*SIZES, "real files"):
        ks = [k for k in old if size in k] if size in SIZES else [k for k in old if not any(s in k for s in SIZES)]
        totals = (sum(old[k][-1] for k in ks), sum(new[k][-1] for k in ks))
        lines.append(f"| {size} ({len(ks)}) | {_span(old, ks)} | {_span(new, ks)} | {totals[0]:.1f} | "
                     f"{totals[1]:.1f} |")
    lines.append(f"| all ({len(old)}) | | | {sum(v[-1] for v in old.values()):.1f} | "
                 f"{sum(v[-1] for v in new.values()):.1f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", type=Path, help="measure this tree and write the JSON here")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("OLD", "NEW"))
    args = parser.parse_args()
    if args.save:
        load = os.getloadavg()[0]
        args.save.write_text(json.dumps({"load": load, "threads": args.threads, "inputs": measure(args.threads)},
                                        indent=0))
    if args.compare:
        old, new = (json.loads(p.read_text())["inputs"] for p in args.compare)
        print(compare(old, new))


if __name__ == "__main__":
    main()
