"""``cvstereo live``: run a matcher on two live eDVS128 boards (or --simulate) and show disparity and distance.

Terminal output only: one line per 0.1 s with the median disparity, the distance it means for the rig
(d = a/Z - c with a = focal_px * baseline_m, c = offset_px), events per second of each sensor and the lag
behind real time. (No window: the headless OpenCV build has no highgui.)
"""

from __future__ import annotations

import argparse
import json
import sys

from cvstereo.sensors.session import add_rig_arguments, open_rig, stop_on_signals


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    p = subparsers.add_parser(name, help="match two live eDVS128 boards (or --simulate) and show depth",
                              description=__doc__)
    add_rig_arguments(p)
    p.add_argument("--method", required=True, help="matcher (see `cvstereo match --list-methods`)")
    p.add_argument("--variant", default=None, help="matcher variant (default: the method's first)")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE", help="matcher parameter")
    p.add_argument("--focal-px", type=float, default=160.0, help="focal length in px (default 160)")
    p.add_argument("--baseline-m", type=float, default=0.10, help="baseline in m (default 0.10)")
    p.add_argument("--offset-px", type=float, default=2.5, help="axis offset c in px (default 2.5)")
    p.add_argument("--depth", type=float, nargs=2, default=None, metavar=("A", "C"),
                   help="d = A/Z - C fitted by `cvstereo depth-fit` (overrides the three rig options above)")
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.depth import DepthModel
    from cvstereo.registry import available_methods, create_matcher, matcher_class, parse_param_strings
    from cvstereo.sensors.live import run_live

    try:
        cls = matcher_class(args.method)
    except ImportError:
        raise ValueError(f"method '{args.method}' is not available here; available: "
                         f"{', '.join(available_methods()) or 'none'}.") from None
    params = parse_param_strings(cls.Params, args.param)
    matcher = create_matcher(args.method, args.variant, **params)
    depth = (DepthModel(a=args.depth[0], c=args.depth[1]) if args.depth is not None else
             DepthModel.from_rig(focal_px=args.focal_px, baseline_m=args.baseline_m, offset_px=args.offset_px))
    with stop_on_signals() as stop, open_rig(args) as (rig, devices):
        rig.start()
        done = (lambda: all(d.done for d in devices) and all(c.silent for c in rig.cams)) if devices else None
        try:
            stats = run_live(rig, matcher, depth=depth, seconds=args.seconds, stop=stop, done=done)
        except KeyboardInterrupt:
            stats = None
        rig.stop()
        status = rig.status()
    if stats is not None:
        s = stats.summary()
        print(f"behind real time: mean {s['lag_ms_mean']:.1f} ms, max {s['lag_ms_max']:.1f} ms; "
              f"{s['matches']} matches from {s['events_left']} + {s['events_right']} events; "
              f"{status['late_events']} late events dropped", file=sys.stderr)
        print(json.dumps({"summary": s, "status": status}, default=str), file=sys.stderr)
    return 0
