"""``cvstereo evaluate RECORDING [RIGHT] MATCHES``: the figures of docs/evaluation.md for one matches file."""

from __future__ import annotations

import argparse
from pathlib import Path

from cvstereo.cli._common import (
    add_force_option,
    add_recording_arguments,
    load_matches_for,
    load_recording,
    naming,
    recording_plan,
)
from cvstereo.cli._text import printable

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = sub.add_parser(
        name,
        help="score a matches file against a recording's ground truth",
        description="Score a matches file (written by `cvstereo match`) against the recording it came from: "
        "mean and std of the disparities (the thesis' figures) and, where the recording has ground truth, "
        "error, bad-pixel rates, false-match rate and coverage (docs/evaluation.md).",
    )
    add_recording_arguments(p, matches="required")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    add_force_option(p, "score")
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.evaluation.metrics import FIGURES, evaluate, markdown_table, to_json
    from cvstereo.evaluation.thesis import thesis_disparity

    recording_plan(args).check()  # reads only: its inputs are regular files
    recording, result = load_matches_for(args, load_recording(args))
    with naming(args.matches):
        figures = evaluate(recording, result)
    meta = result.meta
    if args.json:
        print(to_json({"recording": str(args.recording), "matches_file": str(args.matches),
                       "method": meta.get("method"), "variant": meta.get("variant"), "figures": figures},
                      indent=2))
        return 0
    name = Path(args.recording).stem
    pub = thesis_disparity(str(meta.get("method")), str(meta.get("variant")), name)
    print(printable(f"method {meta.get('method')} ({meta.get('variant')}), anchor {meta.get('anchor')}, "
                    f"recording {args.recording}" + ("" if recording.has_truth else
                                                     " (no ground truth: mean/std only)")))
    print(markdown_table({name: figures}, columns=[f for f in FIGURES if f != "truth_mean"] if recording.has_truth
                         else ["matches", "mean", "std", "events_per_s", "realtime_x"],
                         thesis={name: pub} if pub else None))
    return 0
