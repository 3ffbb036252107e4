"""``cvstereo export-dsec SEQUENCE MATCHES -o DIR``: a matches file as DSEC's disparity submission (16-bit PNGs).

Write the disparity maps of a matches file (computed on a DSEC sequence folder, with --calibration for DSEC's
rectification) in DSEC's submission format: DIR/SEQUENCE_NAME/NNNNNN.png, one 16-bit PNG of round(disparity x 256)
per requested time, in the rectified left event camera's frame, 0 where no match answered; a map at time ts holds
the matches of (ts - 50 ms, ts] (docs/evaluation.md). The times are DSEC's test timestamps file (--timestamps,
'timestamp_us, file_index'), or by default the sequence's own ground-truth times and names.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from cvstereo.cli._common import (
    add_force_option,
    check_files,
    load_matches_streamed,
    naming,
    recording_plan,
)
from cvstereo.cli._subcommand import subcommand
from cvstereo.io.output_plan import OutputKind

__all__ = ["DISPARITY_PNG", "add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "write a matches file as DSEC's disparity submission: 16-bit PNGs of disparity x 256",
                   __doc__)
    p.add_argument("recording", metavar="SEQUENCE", help="the DSEC sequence folder the matches were computed on")
    p.add_argument("matches", metavar="MATCHES", help="matches .npz written by `cvstereo match`")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="the submission folder: the PNGs go into DIR/SEQUENCE_NAME/ (created)")
    p.add_argument("--timestamps", metavar="CSV", default=None,
                   help="DSEC's test timestamps of this sequence (timestamp_us, file_index; default: the times of "
                   "the sequence's disparity/timestamps.txt)")
    p.add_argument("--calibration", metavar="FILE", default=None,
                   help="DSEC cam_to_cam.yaml (default: the sequence's calibration/cam_to_cam.yaml)")
    add_force_option(p, "export")
    p.set_defaults(right=None, format=None)
    return p


#: What export-dsec writes.
DISPARITY_PNG = OutputKind("a 16-bit disparity PNG", (".png",))


def run(args: argparse.Namespace) -> int:
    from cvstereo.evaluation.dense_truth import predicted_maps
    from cvstereo.evaluation.truth_maps import truth_maps_for
    from cvstereo.io.dsec_sequence import (
        MAX_PNG_DISPARITY,
        find_dsec_sequence,
        is_dsec_sequence,
        read_timestamps,
        write_disparity_png,
    )

    if not is_dsec_sequence(args.recording):
        raise ValueError(f"{args.recording}: not a DSEC sequence folder (events/left/events.h5, "
                         "events/right/events.h5); export-dsec writes DSEC's format for DSEC's sequences.")
    plan = recording_plan(args)
    with naming(args.recording):
        seq = find_dsec_sequence(args.recording)
        truth = truth_maps_for(args.recording, calibration=args.calibration)
    plan.read(args.timestamps, *truth.files)
    if args.timestamps is not None:
        check_files([args.timestamps])  # a regular file before it is read
        with naming(args.timestamps):
            times, index = read_timestamps(args.timestamps)
        if index is None:
            raise ValueError(f"--timestamps {args.timestamps}: one column; DSEC's test timestamps have two "
                             "(timestamp_us, file_index), which name the PNGs.")
        names = [f"{i:06d}.png" for i in index.tolist()]
        times = times.tolist()
    elif truth.times:
        times, names = truth.times, truth.names
    else:
        raise ValueError(f"{args.recording}: no ground-truth times to export at (a test sequence); give DSEC's "
                         "test timestamps of this sequence: --timestamps CSV.")
    paths = plan.write_folder(args.output, [f"{seq.name}/{n}" for n in names], DISPARITY_PNG)
    with plan:
        result = load_matches_streamed(args)
        maps = predicted_maps(result.matches, times, resolution=truth.resolution,
                              rectification=truth.rectification)
        beyond = 0
        for path, (_, image) in zip(paths, maps, strict=True):
            # The format holds up to MAX_PNG_DISPARITY: a larger answer is left out (said below), not wrapped.
            over = image > MAX_PNG_DISPARITY
            beyond += int(over.sum())
            image[over] = np.nan
            write_disparity_png(path, image)
    if beyond:
        print(f"warning: {beyond} pixel answers above {MAX_PNG_DISPARITY:g} px (the most DSEC's 16-bit PNGs hold) "
              "were written as 0, no answer.", file=sys.stderr)
    print(f"{len(paths)} disparity maps -> {Path(args.output) / seq.name}")
    return 0
