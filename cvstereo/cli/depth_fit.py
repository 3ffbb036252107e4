"""``cvstereo depth-fit FILE:DISTANCE ...``: fit d = a/Z - c from recordings at measured distances.

Fit the disparity-to-distance model d = a/Z - c (a = focal length x baseline, c from axes that are not exactly
parallel) by least squares, from two or more recordings (or matches files) made at distances you measured (the
thesis used a cord). Each file's median disparity is one point. Prints a and c and the option `--depth A C` that
`match`, `plot` and `video` take; -o writes the model file that `--depth DEPTH.json` reads.
"""

from __future__ import annotations

import argparse
import math

from cvstereo.cli._common import add_matcher_options, matcher_overrides, matcher_threads, naming
from cvstereo.cli._subcommand import subcommand
from cvstereo.cli._text import number

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "fit d = a/Z - c (disparity to metres) from recordings at measured distances", __doc__)
    p.add_argument("points", nargs="+", metavar="FILE:DISTANCE",
                   help="a recording or a matches .npz, and its distance in metres, e.g. arm50.npz:0.5 (a pair of "
                   "one-file-per-camera files: match them first, `cvstereo match LEFT RIGHT -o m.npz`, and give "
                   "m.npz:DISTANCE)")
    add_matcher_options(p, what="matcher for the recordings (matches files are used as they are)")
    p.add_argument("-o", "--output", default=None, metavar="DEPTH.json",
                   help="write the model as JSON (.json, or a name without extension)")
    return p


def _point(text: str) -> tuple[str, float]:
    path, sep, dist = text.rpartition(":")
    try:
        z = float(dist)
    except ValueError:
        z = float("nan")
    if not sep or not path or not (z > 0 and math.isfinite(z)):
        raise ValueError(f"'{text}' is not FILE:DISTANCE with a finite distance in metres > 0, e.g. arm50.npz:0.5.")
    return path, z


def run(args: argparse.Namespace) -> int:
    from cvstereo.geometry.depth import fit_depth_model
    from cvstereo.io.output_plan import DEPTH_MODEL_FILE, OutputPlan

    points = [_point(p) for p in args.points]
    overrides = matcher_overrides(args)  # before any file is read or matched
    args.threads = matcher_threads(args)
    if len({z for _, z in points}) < 2:
        raise ValueError("give files at two or more different distances (d = a/Z - c has two unknowns).")
    plan = OutputPlan()
    plan.read(*(p for p, _ in points))
    plan.write(args.output, DEPTH_MODEL_FILE)
    with plan:  # the files checked before any matching; the model published once fitted
        rows = [_median_disparity(path, z, args, overrides) for path, z in points]
        try:
            model = fit_depth_model([r[1] for r in rows], [r[2] for r in rows])
        except ValueError as exc:
            medians = ", ".join(f"{p}: {d:.2f} px at {z:g} m" for p, z, d, _ in rows)
            raise ValueError(f"no depth model fits the files' median disparities ({medians}): {exc}") from None
        if args.output:
            from cvstereo.geometry.depth_file import save_depth_model

            save_depth_model(args.output, model, points=[{"file": p, "distance_m": z, "median_disparity_px": d,
                                                          "matches": n} for p, z, d, n in rows])
    print(f"{'file':40s} {'distance m':>10s} {'median d px':>11s} {'matches':>8s} {'fitted m':>9s}")
    for path, z, d, n in rows:
        print(f"{path:40s} {z:10.3f} {d:11.2f} {n:8d} {number(model.distance(d), '.3f'):>9s}")
    print(f"a = {model.a:.4f} px m, c = {model.c:.4f} px   (use: --depth {model.a:.4f} {model.c:.4f})")
    if args.output:
        print(f"model: {args.output} (use: --depth {args.output})")
    return 0


def _median_disparity(path: str, z: float, args: argparse.Namespace, overrides: dict) -> tuple[str, float, float, int]:
    """(file, distance, median disparity, matches) of one FILE:DISTANCE: a matches file as it is, a recording
    matched with the command's matcher."""
    import numpy as np

    from cvstereo.io import read_matches, read_recording
    from cvstereo.io.npz import npz_keys

    with naming(path):
        if path.endswith(".npz") and "matches" in npz_keys(path):
            disparity = read_matches(path).disparity
        else:
            from cvstereo.run import match

            disparity = match(read_recording(path), method=args.method, variant=args.variant,
                              param_set=args.param_set, threads=args.threads, **overrides).disparity
    if disparity.size == 0:
        raise ValueError(f"{path}: no matches, so no disparity to fit; try another --method.")
    return path, z, float(np.median(disparity)), int(disparity.size)
