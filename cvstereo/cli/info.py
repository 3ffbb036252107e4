"""``cvstereo info FILE...``: what a recording holds, per camera, read as a stream (bounded memory).

Describe each file: per camera the number of events, ON and OFF events, duration and event rate; the resolution;
whether ground truth is present (and for how many events); and, for formats that cannot say, which retina was taken
as left and whether coordinates count from 1, with how that was decided. A file holding one camera is described on
its own.
"""

from __future__ import annotations

import argparse

import numpy as np

from cvstereo.cli._common import add_format_options, check_files, format_options, is_matches_file, naming
from cvstereo.cli._subcommand import subcommand
from cvstereo.cli._text import number, printable
from cvstereo.model.recording import ORIGIN_KEY

__all__ = ["add_parser", "describe", "describe_matches", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "events, ON/OFF counts, duration, rate and resolution of recordings", __doc__)
    p.add_argument("files", metavar="FILE", nargs="+",
                   help="recording files (.npz, .txt/.dat, .aedat, .aedat4, .h5) or DSEC sequence folders, each "
                   "described on its own (so both files of a one-file-per-camera pair too: give the DSEC sequence "
                   "folder to see the pair as one); a matches .npz is summarised as such")
    add_format_options(p)
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.io import open_recording, read_matches

    options = format_options(args)
    for k, path in enumerate(args.files):
        check_files([path])
        with naming(path):
            if is_matches_file(path, options.get("format")):
                lines = describe_matches(path, read_matches(path))
            else:
                lines = describe(open_recording(path, **options))
        if k:
            print()
        print("\n".join(lines))
    return 0


def describe_matches(path, result) -> list[str]:
    """Lines describing a matches file: method, what it was computed on, disparities."""
    meta = result.meta
    source = meta.get("input")
    source = ", ".join(map(str, source)) if isinstance(source, list) else source
    lines = [f"{path}: matches file (written by `cvstereo match`), method {meta.get('method', '?')} "
             f"({meta.get('variant', '?')}), {len(result):,} matches"]
    if source is not None or "input_events" in meta:
        lines.append(f"  computed on {source or '?'}"
                     + (f" ({int(meta['input_events']):,} events)" if isinstance(meta.get("input_events"), int)
                        else ""))
    anchor = meta.get("anchor")
    lines.append(f"  anchors: {anchor or '?'}" + (f", windows of {meta.get('window_us')} us" if anchor == "window"
                                                   else ""))
    if len(result):
        d50, d5, d95 = np.percentile(result.disparity, [50, 5, 95])
        lines.append(f"  disparity: median {number(d50)} px, 5-95 % {number(d5, '.1f')}..{number(d95, '.1f')} px")
    return [printable(line, collapse=False) for line in lines]


def describe(stream) -> list[str]:
    """Lines describing a :class:`~cvstereo.io.stream.RecordingStream` (header lines, then a table)."""
    meta = stream.meta
    width, height = stream.resolution
    # A DSEC sequence folder is one stereo input: named by its folder, its files listed below.
    sequence = meta.get("sequence")
    head = (f"{meta['sequence_folder']}: DSEC sequence {sequence}" if sequence else
            f"{', '.join(stream.files)}: {stream.format}")
    lines = [f"{head}, {width}x{height}"
             + (f" ({_FROM[meta['resolution_from']]})" if "resolution_from" in meta else "")
             # A sequence's truth is its disparity maps, said on their own line; per-event truth it has none.
             + ("" if sequence else ", ground truth" if stream.has_truth else ", no ground truth")
             + ("" if stream.is_stereo else ", one camera")]
    indent = "  "
    if sequence:
        lines.append(f"  files: {', '.join(stream.files)}")
        lines.append(f"  ground-truth disparity maps: {meta['ground_truth_maps'] or 'none (a test sequence)'}")
    if "converted_from" in meta:
        source = meta["converted_from"]
        lines.append(f"  converted from {', '.join(source.get('files', []))} ({source.get('format', '?')}):")
        indent = "    "  # what follows describes how that source was read
    if "left_retina" in meta:
        how = meta["left_retina_from"]
        if how == "detected":
            how = (f"detected: the retinas' event images overlay best {meta['overlay_shift_px']} px apart, "
                   f"correlation {number(meta['overlay_score'])}")
        else:
            how = _FROM[how]
        left = meta["left_retina"]
        lines.append(f"{indent}left camera = retina {left} ({how}); right = retina {1 - left}")
    if "one_based" in meta:
        start = 1 if meta["one_based"] else 0
        lines.append(f"{indent}coordinates count from {start} ({_FROM[meta['one_based_from']]})")
    if "topics" in meta:
        lines.append(f"  topics: left {meta['topics'][0]}, right {meta['topics'][1]}; clock: {meta['clock']}")
    if "special_events" in meta:
        lines.append(f"  special (sync) events skipped: {meta['special_events']:,}")
    rows = [_camera_stats(name, stream) for name in stream.cameras]
    firsts = [r["first"] for r in rows if r["first"] is not None]
    origin = meta.get(ORIGIN_KEY, min(firsts) if firsts else None)
    if origin is not None:  # the one place the absolute time is shown: plots and options count from it
        lines.append(f"  t = 0 at {origin} us on the recording's clock (its first event); times shown and time "
                     "options count from it")
    lines.extend("  " + line for line in _table(rows, truth=stream.has_truth))
    # Names and meta come from the file: no raw terminal codes.
    return [printable(line, collapse=False) for line in lines]


_FROM = {"given": "given", "header": "from the file's header", "default": "default", "detected": "detected",
         "messages": "from the messages"}


def _camera_stats(name: str, stream) -> dict:
    n = on = finite = 0
    first = last = None
    for events, truth in stream.chunks(name):
        if not events.size:
            continue
        n += events.size
        on += int(np.count_nonzero(events["p"]))
        first = int(events["t"][0]) if first is None else first
        last = int(events["t"][-1])
        if truth is not None:
            finite += int(np.count_nonzero(np.isfinite(truth)))
    duration = 0.0 if first is None else (last - first) / 1e6
    return {"camera": name, "events": n, "on": on, "off": n - on, "duration": duration, "truth": finite,
            "first": first}


def _table(rows: list[dict], *, truth: bool) -> list[str]:
    head = ["camera", "events", "ON", "OFF", "duration", "rate"] + (["with truth"] if truth else [])
    body = []
    for r in rows:
        n = r["events"]
        cells = [r["camera"], f"{n:,}", _share(r["on"], n), _share(r["off"], n), f"{r['duration']:.3f} s",
                 f"{n / r['duration']:,.0f} ev/s" if r["duration"] > 0 else "-"]
        if truth:
            cells.append(_share(r["truth"], n))
        body.append(cells)
    widths = [max(len(row[i]) for row in [head, *body]) for i in range(len(head))]
    # Names left-aligned, numbers right-aligned, so that digits line up.
    return ["  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths, strict=True)))
            for row in [head, *body]]


def _share(k: int, n: int) -> str:
    return f"{k:,} ({100 * k / n:.1f}%)" if n else "0"
