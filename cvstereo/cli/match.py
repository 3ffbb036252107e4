"""``cvstereo match RECORDING [RIGHT] --method M [--variant V] [--param key=value ...] -o MATCHES.npz``.

Run a stereo matcher (the thesis' frame and event matchers, or OpenCV's StereoBM/SGBM on the same frames) over a
recording and write the matches file (.npz). `cvstereo match --list-methods` lists methods, variants and parameters
with their defaults.

Runs one matcher over a recording, streamed from its file packet by packet (memory holds the matches, not the
events), and writes the matches file of docs/formats.md. The command wires library steps together
(:mod:`cvstereo.geometry.steps`): the geometry resolved, the match (:func:`cvstereo.run.match`, so the file
holds what ``match()`` returns), the geometry and the depth of every match recorded, the point cloud.
Unless the geometry comes from elsewhere (a calibration -- a DSEC sequence's own by default --, offsets, ``--auto``)
or ``--param-set thesis``, the match checks the rig on the first second of the stream and applies what it finds
(:mod:`cvstereo.rigcheck.prefix`; ``--no-rig-check`` turns it off). ``--auto``'s rig check looks at the whole
recording, which it reads into memory before the match reads the file again. ``--param-set thesis|adaptive``
picks the parameter set (:mod:`cvstereo.matchers.sets`). A run that answers in less than 1 %
of the 40 ms windows with events says why on one ``warning:`` line on stderr (and still exits 0). Where the
geometry comes from (calibration, options, the recording's rig, the rig check: :mod:`cvstereo.geometry.source`)
is said on one ``geometry:`` line and stored in the file; the matches file and a ``--point-cloud`` appear
together, once both are written (an output plan: :mod:`cvstereo.io.output_plan`).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import typing

import numpy as np

from cvstereo.cli._common import (
    add_depth_options,
    add_matcher_options,
    add_progress_option,
    add_recording_arguments,
    conflicts_as_usage_errors,
    format_options,
    matcher_overrides,
    matcher_threads,
    open_recording_stream,
    parse_depth_option,
    progress_wanted,
    recording_plan,
    require_range,
)
from cvstereo.cli._rerun import add_rerun_option, rerun_target
from cvstereo.cli._subcommand import subcommand
from cvstereo.cli._text import number, plain_text
from cvstereo.cli.plot import add_cmap_option
from cvstereo.evaluation.diagnostics import silence_warning

__all__ = ["MAX_TIME_OFFSET_US", "add_parser", "list_methods", "run"]

#: Largest --time-offset-us either way: a day (real rigs are off by milliseconds).
MAX_TIME_OFFSET_US = 86_400_000_000


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "run a stereo matcher over a recording and write a matches file", __doc__)
    add_recording_arguments(p, required=False)
    add_matcher_options(p)
    p.add_argument("-o", "--output", metavar="MATCHES.npz", default=None,
                   help="matches file to write (.npz, or a name without extension)")
    p.add_argument("--packet-us", type=int, default=None, metavar="US",
                   help="stream the recording in packets of this length (the result does not depend on it)")
    add_progress_option(p)
    p.add_argument("--list-methods", action="store_true", help="list methods, variants and parameters, then exit")
    add_depth_options(p)
    g = p.add_argument_group("rig correction (cvstereo rigcheck)")
    g.add_argument("--auto", action="store_true",
                   help="run the rig check first; swap the cameras and remove row/time offsets it finds (printed, "
                   "and stored in the matches file's meta under 'rigcheck'). The check looks at the whole "
                   "recording: it is read into memory for it, then read again for the match")
    g.add_argument("--no-rig-check", action="store_true",
                   help="match the events as recorded: no rig check on the first second of the stream (by default "
                   "it runs, unless a calibration, offsets, --auto or --param-set thesis say otherwise)")
    g.add_argument("--row-field", action="store_true",
                   help="the default rig check also looks for rows that differ across the image (a roll, focal "
                   "lengths or lenses that differ) and applies the field it finds instead of one row offset")
    g.add_argument("--row-offset", type=int, default=None, metavar="ROWS",
                   help="add ROWS to the right camera's y before matching (overrides --auto's estimate)")
    g.add_argument("--time-offset-us", type=int, default=None, metavar="US",
                   help="the right camera stamps US later: subtract it from its t (overrides --auto's estimate)")
    g = p.add_argument_group("calibrated rigs and 3D output (cvstereo needs no calibration; use one if you have it)")
    g.add_argument("--calibration", metavar="FILE", default=None,
                   help="rectify the events with this calibration before matching: DSEC cam_to_cam.yaml, Kalibr/MVSEC "
                   "camchain .yaml, or .json/.npz with K1 D1 K2 D2 R T resolution; also gives the depth model")
    g.add_argument("--point-cloud", metavar="FILE.ply", default=None,
                   help="also write the matches with a distance as a PLY point cloud (needs a depth model)")
    g.add_argument("--focal-px", type=float, default=None, metavar="F",
                   help="point cloud without a calibration: focal length in px (default: the recording's rig, where "
                   "it has one, else the thesis rig's 165)")
    add_rerun_option(p)
    add_cmap_option(p)
    p.set_defaults(_parser=p)
    return p


def run(args: argparse.Namespace) -> int:
    if args.list_methods:
        print(list_methods())
        return 0
    if args.recording is None or args.output is None:
        args._parser.error("RECORDING and -o MATCHES.npz are required (or give --list-methods)")
    if args.focal_px is not None and args.point_cloud is None:
        args._parser.error("--focal-px is the point cloud's focal length: give --point-cloud FILE.ply with it")
    overrides = matcher_overrides(args)  # method, variant and values, before reading a possibly long recording
    threads = matcher_threads(args)
    require_range(args.packet_us, "--packet-us", gt=0)
    if args.time_offset_us is not None and abs(args.time_offset_us) > MAX_TIME_OFFSET_US:
        raise ValueError(f"--time-offset-us must be within +-{MAX_TIME_OFFSET_US:,} us (a day), got "
                         f"{args.time_offset_us:,}.")
    from cvstereo.geometry.steps import point_cloud_of, record_geometry
    from cvstereo.io import write_matches
    from cvstereo.io.output_plan import MATCHES_FILE, POINT_CLOUD, RERUN_FILE
    from cvstereo.run import DEFAULT_PACKET_US, match

    plan = recording_plan(args)
    plan.read(args.calibration, what="calibration file")
    plan.write(args.output, MATCHES_FILE)
    plan.write(args.point_cloud, POINT_CLOUD, option="--point-cloud")
    rerun = rerun_target(args)
    if rerun.wanted:
        from cvstereo.viz.colormaps import check_cmap

        check_cmap(args.cmap)
    plan.write(rerun.path, RERUN_FILE, option="--rerun")
    said = []  # lines about outputs, printed once they are published
    from cvstereo.viz.rerun_log import rerun_stream

    # Every file checked (and a viewer started) before any work; the outputs published together at the end.
    with plan, rerun_stream(rerun) as viewer:
        options = _geometry_options(args)
        stream = open_recording_stream(args)  # streamed: read again for the match after an --auto check
        height = stream.resolution[1]
        if args.row_offset is not None and abs(args.row_offset) >= height:
            raise ValueError(f"--row-offset must be within +-{height - 1} rows (the sensor is {height} rows high), "
                             f"got {args.row_offset}.")
        geometry = options.resolve(stream.meta, stream.resolution, recording=stream.read)
        if args.point_cloud is not None and geometry.depth is None:
            raise ValueError("--point-cloud needs a depth model: give --depth A C (or MODEL.json) or --calibration.")
        prepared = geometry.prepare(stream)
        rig_check = geometry.rig_check_wanted and not args.no_rig_check
        if args.row_field and not (rig_check and args.param_set != "thesis"):
            raise ValueError("--row-field needs the default rig check: not with --no-rig-check, --auto, "
                             "--param-set thesis, a calibration or offsets.")
        result = match(prepared, method=args.method, variant=args.variant, progress=progress_wanted(args),
                       packet_us=args.packet_us or DEFAULT_PACKET_US, param_set=args.param_set, threads=threads,
                       rig_check=rig_check, row_field=args.row_field, **geometry.match_kwargs(),
                       **overrides)
        geometry = geometry.matched(result.meta)  # with what the match's own rig check applied
        result = record_geometry(result, geometry)
        result.meta["format_options"] = {k: list(v) if isinstance(v, tuple) else v
                                         for k, v in format_options(args).items()}
        if args.point_cloud is not None:
            said.append(_write_point_cloud(args, result, point_cloud_of(result, geometry), geometry))
        write_matches(args.output, result.matches, result.meta, arrays=result.arrays)
        if viewer is not None:  # the pictures need the events: the file is read again, whole, only for --rerun
            said.append(_log_to_rerun(args, viewer, rerun, prepared.read(), result, geometry))
    m = result.meta
    print(geometry.summary(), *said, sep="\n")
    print(f"{len(result)} matches from {m['input_events']} events ({args.method}, {m['variant']}, "
          f"{args.param_set}) in {m['elapsed_s']:.2f} s -> {args.output}")
    warning = silence_warning(m, n_matches=len(result))
    if warning is not None:
        print(f"warning: {warning}", file=sys.stderr)
    if len(result):
        depth = geometry.depth
        d50, d5, d95 = np.percentile(result.disparity, [50, 5, 95])
        line = f"disparity: median {number(d50)} px, 5-95 % {number(d5, '.1f')}..{number(d95, '.1f')} px"
        if depth is not None:
            z50, z5, z95 = depth.distance([d50, d95, d5])  # larger disparity, nearer
            line += (f"; distance: median {number(z50, '.2f', ' m')}, 5-95 % {number(z5)}..{number(z95, '.2f', ' m')}"
                     f" (d = {depth.a:.2f}/Z - {depth.c:.2f})")
        print(line)
    return 0


def _geometry_options(args: argparse.Namespace):
    """What the command line gives towards the geometry (:class:`cvstereo.geometry.source.GeometryOptions`);
    options that exclude each other are usage errors."""
    from cvstereo.geometry.calibration import load_calibration
    from cvstereo.geometry.source import GeometryOptions

    calibration = None
    if args.calibration is not None:
        calibration = load_calibration(args.calibration)
    elif _own_calibration_applies(args):
        from cvstereo.io.dsec_sequence import find_dsec_sequence

        own = find_dsec_sequence(args.recording).calibration
        calibration = None if own is None else load_calibration(own)
    with conflicts_as_usage_errors(args):
        return GeometryOptions(calibration=calibration,
                               depth=parse_depth_option(args.depth) if args.depth is not None and args.metres
                               else None,
                               focal_px=args.focal_px, row_offset=args.row_offset, time_offset_us=args.time_offset_us,
                               metres=args.metres, point_cloud=args.point_cloud is not None,
                               rig_check=_rig_check if args.auto else None)


def _own_calibration_applies(args: argparse.Namespace) -> bool:
    """Whether a DSEC sequence's own ``calibration/cam_to_cam.yaml`` is taken: the input is a sequence folder, and
    no option that a calibration would conflict with is given (they mean the user wants the raw events)."""
    from cvstereo.io.dsec_sequence import is_dsec_sequence

    given = (args.row_offset, args.time_offset_us, args.focal_px, args.depth if args.metres else None)
    return is_dsec_sequence(args.recording) and not args.auto and all(v is None for v in given)


def _rig_check(recording):
    """``--auto``: the rig check, its report printed."""
    from cvstereo.rigcheck import check_rig

    report = check_rig(recording)
    print(report.summary())
    return report


def _log_to_rerun(args: argparse.Namespace, viewer, rerun, recording, result, geometry) -> str:
    """``--rerun``: the windows of the matches (the matcher's own for frame matchers, else 40 ms) for the viewer."""
    from cvstereo.viz.rerun_log import log_windows

    intrinsics = geometry.intrinsics if geometry.depth is not None else None
    n = log_windows(viewer, recording, result, depth=geometry.depth, intrinsics=intrinsics, cmap=args.cmap)
    return f"{n} windows -> {rerun.path or 'the rerun viewer'}"


def _write_point_cloud(args: argparse.Namespace, result, points, geometry) -> str:
    """Write ``points``, the point cloud of ``result``, to ``--point-cloud`` (into the plan); return the line that
    says so."""
    from cvstereo.geometry.pointcloud import write_ply

    write_ply(args.point_cloud, points, model=geometry.depth, intrinsics=geometry.intrinsics,
              comments=(f"input {' '.join(result.meta['input'])}", f"method {args.method} ({result.meta['variant']})"))
    return f"{points.size} points -> {args.point_cloud} (intrinsics from {geometry.intrinsics.source})"


def list_methods() -> str:
    """Every registered method with its variants and parameters (defaults, types), as text.

    Methods whose module cannot be imported here are listed as unavailable, with the reason. The parameter
    defaults listed are the ``thesis`` set's; the ``adaptive`` line gives what that set changes, and why its
    default variant. A parameter whose 0 means "automatic" says what it then takes (a matcher class's
    ``automatic_values(params)``).
    """
    from cvstereo.matchers.registry import METHODS, matcher_class

    lines = []
    for name in METHODS:
        try:
            cls = matcher_class(name)
        except ImportError as exc:
            lines.append(f"{name}: unavailable ({type(exc).__name__}: {exc})")
            lines.append("")
            continue
        variants = list(cls.variants)
        lines.append(f"{name}: {(cls.__doc__ or '').strip().splitlines()[0]}")
        spec = getattr(cls.Params, "adaptive", None)
        adaptive = spec.variant if spec is not None else variants[0]
        labels = []
        for i, v in enumerate(variants):
            tags = (["default"] if v == adaptive else []) + (["thesis default"] if i == 0 and v != adaptive else [])
            labels.append(f"{v} ({', '.join(tags)})" if tags else v)
        lines.append("  variants: " + ", ".join(labels))
        for v in variants[1:]:
            if cls.variants[v]:
                lines.append(f"    {v}: " + ", ".join(f"{k}={_text(x)}" for k, x in cls.variants[v].items()))
        if spec is not None:
            lines.append(f"  adaptive set (default): variant {spec.variant}, because {spec.why}; "
                         + ", ".join(f"{k}={_text(x)}" for k, x in spec.params.items()))
            for v, extra in spec.variant_params.items():
                lines.append(f"    with {v}: " + ", ".join(f"{k}={_text(x)}" for k, x in extra.items()))
            lines.append(f"  thesis set (--param-set thesis): variant {variants[0]}, the parameters below "
                         "(absolute thresholds)")
        lines.append("  parameters (--param key=value):")
        hints = typing.get_type_hints(cls.Params)
        defaults = cls.Params()
        # A 0 that means "automatic" (sgbm's p1, p2) is named with the value it takes, so that nobody reads 0.
        automatic = getattr(cls, "automatic_values", lambda params: {})(defaults)
        for f in dataclasses.fields(cls.Params):
            auto = f"; 0 = automatic: {automatic[f.name]}" if f.name in automatic else ""
            lines.append(f"    {f.name} = {_text(getattr(defaults, f.name))}  ({_type_text(hints[f.name])}{auto})")
        lines.append("")
    # Method docstrings and the parameter sets' reasons are written for Sphinx: shown here as plain text.
    return plain_text("\n".join(lines).rstrip())


def _text(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _type_text(hint) -> str:
    if typing.get_origin(hint) is typing.Literal:
        return "one of " + "|".join(map(str, typing.get_args(hint)))
    return getattr(hint, "__name__", str(hint))
