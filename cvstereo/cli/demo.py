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
from cvstereo.cli._subcommand import subcommand

__all__ = ["DEMO_METHODS", "FIGURE_COMBOS", "FIGURE_FOLDER", "FIGURE_RECORDING", "FIGURE_WINDOW_US", "TABLE_FILES",
           "add_parser", "run", "shared_folder"]

#: Matchers the demo runs: the thesis' five and OpenCV's block matcher (`cvstereo bench` runs them all).
DEMO_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector", "stereobm")

#: The preset and matchers drawn in the demo's figures, and the window length of the frame pictures.
FIGURE_RECORDING = "1arm-50cm"
FIGURE_COMBOS = (("frame", "separate"), ("event-area", "gaussian"), ("stereobm", "default"))
FIGURE_WINDOW_US = 40_000

#: What the demo writes into its folder: the tables, and the figures in a folder of their own.
TABLE_FILES = ("results.md", "results.json")
FIGURE_FOLDER = "figures"


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "run the thesis' experiment on the built-in simulated recordings",
                   __doc__)
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
    """The shared data folder: the argument, else $CVSTEREO_SHARED, else ../shared (docs/design.md)."""
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
    from cvstereo.io.output_plan import ANY_FILE, OutputPlan

    out = Path(args.output)
    plan = OutputPlan()
    plan.write_folder(out, TABLE_FILES, ANY_FILE)  # a file named like the folder is refused before the long run
    if importlib.util.find_spec("cvstereo.simulate") is None:
        _real_recordings(shared_folder(args.shared))
        print("\nThe simulator has not landed yet: no simulated recordings to run the matchers on.")
        return 0
    from cvstereo.matchers.registry import available_methods

    methods = args.methods or [m for m in available_methods() if m in DEMO_METHODS]
    if not methods:
        print("No matcher has landed yet: nothing to run on the simulated recordings.")
        return 0
    combos = [c for c in FIGURE_COMBOS if c[0] in methods]
    figures = importlib.util.find_spec("matplotlib") is not None
    if figures:
        plan.write_folder(out / FIGURE_FOLDER, _figure_names(combos), ANY_FILE)
    with plan:  # the folder checked first; tables and figures published together once all are made
        _real_recordings(shared_folder(args.shared))
        print()
        _experiment(args, methods, out, combos if figures else None)
    print(f"\nTables written to {out / TABLE_FILES[0]} and {out / TABLE_FILES[1]}")
    if figures:
        print(f"Figures of {FIGURE_RECORDING} written to {out / FIGURE_FOLDER}/: {', '.join(_figure_names(combos))}")
    else:
        print("(figures skipped: matplotlib is not installed; pip install 'cvstereo[viz]')")
    return 0


def _experiment(args: argparse.Namespace, methods: list[str], out: Path, combos) -> None:
    """Simulate the six presets (cached), run every variant of ``methods`` and write the tables; the figures of
    ``combos`` too (None: none)."""
    from cvstereo.evaluation.experiment import all_combos, experiment_markdown, run_experiment
    from cvstereo.evaluation.metrics import to_json
    from cvstereo.evaluation.thesis import RECORDINGS
    from cvstereo.io import read_recording
    from cvstereo.io.atomic import write_text_atomic
    from cvstereo.simulate import cached_preset

    print("Simulating the thesis' six recordings (cached after the first run) ...", file=sys.stderr)
    progress = progress_wanted(args)
    recordings = {name: read_recording(cached_preset(name, seconds=args.seconds, progress=progress))
                  for name in RECORDINGS}
    # The thesis reproduction runs the thesis set; each method's adaptive default stands beside it.
    result = run_experiment(recordings, all_combos(methods, param_sets=("thesis", "adaptive")), progress=progress)
    text = experiment_markdown(result)
    print(text)
    write_text_atomic(out / TABLE_FILES[0], text + "\n")
    write_text_atomic(out / TABLE_FILES[1], to_json({c.label: rows for c, rows in result.figures.items()}, indent=2))
    if combos is not None:
        _figures(recordings[FIGURE_RECORDING], combos, out / FIGURE_FOLDER)


def _figure_names(combos) -> list[str]:
    """The files :func:`_figures` writes, under the figures folder."""
    names = ["events.png", "filtered.png", "dynamic.png"]
    for method, variant in combos:
        names += [f"{method}-{variant}/{kind}.png" for kind in ("disparity-time", "disparity-map", "error-hist")]
    return names


def _figures(recording, combos, folder: Path) -> None:
    """The thesis' figures for one preset and a few matchers (:func:`_figure_names`; needs the viz extra)."""
    from cvstereo import viz
    from cvstereo.run import match

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
        pictures[f"{name}/disparity-time.png"] = viz.plot_disparity_over_time(recording, result, depth=depth)
        pictures[f"{name}/disparity-map.png"] = viz.plot_disparity_map(recording, result, depth=depth)
        pictures[f"{name}/error-hist.png"] = viz.plot_error_histogram(recording, result)
    for file, fig in pictures.items():
        viz.save_figure(fig, folder / file)
