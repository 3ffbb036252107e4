"""Write an MP4 of a recording with its disparities colour-coded, one frame per 40 ms window.

Left and right events (ON blue, OFF orange) beside the matcher's disparities at the pixels it anchored on,
with time, median disparity and the distance it means on top.

Run:
    python samples/disparity_video.py                          # simulated 2 s of 1arm-50cm, event-area
    python samples/disparity_video.py rec.npz -m frame -o out.mp4
    python samples/disparity_video.py left.h5 right.h5 -o out.mp4   # one file per camera (DSEC, eDVS text)
"""

import argparse

from calibration_free import match
from cvstereo.geometry.rig import THESIS_RIG
from cvstereo.io import read_recording
from cvstereo.viz import write_video

#: The thesis rig's depth model (10 cm baseline, its focal length and axis offset; the simulator's rig too).
RIG = THESIS_RIG.depth_model()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", nargs="?", help="recording file, or the left camera's (default: a simulated clip)")
    parser.add_argument("right", nargs="?", help="the right camera's file, for formats with one file per camera")
    parser.add_argument("-m", "--method", default="event-area", help="matcher (default: event-area)")
    parser.add_argument("-o", "--output", default="disparity.mp4", help="video to write")
    args = parser.parse_args(argv)

    if args.recording:
        recording = read_recording(args.recording, args.right)
    else:
        from cvstereo.simulate import simulate_preset

        recording = simulate_preset("1arm-50cm", seconds=2.0)
    result = match(recording, method=args.method)
    frames = write_video(recording, args.output, result, depth=RIG)
    print(f"wrote {args.output}: {frames} frames, {len(result)} matches")


if __name__ == "__main__":
    main()
