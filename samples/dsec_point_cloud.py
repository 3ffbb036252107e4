"""A point cloud from a DSEC sequence: rectify with its calibration, run a matcher, write PLY.

Reads a time slice of both event cameras of a DSEC-style sequence (``events/left/events.h5``,
``events/right/events.h5``, ``calibration/cam_to_cam.yaml``; the `hdf5` extra), rectifies the events with the
calibration, runs a matcher and writes the matches with a distance as a binary PLY point cloud (the `pointcloud`
extra) in the rectified left camera's frame, metres. Prints how many points, and their median distance.

Run:
    python samples/dsec_point_cloud.py zurich_city_04_a -o cloud.ply              # first second, sgbm
    python samples/dsec_point_cloud.py SEQ --start-s 10 --seconds 0.5 -m event-time
    python samples/dsec_point_cloud.py l.h5 r.h5 --calibration cam_to_cam.yaml     # (or --left l.h5 --right r.h5)
    python samples/dsec_point_cloud.py SEQ --window-ms 50 -o cloud.ply   # cloud_<t_us>.ply per 50 ms window
"""

import argparse
from pathlib import Path

import numpy as np

from calibration_free import match
from cvstereo.geometry.calibration import load_calibration
from cvstereo.geometry.pointcloud import Intrinsics, point_cloud, window_point_clouds, write_ply
from cvstereo.geometry.rectify import Rectification
from cvstereo.io.hdf5 import dsec_time_range, read_time_slice
from cvstereo.model.recording import Recording


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("inputs", nargs="*", metavar="SEQUENCE | LEFT RIGHT",
                        help="a DSEC sequence folder (events/left, events/right, calibration), or the left and right "
                        "events.h5 (then give --calibration)")
    parser.add_argument("--left", help="the left events.h5, as an option")
    parser.add_argument("--right", help="the right events.h5, as an option")
    parser.add_argument("--calibration", help="cam_to_cam.yaml")
    parser.add_argument("-m", "--method", default="sgbm", help="matcher (default: sgbm)")
    parser.add_argument("--start-s", type=float, default=0.0, help="start, seconds after the first event")
    parser.add_argument("--seconds", type=float, default=1.0, help="length of the slice read (default 1 s)")
    parser.add_argument("--window-ms", type=float, default=None,
                        help="one cloud per window of this length (NAME_<start us>.ply) instead of one for the slice")
    parser.add_argument("-o", "--output", default="cloud.ply", help="PLY file to write")
    args = parser.parse_args(argv)
    if len(args.inputs) == 1 and not (args.left or args.right):
        seq = Path(args.inputs[0])
        left, right = seq / "events" / "left" / "events.h5", seq / "events" / "right" / "events.h5"
        calibration = Path(args.calibration) if args.calibration else seq / "calibration" / "cam_to_cam.yaml"
    else:
        rest = list(args.inputs)  # LEFT RIGHT, either of them possibly given as --left/--right instead
        left = args.left or (rest.pop(0) if rest else None)
        right = args.right or (rest.pop(0) if rest else None)
        if rest or not (left and right and args.calibration):
            parser.error("give a sequence folder, or the LEFT and RIGHT events.h5 (or --left, --right) and "
                         "--calibration")
        left, right, calibration = Path(left), Path(right), Path(args.calibration)

    cal = load_calibration(calibration)
    # The slice only: DSEC files are gigabytes. Both cameras on one clock, from the left camera's first event.
    span = dsec_time_range(left)
    if span is None:
        raise SystemExit(f"{left}: no events")
    t0 = span[0] + round(args.start_s * 1e6)
    t1 = t0 + round(args.seconds * 1e6)
    recording = Recording(read_time_slice(left, t0, t1), read_time_slice(right, t0, t1), resolution=cal.resolution,
                          meta={"source": [str(left), str(right)]})

    result = match(recording, method=args.method, rectification=Rectification(cal))
    model, intrinsics = cal.depth_model(), Intrinsics.from_options(cal.resolution, calibration=cal)
    points = point_cloud(result.matches, model, intrinsics)
    comments = (f"input {left} {right}", f"method {args.method}")
    if args.window_ms:
        window_us = round(args.window_ms * 1000)
        stem = args.output.removesuffix(".ply")
        anchor = result.meta["anchor"]
        for start, part in window_point_clouds(result.matches, model, intrinsics, window_us=window_us, anchor=anchor):
            write_ply(f"{stem}_{start}.ply", part, model=model, intrinsics=intrinsics,
                      comments=(*comments, f"window {start}..{start + window_us} us"))
    else:
        write_ply(args.output, points, model=model, intrinsics=intrinsics,
                  comments=(*comments, f"slice {t0}..{t1} us"))
    dropped = result.meta["rectification"]["dropped_events"]
    median = f"{float(np.median(points['z'])):.2f} m" if points.size else "-"
    print(f"{recording.left.size + recording.right.size} events ({dropped} off the rectified sensor), "
          f"{len(result)} matches, {points.size} points, median distance {median} -> {args.output}")


if __name__ == "__main__":
    main()
