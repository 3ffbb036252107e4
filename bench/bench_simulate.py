"""Benchmark the stereo event simulator on the thesis' six recordings.

For each preset (full 11 s unless ``--seconds`` says otherwise): wall-clock and CPU seconds to generate it,
events per sensor against the thesis' table 4.1 (left = eDVS2, right = eDVS1), ON/OFF ratio, right/left
ratio, share of noise events (NaN truth), and the mean true disparity of the signal events against the
disparity the thesis measured. Prints a table; writes ``bench/results/simulate.json`` and ``.md``.

Run::

    .venv/bin/python bench/bench_simulate.py                 # all six, 11 s each
    .venv/bin/python bench/bench_simulate.py --presets 1arm-50cm --seconds 2
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from cvstereo.simulate import PRESETS, simulate_preset

RESULTS = Path(__file__).resolve().parent / "results"

#: The issue's targets: events per sensor within this fraction of table 4.1, noise at most this share.
EVENT_TOLERANCE = 0.25
MAX_NOISE_SHARE = 0.25


def measure(name: str, seconds: float | None, seed: int) -> dict:
    """Generate one preset and gather its figures."""
    preset = PRESETS[name]
    wall, cpu = time.perf_counter(), time.process_time()
    rec = simulate_preset(name, seconds=seconds, seed=seed)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    length = preset.seconds if seconds is None else seconds
    row = {"preset": name, "seconds": length, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}
    for cam in ("left", "right"):
        ev, truth = rec.events(cam == "right"), rec.truth(cam == "right")
        on, off = int((ev["p"] == 1).sum()), int((ev["p"] == 0).sum())
        # The thesis' counts are for 11 s; scale them to the simulated length.
        t_on, t_off = (v * length / preset.seconds for v in preset.thesis_events[cam])
        row[cam] = {
            "on": on, "off": off, "events": on + off, "thesis_events": round(t_on + t_off),
            "vs_thesis": round((on + off) / (t_on + t_off) - 1, 3),
            "on_off_ratio": round(on / max(off, 1), 3), "thesis_on_off_ratio": round(t_on / t_off, 3),
            "noise_share": round(float(np.isnan(truth).mean()), 4),
            "mean_truth": round(float(np.nanmean(truth)), 2), "std_truth": round(float(np.nanstd(truth)), 2),
        }
    row["right_over_left"] = round(row["right"]["events"] / max(row["left"]["events"], 1), 3)
    row["thesis_right_over_left"] = round(sum(preset.thesis_events["right"]) / sum(preset.thesis_events["left"]), 3)
    row["thesis_disparity"] = list(preset.thesis_disparity)
    row["ok"] = bool(
        all(abs(row[c]["vs_thesis"]) <= EVENT_TOLERANCE and row[c]["noise_share"] <= MAX_NOISE_SHARE
            for c in ("left", "right"))
        and all(preset.thesis_disparity[0] - 0.5 <= row[c]["mean_truth"] <= preset.thesis_disparity[1] + 0.5
                for c in ("left", "right")))
    return row


def table(rows: list[dict]) -> str:
    """The rows as a Markdown table."""
    head = ("| preset | wall s | CPU s | left ev (thesis) | right ev (thesis) | R/L (thesis) | ON/OFF L, R (thesis) "
            "| noise L, R | mean truth L, R (thesis) | ok |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        le, ri = r["left"], r["right"]
        lines.append(
            f"| {r['preset']} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} "
            f"| {le['events']} ({le['thesis_events']}, {le['vs_thesis']:+.0%}) "
            f"| {ri['events']} ({ri['thesis_events']}, {ri['vs_thesis']:+.0%}) "
            f"| {r['right_over_left']:.2f} ({r['thesis_right_over_left']:.2f}) "
            f"| {le['on_off_ratio']:.2f}, {ri['on_off_ratio']:.2f} ({le['thesis_on_off_ratio']:.2f}, "
            f"{ri['thesis_on_off_ratio']:.2f}) "
            f"| {le['noise_share']:.1%}, {ri['noise_share']:.1%} "
            f"| {le['mean_truth']:.1f}, {ri['mean_truth']:.1f} "
            f"({r['thesis_disparity'][0]:g}-{r['thesis_disparity'][1]:g}) "
            f"| {'yes' if r['ok'] else 'NO'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="*", default=list(PRESETS), choices=list(PRESETS))
    parser.add_argument("--seconds", type=float, default=None, help="length (default: the preset's, 11 s)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    simulate_preset(args.presets[0], seconds=0.05)  # compile / load the numba kernels outside the timing
    rows = []
    for name in args.presets:
        rows.append(measure(name, args.seconds, args.seed))
        print(json.dumps(rows[-1]), flush=True)
    md = table(rows)
    print(md)
    if not args.no_write:
        RESULTS.mkdir(parents=True, exist_ok=True)
        info = {"machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
                "load_avg_1min_at_end": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}
        (RESULTS / "simulate.json").write_text(json.dumps({"info": info, "rows": rows}, indent=1) + "\n")
        (RESULTS / "simulate.md").write_text(
            "# Simulator benchmark\n\nGenerated by `bench/bench_simulate.py` "
            f"({info['cpus']} CPUs, 1-min load average at the end {info['load_avg_1min_at_end']:.1f}: other jobs "
            "share the machine, so wall seconds vary; CPU seconds count all threads of this process).\n"
            "Events: simulated (thesis table 4.1, difference); left = eDVS2, right = eDVS1. Noise: share of "
            "events with NaN truth. Mean truth: mean true disparity of the signal events (px).\n\n" + md + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
