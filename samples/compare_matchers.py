"""Compare every matcher on one recording: the thesis' mean/std beside the error against ground truth.

Runs each matcher and variant that is installed (the thesis' five, OpenCV StereoBM/SGBM, dv-processing's
semi-dense matcher with the `compare` extra) on a recording and prints one table row per matcher.
Without a file it simulates two seconds of the thesis' "one arm at 100 cm" recording.

Run:
    python samples/compare_matchers.py                     # simulated 1arm-100cm clip
    python samples/compare_matchers.py my_recording.npz    # any recording cvstereo can read
    python samples/compare_matchers.py Fan_disp8.dat -m frame event-time
    python samples/compare_matchers.py left.h5 right.h5                  # one file per camera (DSEC, eDVS text)
"""

import argparse

from calibration_free import available_methods, match, matcher_class
from cvstereo.evaluation.metrics import evaluate, markdown_table
from cvstereo.io import read_recording

#: Length of the simulated clip when no file is given: long enough for every matcher to warm up.
CLIP_SECONDS = 2.0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", nargs="?", help="recording file, or the left camera's (default: a simulated clip)")
    parser.add_argument("right", nargs="?", help="the right camera's file, for formats with one file per camera")
    parser.add_argument("-m", "--methods", nargs="+", default=None, help="matchers to run (default: all installed)")
    args = parser.parse_args(argv)

    if args.recording:
        recording = read_recording(args.recording, args.right)
    else:
        from cvstereo.simulate import simulate_preset

        recording = simulate_preset("1arm-100cm", seconds=CLIP_SECONDS)

    rows = {}
    for method in args.methods or available_methods():
        for variant in matcher_class(method).variants:
            result = match(recording, method=method, variant=variant)
            rows[f"{method}/{variant}"] = evaluate(recording, result)
    columns = ["matches", "mean", "std", "events_per_s"]
    if recording.has_truth:
        columns += ["mae", "bad1", "false_rate", "coverage"]
    print(markdown_table(rows, columns=columns, label="matcher"))


if __name__ == "__main__":
    main()
