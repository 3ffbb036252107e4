"""``cvstereo live``: run a matcher on two live eDVS128 boards or DV cameras / streams (``--dv``), or --simulate, and
show disparity and distance.

Terminal output only: one line per 0.1 s with the median disparity, the distance it means for the rig
(d = a/Z - c with a = focal_px * baseline_m, c = offset_px), events per second of each sensor and the lag
behind real time. (No window: the headless OpenCV build has no highgui.)
"""

from __future__ import annotations

import argparse
import json
import sys

from cvstereo.cli._common import add_matcher_options, matcher_overrides, matcher_threads
from cvstereo.cli._rerun import add_rerun_option, rerun_target
from cvstereo.geometry.rig import THESIS_RIG
from cvstereo.sensors.session import add_rig_arguments, end_finished_streams, open_rig, stop_on_signals, streams_over

__all__ = ["add_parser", "run"]


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    p = subparsers.add_parser(name, help="match two live eDVS128 boards, DV cameras or streams (or --simulate) and "
                              "show depth", description=__doc__)
    add_rig_arguments(p)
    add_matcher_options(p)
    p.add_argument("--focal-px", type=float, default=THESIS_RIG.focal_px,
                   help=f"focal length in px (default {THESIS_RIG.focal_px:g}, the thesis rig's)")
    p.add_argument("--baseline-m", type=float, default=THESIS_RIG.baseline_m,
                   help=f"baseline in m (default {THESIS_RIG.baseline_m:g})")
    p.add_argument("--offset-px", type=float, default=THESIS_RIG.axis_offset_px,
                   help=f"axis offset c in px (default {THESIS_RIG.axis_offset_px:g})")
    p.add_argument("--depth", nargs="+", default=None, metavar="A C | MODEL.json",
                   help="d = A/Z - C fitted by `cvstereo depth-fit`, as two numbers or its -o file (overrides the "
                   "three rig options above)")
    add_rerun_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.cli._common import parse_depth_option
    from cvstereo.geometry.depth import DepthModel
    from cvstereo.matchers.registry import create_matcher
    from cvstereo.sensors.live import run_live
    from cvstereo.viz.rerun_log import rerun_stream

    rerun = rerun_target(args)
    plan = _output_plan(args, rerun)
    params = matcher_overrides(args)
    build = dict(param_set=args.param_set, threads=matcher_threads(args), **params)
    # Its kernels compiled or loaded (and its parameters checked) before the sensors are opened: the matcher built
    # below at the rig's resolution runs the same kernels, so the first packets do not wait for a compiler.
    create_matcher(args.method, args.variant, **build)
    depth = (parse_depth_option(args.depth) if args.depth is not None else
             DepthModel.from_rig(focal_px=args.focal_px, baseline_m=args.baseline_m, offset_px=args.offset_px))
    from cvstereo.sensors.detect import ProtocolMismatchError

    # The --rerun file is checked and a viewer started before the boards are opened; the file is published at the end.
    with stop_on_signals() as stop, plan, rerun_stream(rerun) as viewer, open_rig(args) as (rig, devices):
        stop.raise_if_set()  # stopped while the boards were opened: nothing to show
        # The cameras' own resolution (a DV stream states it; an eDVS is 128x128).
        matcher = create_matcher(args.method, args.variant, resolution=rig.resolution, **build)
        rig.start()

        def done() -> bool:
            if any(isinstance(c.error, ProtocolMismatchError) for c in rig.cams):
                return True  # the protocol settings were refused: stop and say why
            end_finished_streams(rig, devices)
            # Done once both streams are over and matched: events the rig still holds are fed first.
            return streams_over(rig, devices) and not rig.pending

        log = _rerun_log(args, viewer, matcher, depth)
        try:
            stats = run_live(rig, matcher, depth=depth, seconds=args.seconds, stop=stop, done=done, on_packet=log)
        except KeyboardInterrupt:
            stats = None
        rig.stop()
        status = rig.status()
    for cam in rig.cams:
        if isinstance(cam.error, ProtocolMismatchError):
            raise cam.error
    if log is not None:
        print(f"{log.packets} packets -> {rerun.path or 'the rerun viewer'}", file=sys.stderr)
    if stats is not None:
        s = stats.summary()
        print(f"behind real time: mean {s['lag_ms_mean']:.1f} ms, max {s['lag_ms_max']:.1f} ms; "
              f"{s['matches']} matches from {s['events_left']} + {s['events_right']} events; "
              f"{status['late_events']} late events dropped (left {status['late_events_by_camera'][0]}, right "
              f"{status['late_events_by_camera'][1]}: delivered behind the watermark after a camera silent for "
              f"{status['silent_wait_us'] / 1e3:g} ms stopped holding the other back)", file=sys.stderr)
        print(stats.lag.line(), file=sys.stderr)
        print(json.dumps({"summary": s, "status": status}, default=str), file=sys.stderr)
    return 0


def _output_plan(args: argparse.Namespace, rerun):
    """The files ``live`` reads (the ``--simulate`` recording, a ``--depth`` model) and the ``--rerun`` file it
    writes (:class:`~cvstereo.io.output_plan.OutputPlan`): the file may be neither of them."""
    from cvstereo.cli._common import depth_file
    from cvstereo.geometry.depth_file import WHAT
    from cvstereo.io.output_plan import RERUN_FILE, OutputPlan

    plan = OutputPlan()
    if rerun.path is None:
        return plan  # nothing written: the inputs are checked where they are opened, as without the option
    plan.read(args.simulate)
    plan.read(depth_file(args), what=WHAT)
    plan.write(rerun.path, RERUN_FILE, option="--rerun")
    return plan


def _rerun_log(args: argparse.Namespace, viewer, matcher, depth):
    """``--rerun``: each packet and its matches for the viewer (:class:`cvstereo.viz.rerun_log.LiveLog`), the 3D
    points with the rig's focal length; None without the option."""
    if viewer is None:
        return None
    from cvstereo.geometry.pointcloud import Intrinsics
    from cvstereo.viz.rerun_log import LiveLog

    return LiveLog(viewer, matcher, depth=depth, intrinsics=Intrinsics.from_options(matcher.resolution,
                                                                                   focal_px=args.focal_px))
