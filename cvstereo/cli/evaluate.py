"""``cvstereo evaluate RECORDING [RIGHT] MATCHES``: the figures of docs/evaluation.md for one matches file.

Score a matches file (written by `cvstereo match`) against the recording it came from: mean and std of the
disparities (the thesis' figures) and, where the recording has ground truth, error, bad-pixel rates, false-match
rate and coverage (docs/evaluation.md). A DSEC sequence folder or an MVSEC data file is scored against its
ground-truth disparity maps with DSEC's metrics: 1PE, 2PE, MAE, RMSE over the answered pixels, and the coverage.
"""

from __future__ import annotations

import argparse
import sys

from cvstereo.cli._common import (
    add_force_option,
    add_recording_arguments,
    load_matches_for,
    load_matches_streamed,
    load_recording,
    naming,
    recording_plan,
)
from cvstereo.cli._subcommand import subcommand
from cvstereo.cli._text import printable
from cvstereo.io.dsec_sequence import recording_name

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "score a matches file against a recording's ground truth", __doc__)
    add_recording_arguments(p, matches="required")
    g = p.add_argument_group("dense ground truth (a DSEC sequence folder, an MVSEC data file): DSEC's metrics")
    g.add_argument("--calibration", metavar="FILE", default=None,
                   help="the calibration that maps the matches onto the ground truth's rectified left frame "
                   "(default: a DSEC sequence's calibration/cam_to_cam.yaml; MVSEC: its Kalibr camchain file)")
    g.add_argument("--truth", metavar="GT.hdf5", default=None,
                   help="MVSEC's ground-truth depth file (default: NAME_gt.hdf5 beside NAME_data.hdf5)")
    p.add_argument("--json", action="store_true", help="print a JSON object instead of a table")
    add_force_option(p, "score")
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.evaluation.metrics import FIGURES, evaluate, markdown_table, to_json
    from cvstereo.evaluation.thesis import thesis_disparity
    from cvstereo.evaluation.truth_maps import truth_maps_for

    plan = recording_plan(args)
    with naming(args.recording):
        truth = truth_maps_for(args.recording, truth=args.truth, calibration=args.calibration)
    if truth is None and args.calibration is not None:
        raise ValueError(f"--calibration: {args.recording} has no ground-truth disparity maps to map the matches "
                         "onto (a DSEC sequence folder or an MVSEC data file has).")
    plan.read(*(truth.files if truth is not None else ()))
    plan.check()  # reads only: its inputs are regular files
    if truth is not None and truth.times == []:  # said before the events are read
        raise ValueError(f"{args.recording}: no ground-truth disparity maps (disparity/event/*.png with "
                         "disparity/timestamps.txt); DSEC's test sequences have none: write DSEC's submission "
                         "PNGs with `cvstereo export-dsec` instead.")
    if truth is not None:  # the events are not scored, only checked: streamed, never held
        return _dense(args, truth, load_matches_streamed(args))
    recording, result = load_matches_for(args, load_recording(args))
    with naming(args.matches):
        figures = evaluate(recording, result)
    meta = result.meta
    if args.json:
        print(to_json({"recording": str(args.recording), "matches_file": str(args.matches),
                       "method": meta.get("method"), "variant": meta.get("variant"), "figures": figures},
                      indent=2))
        return 0
    name = recording_name(args.recording)
    pub = thesis_disparity(str(meta.get("method")), str(meta.get("variant")), name)
    print(printable(f"method {meta.get('method')} ({meta.get('variant')}), anchor {meta.get('anchor')}, "
                    f"recording {args.recording}" + ("" if recording.has_truth else
                                                     " (no ground truth: mean/std only)")))
    print(markdown_table({name: figures}, columns=[f for f in FIGURES if f != "truth_mean"] if recording.has_truth
                         else ["matches", "mean", "std", "events_per_s", "realtime_x"],
                         thesis={name: pub} if pub else None))
    return 0


def _dense(args: argparse.Namespace, truth, result) -> int:
    """DSEC's metrics against the ground-truth maps (docs/evaluation.md, "Dense ground truth")."""
    from cvstereo.evaluation.dense_truth import score_maps
    from cvstereo.evaluation.metrics import markdown_table, to_json

    with naming(args.matches):
        figures = score_maps(result.matches, truth.read(), resolution=truth.resolution,
                             rectification=truth.rectification)
    if "rectification" not in result.meta:  # after the scoring: an error in the ground truth stays one line
        print(f"note: {args.matches} was matched without --calibration: its disparities are the raw pair's, not the "
              "rectified pair's the ground truth holds (match with --calibration to compare like with like).",
              file=sys.stderr)
    meta = result.meta
    if args.json:
        print(to_json({"recording": str(args.recording), "matches_file": str(args.matches),
                       "method": meta.get("method"), "variant": meta.get("variant"), "truth": truth.what,
                       "figures": figures}, indent=2))
        return 0
    name = recording_name(args.recording)
    print(printable(f"method {meta.get('method')} ({meta.get('variant')}), recording {args.recording}, "
                    f"{truth.what}"))
    print(markdown_table({name: figures}, columns=list(figures)))
    return 0
