"""``cvstereo video RECORDING [RIGHT] [MATCHES] -o OUT.mp4``: an MP4 of the events and, given matches, disparities.

One video frame per window (40 ms: real time at 25 fps): both cameras' events, ON blue and OFF orange, and the
colour-coded disparity at each anchor pixel, with the time since the recording's origin, median disparity and
distance written on top; H.264 (else VP9) that browsers play, at most 1280 px wide unless told otherwise.
"""

from __future__ import annotations

import argparse

from cvstereo.cli._common import (
    add_depth_options,
    add_force_option,
    add_recording_arguments,
    recording_plan,
    require_range,
)
from cvstereo.cli._rerun import add_rerun_option, rerun_target
from cvstereo.cli._subcommand import subcommand
from cvstereo.cli.plot import add_cmap_option, check_window_options, load_picture_inputs

__all__ = ["MAX_FPS", "MAX_SCALE", "MIN_WIDTH_PX", "add_parser", "run"]

#: Limits of the video options: a frame rate a player shows, and a frame size that fits in memory.
MAX_FPS, MAX_SCALE = 1000.0, 32
#: Smallest --max-width: room for the panels' labels.
MIN_WIDTH_PX = 160


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "write an MP4 of a recording with its disparities (extra: video)",
                   __doc__)
    add_recording_arguments(p, matches="optional")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mp4",
                   help="video file to write (.mp4, or a name without extension)")
    p.add_argument("--fps", type=float, default=25.0, help="frames per second (default: %(default)g)")
    p.add_argument("--scale", type=float, default=None,
                   help="video pixels per sensor pixel (default: the largest whole number up to 4 that keeps the "
                   "frame within --max-width, below 1 for wide sensors)")
    p.add_argument("--max-width", type=int, default=None, metavar="PX",
                   help="largest frame width where --scale is not given (default: 1280)")
    p.add_argument("--seconds", type=float, default=None,
                   help="only the first SECONDS of the recording (from its origin)")
    p.add_argument("--window-ms", type=float, default=40.0, metavar="MS",
                   help="time per video frame (default: %(default)g)")
    p.add_argument("--vmin", type=float, default=None, metavar="PX",
                   help="disparity at the low end of the colour scale (default: from the data)")
    p.add_argument("--vmax", type=float, default=None, metavar="PX",
                   help="disparity at the high end of the colour scale (default: from the data)")
    add_cmap_option(p)
    add_rerun_option(p)
    add_depth_options(p)
    add_force_option(p, "draw the matches")
    p.set_defaults(_parser=p)
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.viz.colormaps import check_cmap
    from cvstereo.viz.encode import CODEC_NAMES, require_av, video_codec
    from cvstereo.viz.video import MAX_WIDTH_PX, write_video

    require_av()  # before reading anything: a missing extra is said at once
    check_window_options(args)
    require_range(args.fps, "--fps", gt=0, le=MAX_FPS)
    require_range(args.scale, "--scale", gt=0, le=MAX_SCALE)
    require_range(args.seconds, "--seconds", gt=0)
    max_width = MAX_WIDTH_PX if args.max_width is None else args.max_width
    if args.max_width is not None and args.scale is not None:
        args._parser.error("--max-width applies where --scale is not given: give one of them")
    require_range(max_width, "--max-width", ge=MIN_WIDTH_PX)
    check_cmap(args.cmap)
    rerun = rerun_target(args)
    from cvstereo.io.output_plan import RERUN_FILE, VIDEO
    from cvstereo.viz.rerun_log import log_windows, rerun_stream

    plan = recording_plan(args)
    plan.write(args.output, VIDEO)
    if rerun.path is not None:
        plan.write(rerun.path, RERUN_FILE, option="--rerun")
    # Every file checked before the frames are drawn (and a viewer started); the outputs published once complete.
    with plan, rerun_stream(rerun) as stream:
        recording, result, depth = load_picture_inputs(args)
        n = write_video(recording, args.output, result, fps=args.fps, window_us=round(args.window_ms * 1000),
                        scale=args.scale, max_width=max_width, seconds=args.seconds, depth=depth, vmin=args.vmin,
                        vmax=args.vmax, cmap=args.cmap)
        if stream is not None:
            log_windows(stream, recording, result, window_us=round(args.window_ms * 1000), depth=depth,
                        cmap=args.cmap, vmin=args.vmin, vmax=args.vmax, seconds=args.seconds)
    print(f"{n} frames ({n / args.fps:.1f} s at {args.fps:g} fps, {CODEC_NAMES[video_codec()]}) -> {args.output}")
    return 0
