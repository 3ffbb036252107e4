"""``cvstereo video RECORDING [RIGHT] [MATCHES] -o OUT.mp4``: an MP4 of the events and, given matches, disparities.

One video frame per window (40 ms: real time at 25 fps): both cameras' events, ON blue and OFF orange, and the
colour-coded disparity at each anchor pixel, with time, median disparity and distance written on top.
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
from cvstereo.cli.plot import check_window_options, load_picture_inputs

__all__ = ["MAX_FPS", "MAX_SCALE", "add_parser", "run"]

#: Limits of the video options: a frame rate a player shows, and a frame size that fits in memory.
MAX_FPS, MAX_SCALE = 1000.0, 32


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = sub.add_parser(name, help="write an MP4 of a recording with its disparities",
                       description=__doc__.split("\n\n")[1])
    add_recording_arguments(p, matches="optional")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mp4",
                   help="video file to write (.mp4, or a name without extension)")
    p.add_argument("--fps", type=float, default=25.0, help="frames per second (default: %(default)g)")
    p.add_argument("--scale", type=int, default=4, help="video pixels per sensor pixel (default: %(default)d)")
    p.add_argument("--seconds", type=float, default=None, help="only the first SECONDS of the recording")
    p.add_argument("--window-ms", type=float, default=40.0, metavar="MS",
                   help="time per video frame (default: %(default)g)")
    p.add_argument("--vmin", type=float, default=None, metavar="PX",
                   help="disparity at the low end of the colour scale (default: from the data)")
    p.add_argument("--vmax", type=float, default=None, metavar="PX",
                   help="disparity at the high end of the colour scale (default: from the data)")
    add_depth_options(p)
    add_force_option(p, "draw the matches")
    p.set_defaults(_parser=p)
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.viz import write_video
    from cvstereo.viz.video import CODEC_NAMES, video_codec

    check_window_options(args)
    require_range(args.fps, "--fps", gt=0, le=MAX_FPS)
    if not 1 <= args.scale <= MAX_SCALE:
        raise ValueError(f"--scale must be between 1 and {MAX_SCALE} video pixels per sensor pixel, got {args.scale}.")
    require_range(args.seconds, "--seconds", gt=0)
    from cvstereo.io.output_plan import VIDEO

    plan = recording_plan(args)
    plan.write(args.output, VIDEO)
    with plan:  # every file checked before the frames are drawn; the video published once complete
        recording, result, depth = load_picture_inputs(args)
        n = write_video(recording, args.output, result, fps=args.fps, window_us=round(args.window_ms * 1000),
                        scale=args.scale, seconds=args.seconds, depth=depth, vmin=args.vmin, vmax=args.vmax)
    codec = video_codec()
    note = "" if codec == "avc1" else " (this OpenCV build has no H.264 encoder)"
    print(f"{n} frames ({n / args.fps:.1f} s at {args.fps:g} fps, {CODEC_NAMES[codec]}{note}) -> {args.output}")
    return 0

