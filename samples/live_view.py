"""Live disparity and distance from two eDVS128 boards (or two virtual boards playing a recording).

Opens both boards, synchronises their clocks, runs a matcher on the stream and prints a status line ten
times a second: median disparity, the distance it means (d = f*B/Z - c with the rig's numbers), events
per second of each sensor, and how far behind real time it runs. Stop with Ctrl-C.

Run:
    python samples/live_view.py --left /dev/ttyUSB0 --right /dev/ttyUSB1
    python samples/live_view.py --simulate rec.npz --seconds 5     # no hardware: two virtual eDVS
"""

import argparse
import contextlib

from calibration_free import create_matcher
from cvstereo.geometry.rig import THESIS_RIG

#: The thesis rig's depth model (10 cm baseline, its focal length and axis offset; the simulator's rig too).
RIG = THESIS_RIG.depth_model()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--left", help="serial port of the left board")
    parser.add_argument("--right", help="serial port of the right board")
    parser.add_argument("--simulate", metavar="RECORDING", help="play this recording on two virtual boards")
    parser.add_argument("-m", "--method", default="event-time", help="matcher (default: event-time)")
    parser.add_argument("--seconds", type=float, default=None, help="stop after this long (default: Ctrl-C)")
    args = parser.parse_args(argv)
    if not args.simulate and not (args.left and args.right):
        parser.error("give --left and --right ports, or --simulate RECORDING")

    from cvstereo.sensors import StereoEDVS, VirtualClock, VirtualEDVS
    from cvstereo.sensors.live import run_live

    with contextlib.ExitStack() as stack:
        left, right = args.left, args.right
        if args.simulate:
            from cvstereo.io import read_recording

            rec = read_recording(args.simulate)
            # One clock and one scene start for both virtual boards, as two real boards after !ETM.
            clock = VirtualClock()
            left, right = (stack.enter_context(VirtualEDVS(ev, clock=clock, time_origin_us=rec.t_start))
                           for ev in (rec.left, rec.right))
        rig = stack.enter_context(StereoEDVS(left, right))
        rig.start()
        with contextlib.suppress(KeyboardInterrupt):
            stats = run_live(rig, create_matcher(args.method), depth=RIG, seconds=args.seconds)
        rig.stop()
    print(f"done: {stats.matches} matches from {sum(stats.events)} events")


if __name__ == "__main__":
    main()
