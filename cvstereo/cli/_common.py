"""Options and helpers shared by several subcommands."""

from __future__ import annotations

import argparse


def add_recording_arguments(parser: argparse.ArgumentParser, *, right: bool = True) -> None:
    """Add ``RECORDING [RIGHT]`` and the format options a file cannot always tell."""
    parser.add_argument("recording", metavar="RECORDING", help="recording file (or the left camera's file)")
    if right:
        parser.add_argument("right", metavar="RIGHT", nargs="?", default=None,
                            help="the right camera's file, for formats with one file per camera")
    add_format_options(parser)


def add_format_options(parser: argparse.ArgumentParser) -> None:
    """``--format``, ``--left-retina``, ``--one-based``, ``--resolution``."""
    from cvstereo.io import FORMATS

    g = parser.add_argument_group("input format (where the file cannot tell)")
    g.add_argument("--format", choices=FORMATS, default=None, help="input format (default: from the extension)")
    g.add_argument("--left-retina", type=int, choices=(0, 1), default=None,
                   help="merged text files: which retina id is the left camera (default: detect from the data)")
    g.add_argument("--one-based", action=argparse.BooleanOptionalAction, default=None,
                   help="text files: coordinates count from 1 (default: detect)")
    g.add_argument("--resolution", type=_resolution, default=None, metavar="WxH",
                   help="sensor size (default: from the file, else 128x128)")


def _resolution(text: str) -> tuple[int, int]:
    from cvstereo.events import check_resolution

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not WIDTHxHEIGHT, e.g. 128x128") from None
    try:
        return check_resolution((w, h), source="size")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def format_options(args: argparse.Namespace) -> dict:
    """The format options given on the command line, as keyword arguments for the readers."""
    opts = {}
    if getattr(args, "format", None):
        opts["format"] = args.format
    for key in ("left_retina", "one_based", "resolution"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    return opts


def load_recording(args: argparse.Namespace, path_attr: str = "recording"):
    """Read the recording named on the command line with its format options."""
    from cvstereo.io import read_recording

    return read_recording(getattr(args, path_attr), getattr(args, "right", None), **format_options(args))


def add_depth_options(p: argparse.ArgumentParser) -> None:
    """``--depth A C`` and ``--metres/--no-metres``: a distance axis from d = A/Z - C."""
    g = p.add_argument_group("distance in metres (d = A/Z - C)")
    g.add_argument("--depth", type=float, nargs=2, default=None, metavar=("A", "C"),
                   help="A = focal length (px) x baseline (m) and C (px), e.g. from `cvstereo depth-fit` "
                   "(default: from the recording's rig, where it has one)")
    g.add_argument("--metres", action=argparse.BooleanOptionalAction, default=True,
                   help="show distances where a depth model is known (default: yes)")


def depth_model(args: argparse.Namespace, recording):
    """The DepthModel the options ask for, or None."""
    from cvstereo.depth import DepthModel
    from cvstereo.viz import depth_from_meta

    if not args.metres:
        return None
    if args.depth is not None:
        return DepthModel(a=args.depth[0], c=args.depth[1])
    return depth_from_meta(recording.meta)
