"""``cvstereo match RECORDING [RIGHT] --method M [--variant V] [--param key=value ...] -o MATCHES.npz``.

Runs one matcher over a recording (through :func:`calibration_free.match`, so the file holds exactly what
``match()`` returns) and writes the matches file of formats.md. ``--list-methods`` prints every registered
method with its variants and parameters. ``--param-set thesis|adaptive`` picks the parameter set
(:mod:`cvstereo.param_sets`). A run that answers in less than 1 % of the 40 ms windows with events says why on
one ``warning:`` line on stderr (and still exits 0).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import typing

import numpy as np

from cvstereo.cli._common import add_depth_options, add_format_options, depth_model, format_options
from cvstereo.param_sets import DEFAULT_PARAM_SET, PARAM_SETS


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = sub.add_parser(
        name,
        help="run a stereo matcher over a recording and write a matches file",
        description="Run a stereo matcher (the thesis' frame and event matchers, or OpenCV's StereoBM/SGBM on "
        "the same frames) over a recording and write the matches file (.npz). "
        "`cvstereo match --list-methods` lists methods, variants and parameters with their defaults.",
    )
    p.add_argument("recording", metavar="RECORDING", nargs="?", default=None,
                   help="recording file (or the left camera's file)")
    p.add_argument("right", metavar="RIGHT", nargs="?", default=None,
                   help="the right camera's file, for formats with one file per camera")
    p.add_argument("--method", "-m", default="frame", help="matcher name (default: frame; see --list-methods)")
    p.add_argument("--variant", default=None,
                   help="variant name (default: the parameter set's default variant; see --list-methods)")
    p.add_argument("--param-set", choices=PARAM_SETS, default=DEFAULT_PARAM_SET,
                   help="adaptive (default): thresholds relative to the recording's own signal level and each "
                   "method's best variant; thesis: the thesis' constants and default variants, as published")
    p.add_argument("--param", "-p", action="append", default=[], metavar="KEY=VALUE",
                   help="override a parameter (repeatable); names as in --list-methods")
    p.add_argument("-o", "--output", metavar="MATCHES.npz", default=None, help="matches file to write")
    p.add_argument("--packet-us", type=int, default=None, metavar="US",
                   help="stream the recording in packets of this length (the result does not depend on it)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="show a progress bar (default: when stderr is a terminal)")
    p.add_argument("--list-methods", action="store_true", help="list methods, variants and parameters, then exit")
    add_depth_options(p)
    g = p.add_argument_group("rig correction (cvstereo rigcheck)")
    g.add_argument("--auto", action="store_true",
                   help="run the rig check first; swap the cameras and remove row/time offsets it finds (printed, "
                   "and stored in the matches file's meta under 'rigcheck')")
    g.add_argument("--row-offset", type=int, default=None, metavar="ROWS",
                   help="add ROWS to the right camera's y before matching (overrides --auto's estimate)")
    g.add_argument("--time-offset-us", type=int, default=None, metavar="US",
                   help="the right camera stamps US later: subtract it from its t (overrides --auto's estimate)")
    add_format_options(p)
    p.set_defaults(_parser=p)
    return p


def run(args: argparse.Namespace) -> int:
    from calibration_free.registry import matcher_class, parse_param_strings

    if args.list_methods:
        print(list_methods())
        return 0
    if args.recording is None or args.output is None:
        args._parser.error("RECORDING and -o MATCHES.npz are required (or give --list-methods)")
    cls = matcher_class(args.method)  # ValueError listing the known methods
    overrides = parse_param_strings(cls.Params, args.param)  # ValueError listing the allowed names
    # Validate variant and values before reading a possibly long recording.
    from cvstereo.param_sets import resolve

    variant, set_params = resolve(args.method, args.variant, args.param_set)
    cls.make_params(variant, **{**set_params, **overrides})
    from calibration_free.run import DEFAULT_PACKET_US, match
    from cvstereo.cli._common import load_recording

    recording = load_recording(args)
    recording, rig, offsets = _rig_correction(args, recording)
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    result = match(recording, method=args.method, variant=args.variant, progress=progress,
                   packet_us=args.packet_us or DEFAULT_PACKET_US, param_set=args.param_set, **offsets, **overrides)
    if rig is not None:
        result.meta["rigcheck"] = rig
    result.meta["input"] = [args.recording] + ([args.right] if args.right else [])
    result.meta["format_options"] = {k: list(v) if isinstance(v, tuple) else v
                                     for k, v in format_options(args).items()}
    depth = depth_model(args, recording)
    if depth is not None:
        # The matches format is a contract: distances are not a column; the model that gives them is in meta.
        result.meta["depth"] = depth.to_dict()
    result.save(args.output)
    m = result.meta
    print(f"{len(result)} matches from {m['input_events']} events ({args.method}, {m['variant']}, "
          f"{args.param_set}) in {m['elapsed_s']:.2f} s -> {args.output}")
    from cvstereo.signal_level import silence_warning

    warning = silence_warning(m, n_matches=len(result))
    if warning is not None:
        print(f"warning: {warning}", file=sys.stderr)
    if len(result):
        d50, d5, d95 = np.percentile(result.disparity, [50, 5, 95])
        line = f"disparity: median {d50:.2f} px, 5-95 % {d5:.1f}..{d95:.1f} px"
        if depth is not None:
            z50, z5, z95 = depth.distance([d50, d95, d5])  # larger disparity, nearer
            line += (f"; distance: median {z50:.2f} m, 5-95 % {z5:.2f}..{z95:.2f} m "
                     f"(d = {depth.a:.2f}/Z - {depth.c:.2f})")
        print(line)
    return 0


def _rig_correction(args: argparse.Namespace, recording):
    """``--auto`` / ``--row-offset`` / ``--time-offset-us``: (recording to match, rigcheck meta or None, offsets)."""
    rig, offsets = None, {}
    if args.auto:
        from cvstereo.rigcheck import check_rig

        report = check_rig(recording)
        print(report.summary())
        prepared = report.prepare(recording)
        swap, recording = prepared is not recording, prepared
        offsets = report.match_kwargs()
        rig = {**report.to_dict(), "applied": {"swap": swap, **offsets}}
    for key in ("row_offset", "time_offset_us"):
        if getattr(args, key) is not None:
            offsets[key] = getattr(args, key)
    if rig is not None:
        rig["applied"].update(offsets)
        print(f"applied: {'swapped cameras, ' if rig['applied']['swap'] else ''}row offset "
              f"{offsets.get('row_offset', 0)}, time offset {offsets.get('time_offset_us', 0)} us")
    return recording, rig, offsets


def list_methods() -> str:
    """Every registered method with its variants and parameters (defaults, types), as text.

    Methods whose module cannot be imported here are listed as unavailable, with the reason. The parameter
    defaults listed are the ``thesis`` set's; the ``adaptive`` line gives what that set changes, and why its
    default variant.
    """
    from calibration_free.registry import METHODS, matcher_class
    from cvstereo.param_sets import ADAPTIVE

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
        spec = ADAPTIVE.get(name)
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
        for f in dataclasses.fields(cls.Params):
            lines.append(f"    {f.name} = {_text(getattr(defaults, f.name))}  ({_type_text(hints[f.name])})")
        lines.append("")
    return "\n".join(lines).rstrip()


def _text(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _type_text(hint) -> str:
    if typing.get_origin(hint) is typing.Literal:
        return "one of " + "|".join(map(str, typing.get_args(hint)))
    return getattr(hint, "__name__", str(hint))
