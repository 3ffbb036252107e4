"""``cvstereo convert RECORDING [RIGHT] -o OUT [OUT_RIGHT]``: rewrite a recording in another format (atomically).

Read a recording in any supported format and write it in another. The output format comes from --to or the output
name: .npz, .aedat, a text name (.txt/.dat) for a merged five-column file, or two text names (left, right) for one
file per camera. Outputs appear only once complete. Ground truth is kept by .npz only.
"""

from __future__ import annotations

import argparse
import sys

from cvstereo.cli._common import add_recording_arguments, format_options, naming, recording_plan
from cvstereo.cli._subcommand import subcommand

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    from cvstereo.io import FORMATS

    p = subcommand(sub, name, "convert a recording between formats (npz, eDVS text, merged text, AEDAT 2.0)", __doc__)
    add_recording_arguments(p)
    p.add_argument("-o", "--output", metavar="OUT", nargs="+", required=True,
                   help="output file, or the left and right output files for --to edvs-text")
    p.add_argument("--to", choices=FORMATS, default=None, help="output format (default: from the output name)")
    p.add_argument("--out-left-retina", type=int, choices=(0, 1), default=0,
                   help="merged text output: the retina id written for the left camera (default 0)")
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.io import open_recording, output_format, write_recording
    from cvstereo.io.output_plan import ANY_FILE
    from cvstereo.model.recording import Recording

    if len(args.output) > 2:
        return _usage("give at most two outputs (left, right)")
    if args.to is not None and (args.to == "edvs-text") != (len(args.output) == 2):
        return _usage("--to edvs-text writes two files: give -o LEFT RIGHT (and only then two outputs)")
    right_out = args.output[1] if len(args.output) == 2 else None
    # Everything about the outputs is checked before a possibly long read: format, names, inputs.
    to = output_format(args.output[0], format=args.to, right=right_out)  # the names fit the format (its table)
    plan = recording_plan(args)
    for path in args.output:
        plan.write(path, ANY_FILE)
    with plan:  # the files checked before reading; both cameras' files published together
        with naming(args.recording, args.right):
            stream = open_recording(args.recording, args.right, **format_options(args))
            rec = stream.read()
        # The reader's decisions (left retina, one-based, ...) stay in meta, marked as the source's.
        meta = {**rec.meta, "converted_from": {"format": stream.format, "files": list(stream.files)}}
        rec = Recording(rec.left, rec.right, rec.left_disparity, rec.right_disparity, rec.resolution, meta)
        write_recording(args.output[0], rec, format=to, right=right_out, left_retina=args.out_left_retina)
    print(f"wrote {' and '.join(args.output)}: {rec.left.size:,} left and {rec.right.size:,} right events"
          + (" (ground truth dropped: only .npz keeps it)" if rec.has_truth and to != "npz" else ""))
    return 0


def _usage(message: str) -> int:
    # Wrong argument counts are usage errors (exit 2, like argparse's), not bad input (exit 1).
    print(f"cvstereo convert: error: {message}", file=sys.stderr)
    return 2
