"""OpenCV StereoBM beside the thesis' frame-based matcher, on the same 40 ms windows.

Both see the same events cut into the same windows on the absolute clock; the script prints their
figures side by side and saves a picture of the same window's colour-coded disparities for each
(matplotlib: `viz` extra).

Run:
    python samples/stereobm_side_by_side.py                      # simulated 2 s of 2arms-100cm
    python samples/stereobm_side_by_side.py rec.npz -o bm_vs_frame.png
"""

import argparse

from calibration_free import match
from cvstereo.evaluation.metrics import evaluate, markdown_table
from cvstereo.io import read_recording

#: Window of the frame matchers (formats.md), used to pick the window to draw.
WINDOW_US = 40_000

#: The thesis' frame matcher (its best variant in tables 4.2-4.5) and OpenCV's block matcher with our defaults.
MATCHERS = {"frame (thesis 3.3, separate ON/OFF)": ("frame", "separate"), "OpenCV StereoBM": ("stereobm", None)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", nargs="?", help="recording file, or the left camera's (default: a simulated clip)")
    parser.add_argument("right", nargs="?", help="the right camera's file, for formats with one file per camera")
    parser.add_argument("-o", "--output", default="side_by_side.png",
                        help="picture name; one per matcher is written: NAME_frame.png, NAME_stereobm.png")
    args = parser.parse_args(argv)

    if args.recording:
        recording = read_recording(args.recording, args.right)
    else:
        from cvstereo.simulate import simulate_preset

        recording = simulate_preset("2arms-100cm", seconds=2.0)

    results = {name: match(recording, method=m, variant=v) for name, (m, v) in MATCHERS.items()}
    print(markdown_table({name: evaluate(recording, r) for name, r in results.items()},
                         columns=["matches", "mean", "std", "mae", "bad1", "coverage", "realtime_x"], label="matcher"))

    from cvstereo.viz import plot_disparity_map, save_figure

    # The same window for both: the one in the middle of the recording.
    t_end = (recording.t_start + recording.t_end) // 2 // WINDOW_US * WINDOW_US
    stem = args.output.removesuffix(".png")
    for (method, _), result in zip(MATCHERS.values(), results.values(), strict=True):
        path = f"{stem}_{method}.png"
        save_figure(plot_disparity_map(recording, result, t_end, n_windows=1), path)
        print(f"picture: {path}")

if __name__ == "__main__":
    main()
