"""``cvstereo plot KIND RECORDING [RIGHT] [MATCHES] -o OUT.png``: the thesis' pictures of a recording and its matches.

Needs the ``viz`` extra (matplotlib). ``KIND all`` writes every picture the inputs allow into the folder ``-o``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from cvstereo.cli._common import (
    add_depth_options,
    add_force_option,
    add_recording_arguments,
    conflicts_as_usage_errors,
    load_matches_for,
    load_recording,
    naming,
    picture_depth,
    recording_plan,
    require_range,
)

__all__ = ["KINDS", "MAX_DPI", "MAX_TIME_MS", "MAX_WINDOWS", "MAX_WINDOW_MS", "add_cmap_option", "add_parser",
           "check_window_inside", "check_window_options", "load_picture_inputs", "make_figure", "name_recording",
           "run", "start_us"]

#: Largest --dpi: print quality; a figure at 100000 dpi would need gigabytes.
MAX_DPI = 1200
#: Largest --windows of a disparity map (one row of pictures each).
MAX_WINDOWS = 50
#: Largest window and start time in ms (an hour; 10^13 ms keeps microseconds within int64).
MAX_WINDOW_MS, MAX_TIME_MS = 3_600_000, 1e13


def name_recording(recording, path) -> None:
    """Give a recording without a preset or scene (a real file) its file name, so that titles name it."""
    from cvstereo.viz.mpl import recording_name

    if not recording_name(recording.meta):
        recording.meta["name"] = Path(path).name


def load_picture_inputs(args: argparse.Namespace):
    """What `plot` and `video` draw: (the recording, named for titles and with its cameras as the matches used
    them; the matches, checked to come from it (:func:`~cvstereo.cli._common.load_matches_for`), or None; the
    depth model, or None)."""
    recording = load_recording(args)
    name_recording(recording, args.recording)
    result = None
    if args.matches is not None:
        recording, result = load_matches_for(args, recording)
    with conflicts_as_usage_errors(args):
        return recording, result, picture_depth(args, recording, result)


def check_window_options(args: argparse.Namespace) -> None:
    """``--window-ms`` (and ``--t-start-ms`` where the command has it) finite and within their limits."""
    require_range(args.window_ms, "--window-ms", gt=0, le=MAX_WINDOW_MS)
    require_range(getattr(args, "t_start_ms", None), "--t-start-ms", ge=0, le=MAX_TIME_MS)

def add_cmap_option(p: argparse.ArgumentParser) -> None:
    """``--cmap NAME``: the colour map of disparities (every command that draws them)."""
    from cvstereo.viz.colormaps import DISPARITY_CMAP

    p.add_argument("--cmap", default=DISPARITY_CMAP, metavar="NAME",
                   help="colour map of the disparities, any matplotlib name (default: %(default)s, colour-blind "
                   "safe; its darkest end is left out so that it shows on the black background)")


def start_us(args: argparse.Namespace, recording) -> int | None:
    """``--t-start-ms`` as an absolute time, us: milliseconds after the recording's origin (``cvstereo info``'s
    "t = 0 at"), None when not given."""
    ms = getattr(args, "t_start_ms", None)
    return None if ms is None else recording.origin_us + _ms_to_us(ms)


def check_window_inside(args: argparse.Namespace, recording) -> None:
    """``--t-start-ms`` must show some of the recording: an empty window past its end is a typo, not a picture.

    The window ``[t, t + --window-ms)`` (t counted from the recording's origin, as the pictures show times) must
    overlap ``[first event, last event]``; the error names that span so that the user can pick a time.
    """
    t_start = start_us(args, recording)
    if t_start is None:
        return
    first, last, origin = recording.t_start, recording.t_end, recording.origin_us
    if t_start > last or t_start + _ms_to_us(args.window_ms) <= first:
        raise ValueError(f"--t-start-ms {args.t_start_ms:g} shows no event: the recording's events lie between "
                         f"{(first - origin) / 1000:g} ms and {(last - origin) / 1000:g} ms after its origin; pick a "
                         "start in that span (or leave it out for the busiest window).")


#: Picture kind (also its file name under ``all``) -> (needs matches, what it shows).
KINDS: dict[str, tuple[bool, str]] = {
    "events": (False, "both cameras' events of one window, ON blue, OFF orange (thesis fig. 3.2)"),
    "filtered": (False, "Gaussian-filtered signed frames and the pixels above threshold (fig. 3.3)"),
    "dynamic": (False, "the decaying dynamic frames at the end of the window (fig. 3.5)"),
    "disparity-time": (True, "every match's disparity over time with the ground truth (figs. 4.4, 4.5)"),
    "disparity-map": (True, "colour-coded disparity at the anchor pixels per window (figs. 4.3, 4.6)"),
    "error-hist": (True, "histogram of the error against ground truth, with MAE and bad1"),
}


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    kinds = "\n".join(f"  {k:15s} {desc}{' (needs MATCHES)' if needs else ''}" for k, (needs, desc) in KINDS.items())
    p = sub.add_parser(
        name,
        help="draw the thesis' figures of a recording and a matches file (extra: viz)",
        description="Draw a picture of a recording and, for the disparity pictures, of a matches file written by "
        f"`cvstereo match`. Kinds:\n{kinds}\n  all             every picture the inputs allow, into the folder -o",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("kind", metavar="KIND", choices=[*KINDS, "all"], help=f"one of: {', '.join(KINDS)}, all")
    add_recording_arguments(p, matches="optional")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="picture to write (.png, .pdf, .svg); for KIND all, a folder (created if missing)")
    p.add_argument("--t-start-ms", type=float, default=None, metavar="MS",
                   help="start of the window shown, ms after the recording's first event (its origin, `cvstereo "
                   "info` prints it; default: the window with the most events); disparity-map: the first of "
                   "--windows consecutive windows (a frame matcher's: the window holding that time on the "
                   "recording's clock; default: windows spread over the matches)")
    p.add_argument("--window-ms", type=float, default=40.0, metavar="MS",
                   help="window length (default: %(default)g, the thesis'; frame matchers' own window for "
                   "their matches)")
    p.add_argument("--windows", type=int, default=3, metavar="N", help="disparity-map: number of windows (rows)")
    p.add_argument("--vmin", type=float, default=None, metavar="PX",
                   help="disparity-map: disparity at the low end of the colour scale (default: from the data)")
    p.add_argument("--vmax", type=float, default=None, metavar="PX",
                   help="disparity-map: disparity at the high end of the colour scale (default: from the data)")
    add_cmap_option(p)
    p.add_argument("--log", action="store_true", help="error-hist: logarithmic count axis")
    p.add_argument("--width-in", type=float, default=None, metavar="IN",
                   help="figure width in inches, height in proportion, text shrunk to fit (e.g. 3.5 for one column "
                   "of a two-column paper; default: the figure's own)")
    p.add_argument("--column", dest="width_in", action="store_const", const=3.5,
                   help="the same as --width-in 3.5 (a single paper column)")
    add_depth_options(p)
    p.add_argument("--dpi", type=float, default=None, help="resolution of raster pictures (default: 120)")
    add_force_option(p, "draw")
    p.set_defaults(_parser=p)
    return p


def _ms_to_us(ms: float | None) -> int | None:
    return None if ms is None else round(ms * 1000)


def run(args: argparse.Namespace) -> int:
    from cvstereo.viz.mpl import require_matplotlib

    require_matplotlib()  # before reading anything: a missing extra is said at once
    check_window_options(args)
    if not 1 <= args.windows <= MAX_WINDOWS:
        raise ValueError(f"--windows must be between 1 and {MAX_WINDOWS}, got {args.windows}.")
    require_range(args.dpi, "--dpi", gt=0, le=MAX_DPI)
    from cvstereo.viz.colormaps import check_cmap

    check_cmap(args.cmap)
    if args.kind != "all" and KINDS[args.kind][0] and args.matches is None:
        raise ValueError(f"plot {args.kind} shows matches: give the MATCHES file written by `cvstereo match` "
                         f"after RECORDING (e.g. cvstereo plot {args.kind} rec.npz matches.npz -o out.png).")
    from cvstereo.io.output_plan import FIGURE
    from cvstereo.viz import save_figure

    plan = recording_plan(args)
    if args.kind == "all":
        kinds = [kind for kind, (needs_matches, _) in KINDS.items() if args.matches is not None or not needs_matches]
        outputs = plan.write_folder(args.output, [f"{kind}.png" for kind in kinds], FIGURE)
    else:
        plan.write(args.output, FIGURE)
        kinds, outputs = [args.kind], [args.output]
    said = []
    with plan:  # every file checked first; the pictures published together once all are drawn
        recording, result, depth = load_picture_inputs(args)
        check_window_inside(args, recording)
        planned = dict(zip(kinds, outputs, strict=True))
        for kind in KINDS if args.kind == "all" else kinds:
            if kind not in planned:
                said.append(f"{kind}: skipped (no MATCHES given)")
            elif kind == "error-hist" and args.kind == "all" and not recording.has_truth:
                said.append(f"{kind}: skipped (the recording has no ground truth)")
            else:
                with naming(args.recording, args.matches):
                    figure = make_figure(kind, recording, result, args, depth)
                save_figure(figure, planned[kind], dpi=args.dpi, width_in=args.width_in)
                said.append(f"{kind} -> {planned[kind]}")
    print("\n".join(said))
    return 0


def make_figure(kind: str, recording, result, args: argparse.Namespace, depth):
    """The figure of one kind, with the command line's window options."""
    from cvstereo import viz

    window_us = _ms_to_us(args.window_ms)
    t_start = start_us(args, recording)
    if kind == "events":
        return viz.plot_event_frames(recording, t_start, window_us=window_us)
    if kind == "filtered":
        return viz.plot_filtered_frames(recording, t_start, window_us=window_us)
    if kind == "dynamic":
        t = None if t_start is None else t_start + window_us
        return viz.plot_dynamic_frames(recording, t)
    if kind == "disparity-time":
        return viz.plot_disparity_over_time(recording, result, window_us=window_us, depth=depth)
    if kind == "disparity-map":
        anchor, own = result.meta.get("anchor"), int(result.meta.get("window_us", 0) or 0)
        w = own if anchor == "window" and own > 0 else window_us
        # A frame matcher's windows lie on the absolute grid: show the one holding t_start, not a shifted one.
        first = None if t_start is None else (t_start - t_start % w if anchor == "window" else t_start)
        ends = None if first is None else [first + w * (i + 1) for i in range(args.windows)]
        return viz.plot_disparity_map(recording, result, ends, n_windows=args.windows, window_us=window_us,
                                      depth=depth, vmin=args.vmin, vmax=args.vmax, cmap=args.cmap)
    if kind == "error-hist":
        return viz.plot_error_histogram(recording, result, log=args.log)
    raise ValueError(f"unknown picture kind {kind!r}; choose one of: {', '.join(KINDS)}, all.")
