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

from cvstereo.cli._common import add_matcher_options, matcher_overrides
from cvstereo.geometry.rig import THESIS_RIG
from cvstereo.sensors.session import add_rig_arguments, end_finished_streams, open_rig, stop_on_signals, streams_over

__all__ = ["WARM_UP_EVENTS", "WARM_UP_SPAN_US", "add_parser", "compile_before_streaming", "run"]


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
    return p


#: Synthetic events a copy of the matcher runs on before the boards stream, and their time span, us.
WARM_UP_EVENTS = 2_000
WARM_UP_SPAN_US = 100_000


def compile_before_streaming(matcher) -> None:
    """Run a copy of ``matcher`` on a few synthetic events (both cameras) before the boards stream, so that its
    compiled kernels are built or loaded from numba's cache then: otherwise the first packets wait for that
    and the readers' queues fill meanwhile. ``matcher`` itself is left untouched."""
    import copy

    import numpy as np

    from cvstereo.model.events import make_events

    rng = np.random.default_rng(0)
    width, height = matcher.resolution
    t = np.sort(rng.integers(0, WARM_UP_SPAN_US, WARM_UP_EVENTS))
    ev = make_events(t, rng.integers(0, width, t.size), rng.integers(0, height, t.size), rng.integers(0, 2, t.size))
    twin = copy.deepcopy(matcher)
    twin.feed(ev, ev, until=WARM_UP_SPAN_US)
    twin.flush()


def run(args: argparse.Namespace) -> int:
    from cvstereo.cli._common import parse_depth_option
    from cvstereo.geometry.depth import DepthModel
    from cvstereo.matchers.registry import create_matcher
    from cvstereo.sensors.live import run_live

    params = matcher_overrides(args)
    depth = (parse_depth_option(args.depth) if args.depth is not None else
             DepthModel.from_rig(focal_px=args.focal_px, baseline_m=args.baseline_m, offset_px=args.offset_px))
    from cvstereo.sensors.detect import ProtocolMismatchError

    with stop_on_signals() as stop, open_rig(args) as (rig, devices):
        stop.raise_if_set()  # stopped while the boards were opened: nothing to show
        # The cameras' own resolution (a DV stream states it; an eDVS is 128x128).
        matcher = create_matcher(args.method, args.variant, param_set=args.param_set, resolution=rig.resolution,
                                 **params)
        compile_before_streaming(matcher)
        rig.start()

        def done() -> bool:
            if any(isinstance(c.error, ProtocolMismatchError) for c in rig.cams):
                return True  # the protocol settings were refused: stop and say why
            end_finished_streams(rig, devices)
            # Done once both streams are over and matched: events the rig still holds are fed first.
            return streams_over(rig, devices) and not rig.pending

        try:
            stats = run_live(rig, matcher, depth=depth, seconds=args.seconds, stop=stop, done=done)
        except KeyboardInterrupt:
            stats = None
        rig.stop()
        status = rig.status()
    for cam in rig.cams:
        if isinstance(cam.error, ProtocolMismatchError):
            raise cam.error
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
