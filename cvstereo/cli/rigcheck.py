"""``cvstereo rigcheck RECORDING [RIGHT] [--json]``: what a calibration would have told, from the events.

Estimate from the events alone which camera is left, the vertical (row) offset between the sensors, the time offset
between the streams, the disparity range present, the ON/OFF and event-rate imbalance and the noise rate, each with
a confidence in [0, 1]. `cvstereo match --auto` applies the findings (a time offset only when confident and not
ambiguous: on a periodic scene such as a fan the coincidences peak once per blade period).

The figures and confidences are :func:`cvstereo.rigcheck.check_rig`'s, with whether the time offset is
ambiguous; a figure that cannot be estimated reads ``n/a`` (``null`` in ``--json``).
"""

from __future__ import annotations

import argparse
import json

from cvstereo.cli._common import (
    add_progress_option,
    add_recording_arguments,
    load_recording,
    naming,
    progress_wanted,
    recording_plan,
)
from cvstereo.cli._subcommand import subcommand

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "estimate the rig (left/right, row and time offset, disparity range, imbalance, noise) "
                   "from a recording", __doc__)
    add_recording_arguments(p)
    p.add_argument("--max-disparity", type=int, default=64, metavar="PX", help="largest disparity searched")
    p.add_argument("--max-row-offset", type=int, default=8, metavar="ROWS", help="largest row offset searched")
    p.add_argument("--max-time-offset-ms", type=float, default=20.0, metavar="MS",
                   help="largest time offset searched")
    p.add_argument("--json", action="store_true", help="print the report as a JSON object")
    add_progress_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.rigcheck import RigCheckParams

    params = RigCheckParams(max_disparity=args.max_disparity, max_row_offset=args.max_row_offset,
                            max_time_offset_us=round(args.max_time_offset_ms * 1000))
    recording_plan(args).check()  # reads only: its inputs are regular files
    recording = load_recording(args)
    with naming(args.recording, args.right):
        report = _check(args, recording, params)
    if args.json:
        # to_dict gives null for a figure that could not be estimated: strict JSON, never a bare NaN.
        print(json.dumps(report.to_dict(), indent=2, allow_nan=False))
    else:
        print(report.summary())
    return 0


def _check(args: argparse.Namespace, recording, params):
    """The rig check, with a progress bar of its stages where wanted."""
    from cvstereo.rigcheck import check_rig

    if progress_wanted(args):
        from tqdm.auto import tqdm

        from cvstereo.rigcheck.check import STAGES

        # One step per stage; the two repeats are counted as done when check_rig skips them.
        with tqdm(total=len(STAGES), unit="stage", desc="rigcheck", leave=False) as bar:
            def stage(name: str) -> None:
                bar.update(STAGES.index(name) - bar.n)
                bar.set_postfix_str(name)

            report = check_rig(recording, params, progress=stage)
            bar.update(len(STAGES) - bar.n)
        return report
    return check_rig(recording, params)
