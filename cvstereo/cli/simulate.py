"""``cvstereo simulate``: write a simulated stereo recording with per-event ground truth.

Examples::

    cvstereo simulate --list-presets
    cvstereo simulate --preset 2arms-100cm -o 2arms-100cm.npz
    cvstereo simulate --scene arms --arms 1 --distance 0.8 --seconds 3 --seed 7 -o arm.npz
    cvstereo simulate --scene rotation --seconds 5 -o room.npz
    cvstereo simulate --scene motorcycle --seconds 2 -o moto.npz
"""

from __future__ import annotations

import argparse
import sys


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    """Register the subcommand."""
    p = subparsers.add_parser(
        name, help="simulate a stereo pair of event cameras (recording with ground truth)",
        description="Simulate two DVS128 on the thesis' rig looking at a scene; write a recording .npz whose "
                    "events carry their true disparity. Deterministic for a seed.",
    )
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--preset", metavar="NAME", help="one of the thesis' recordings (see --list-presets)")
    what.add_argument("--scene", choices=("arms", "rotation", "motorcycle"), help="a scene with your parameters")
    what.add_argument("--list-presets", action="store_true", help="list the presets and exit")
    p.add_argument("-o", "--output", metavar="OUT.npz", help="recording to write")
    p.add_argument("--arms", type=int, choices=(1, 2), default=None, help="--scene arms: how many arms (default 1)")
    p.add_argument("--distance", type=float, default=None, metavar="METRES",
                   help="--scene arms: distance of the arms from the rig (default 0.5)")
    p.add_argument("--seconds", type=float, default=None,
                   help="length (default: the preset's, 11 s; 2 s for --scene)")
    p.add_argument("--seed", type=int, default=0, help="seed of textures, motion, mismatch, noise (default 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(_usage_error=p.error)  # missing options are usage errors (exit 2), found only in run()
    return p


def run(args: argparse.Namespace) -> int:
    """Run the subcommand; returns the exit code."""
    from cvstereo.simulate import PRESETS, SCENES, simulate, simulate_preset

    if args.list_presets:
        for name, preset in PRESETS.items():
            left, right = preset.thesis_events["left"], preset.thesis_events["right"]
            lo, hi = preset.thesis_disparity
            print(f"{name:12s} {preset.seconds:g} s; thesis: left {sum(left)} events, right {sum(right)}, "
                  f"disparity {lo:g}-{hi:g} px")
        return 0
    if not args.output:
        args._usage_error("give the output file with -o OUT.npz")
    if args.scene != "arms" and (args.arms is not None or args.distance is not None):
        args._usage_error("--arms and --distance belong to --scene arms")
    progress = not args.no_progress
    if args.preset:
        rec = simulate_preset(args.preset, seconds=args.seconds, seed=args.seed, progress=progress)
    else:
        params = {"seed": args.seed}
        if args.scene == "arms":
            params.update(arms=args.arms or 1, distance_m=0.5 if args.distance is None else args.distance)
        scene = SCENES[args.scene](**params)
        rec = simulate(scene, seconds=2.0 if args.seconds is None else args.seconds, seed=args.seed,
                       progress=progress)

    from cvstereo.io.npz import write_recording_npz

    write_recording_npz(args.output, rec)
    counts = ", ".join(f"{cam} {getattr(rec, cam).size}" for cam in ("left", "right"))
    print(f"wrote {args.output}: {rec.duration_s:.2f} s, events {counts}", file=sys.stderr)
    return 0
