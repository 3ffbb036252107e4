"""``cvstereo demo``: the main job of ``make demo``.

The thesis' experiment on the built-in simulated recordings: the six presets are simulated once and
cached, every matcher variant runs on each, and the thesis-style tables are printed with the ground-truth
figures beside the thesis' published numbers. The real TUM recordings are summarised when present.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
from pathlib import Path

from cvstereo.cli._common import add_progress_option, progress_wanted

#: Matchers the demo runs: the thesis' five and OpenCV's block matcher (`cvstereo bench` runs them all).
DEMO_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector", "stereobm")

#: The preset and matchers drawn in the demo's figures, and the window length of the frame pictures.
FIGURE_RECORDING = "1arm-50cm"
FIGURE_COMBOS = (("frame", "separate"), ("event-area", "gaussian"), ("stereobm", "default"))
FIGURE_WINDOW_US = 40_000


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = sub.add_parser(name, help="run the thesis' experiment on the built-in simulated recordings",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("-o", "--output", default="demo-output", help="folder for tables and figures (default: %(default)s)")
    p.add_argument("--seconds", type=float, default=None,
                   help="simulate only the first SECONDS of each preset (default: all 11 s, as the thesis)")
    p.add_argument("-m", "--methods", nargs="+", default=None, metavar="METHOD",
                   help="matchers to run (default: every available one)")
    p.add_argument("--shared", default=None,
                   help="shared data folder with data/tum-stereo (default: $CVSTEREO_SHARED or ../shared)")
    add_progress_option(p)
    return p


def shared_folder(arg: str | None) -> Path:
    """The shared data folder: the argument, else $CVSTEREO_SHARED, else ../shared (design.md)."""
    if arg:
        return Path(arg)
    if "CVSTEREO_SHARED" in os.environ:
        return Path(os.environ["CVSTEREO_SHARED"])
    return Path.cwd().parent / "shared"


def _real_recordings(shared: Path) -> None:
    from cvstereo.io import read_recording

    folder = shared / "data" / "tum-stereo"
    files = sorted(folder.glob("*.dat")) if folder.is_dir() else []
    if not files:
        print(f"(real TUM recordings not found under {folder}; skipped)")
        return
    print("Real stereo DVS128 recordings (TUM), left camera detected from the data:")
    for path in files:
        rec = read_recording(path)
        print(f"  {path.name:28s} left {rec.left.size:7,d}  right {rec.right.size:7,d} events, "
              f"{rec.duration_s:5.1f} s, left = retina {rec.meta.get('left_retina', '?')}")


def run(args: argparse.Namespace) -> int:
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"-o {out}: exists and is not a folder; the demo writes its tables and figures "
                                 "into a folder.")
    _real_recordings(shared_folder(args.shared))
    print()
    if importlib.util.find_spec("cvstereo.simulate") is None:
        print("The simulator has not landed yet: no simulated recordings to run the matchers on.")
        return 0
    from cvstereo.evaluate import to_json
    from cvstereo.experiment import all_combos, experiment_markdown, run_experiment
    from cvstereo.io import read_recording
    from cvstereo.io._atomic import write_text_atomic
    from cvstereo.registry import available_methods
    from cvstereo.simulate import cached_preset
    from cvstereo.thesis import RECORDINGS

    methods = args.methods or [m for m in available_methods() if m in DEMO_METHODS]
    if not methods:
        print("No matcher has landed yet: nothing to run on the simulated recordings.")
        return 0
    print("Simulating the thesis' six recordings (cached after the first run) ...", file=sys.stderr)
    progress = progress_wanted(args)
    recordings = {name: read_recording(cached_preset(name, seconds=args.seconds, progress=progress))
                  for name in RECORDINGS}
    # The thesis reproduction runs the thesis set; each method's adaptive default stands beside it.
    result = run_experiment(recordings, all_combos(methods, param_sets=("thesis", "adaptive")), progress=progress)
    text = experiment_markdown(result)
    print(text)
    out.mkdir(parents=True, exist_ok=True)  # only now: a stopped or failed demo leaves no empty folder
    write_text_atomic(out / "results.md", text + "\n")
    write_text_atomic(out / "results.json", to_json({c.label: rows for c, rows in result.figures.items()}, indent=2))
    print(f"\nTables written to {out / 'results.md'} and {out / 'results.json'}")
    _figures(recordings[FIGURE_RECORDING], [c for c in FIGURE_COMBOS if c[0] in methods], out / "figures")
    return 0


def _figures(recording, combos, folder: Path) -> None:
    """The thesis' figures for one preset and a few matchers (needs the viz extra; skipped without it)."""
    if importlib.util.find_spec("matplotlib") is None:
        print("(figures skipped: matplotlib is not installed; pip install 'cvstereo[viz]')")
        return
    from cvstereo import viz
    from cvstereo.pipeline import match

    folder.mkdir(parents=True, exist_ok=True)
    t0 = viz.busiest_window(recording, FIGURE_WINDOW_US)
    pictures = {
        "events.png": viz.plot_event_frames(recording, t0),
        "filtered.png": viz.plot_filtered_frames(recording, t0),
        "dynamic.png": viz.plot_dynamic_frames(recording, t0 + FIGURE_WINDOW_US),
    }
    depth = viz.depth_from_meta(recording.meta)
    # File names as `cvstereo plot all` writes them, one folder per matcher for the pictures of its matches.
    for method, variant in combos:
        result = match(recording, method=method, variant=variant)
        name = f"{method}-{variant}"
        (folder / name).mkdir(exist_ok=True)
        pictures[f"{name}/disparity-time.png"] = viz.plot_disparity_over_time(recording, result, depth=depth)
        pictures[f"{name}/disparity-map.png"] = viz.plot_disparity_map(recording, result, depth=depth)
        pictures[f"{name}/error-hist.png"] = viz.plot_error_histogram(recording, result)
    for file, fig in pictures.items():
        viz.save_figure(fig, folder / file)
    print(f"Figures of {FIGURE_RECORDING} written to {folder}/: {', '.join(pictures)}")
