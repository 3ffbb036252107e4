"""``cvstereo simulate``: write a simulated stereo recording with per-event ground truth.

Simulate two DVS128 on the thesis' rig looking at a scene; write a recording .npz whose events carry their true
disparity. Deterministic for a seed.

Examples::

    cvstereo simulate --list-presets
    cvstereo simulate --preset 2arms-100cm -o 2arms-100cm.npz
    cvstereo simulate --scene arms --arms 1 --distance 0.8 --seconds 3 --seed 7 -o arm.npz
    cvstereo simulate --scene rotation --seconds 5 -o room.npz
    cvstereo simulate --scene motorcycle --seconds 2 -o moto.npz
    cvstereo simulate --scene fan --distance 1.5 --seconds 2 -o fan.npz
    cvstereo simulate --list-suites
    cvstereo simulate --suite robustness                 # fill the cache, print the paths
    cvstereo simulate --suite robustness -o suite/       # and copy each recording to suite/NAME.npz
    cvstereo simulate --suite generalization             # suite v2: six scene families, tuning and eval halves
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

from cvstereo.cli._common import add_progress_option, progress_wanted
from cvstereo.cli._subcommand import subcommand

__all__ = ["add_parser", "run"]

#: --distance default per scene that takes one (metres).
_DEFAULT_DISTANCE = {"arms": 0.5, "fan": 1.5}


def add_parser(subparsers, name: str) -> argparse.ArgumentParser:
    """Register the subcommand."""
    from cvstereo.simulate import SCENES

    p = subcommand(subparsers, name, "simulate a stereo pair of event cameras (recording with ground truth)", __doc__)
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--preset", metavar="NAME", help="one of the thesis' recordings (see --list-presets)")
    what.add_argument("--scene", choices=tuple(SCENES), help="a scene with your parameters")
    what.add_argument("--suite", metavar="NAME", help="every recording of a suite (see --list-suites), cached")
    what.add_argument("--list-presets", action="store_true", help="list the presets and exit")
    what.add_argument("--list-suites", action="store_true", help="list the suites and their recordings and exit")
    p.add_argument("-o", "--output", metavar="OUT",
                   help="recording to write (with --suite: a folder that receives NAME.npz per recording)")
    p.add_argument("--arms", type=int, choices=(1, 2), default=None, help="--scene arms: how many arms (default 1)")
    p.add_argument("--distance", type=float, default=None, metavar="METRES",
                   help="--scene arms or fan: distance from the rig (default 0.5 for arms, 1.5 for the fan)")
    p.add_argument("--seconds", type=float, default=None,
                   help="length (default: the preset's, 11 s; 2 s for --scene; the suite's for --suite)")
    p.add_argument("--seed", type=int, default=0, help="seed of textures, motion, mismatch, noise (default 0)")
    add_progress_option(p)
    p.set_defaults(_usage_error=p.error)  # missing options are usage errors (exit 2), found only in run()
    return p


def run(args: argparse.Namespace) -> int:
    """Run the subcommand; returns the exit code."""
    from cvstereo.simulate import MAX_SECONDS, PRESETS, SCENES, simulate, simulate_preset

    if args.list_presets:
        for name, preset in PRESETS.items():
            left, right = preset.thesis_events["left"], preset.thesis_events["right"]
            lo, hi = preset.thesis_disparity
            print(f"{name:12s} {preset.seconds:g} s; thesis: left {sum(left)} events, right {sum(right)}, "
                  f"disparity {lo:g}-{hi:g} px")
        return 0
    if args.list_suites:
        return _list_suites()
    if args.seconds is not None and not 0 < args.seconds <= MAX_SECONDS:
        raise ValueError(f"--seconds {args.seconds:g} is out of range: give 0 < seconds <= {MAX_SECONDS:g} "
                         "(the simulator keeps the whole recording in memory)")
    if args.suite:
        if args.arms is not None or args.distance is not None:
            args._usage_error("--arms and --distance belong to --scene; a suite sets its own")
        return _run_suite(args)
    if not args.output:
        args._usage_error("give the output file with -o OUT.npz")
    if args.scene not in ("arms", "fan") and args.distance is not None:
        args._usage_error("--distance belongs to --scene arms or --scene fan")
    if args.scene != "arms" and args.arms is not None:
        args._usage_error("--arms belongs to --scene arms")
    progress = progress_wanted(args)
    if args.preset:
        rec = simulate_preset(args.preset, seconds=args.seconds, seed=args.seed, progress=progress)
    else:
        params = {"seed": args.seed}
        if args.scene in _DEFAULT_DISTANCE:
            params["distance_m"] = _DEFAULT_DISTANCE[args.scene] if args.distance is None else args.distance
        if args.scene == "arms":
            params["arms"] = args.arms or 1
        scene = SCENES[args.scene](**params)
        rec = simulate(scene, seconds=2.0 if args.seconds is None else args.seconds, seed=args.seed,
                       progress=progress)

    from cvstereo.io.npz import write_recording_npz

    write_recording_npz(args.output, rec)
    counts = ", ".join(f"{cam} {getattr(rec, cam).size}" for cam in ("left", "right"))
    print(f"wrote {args.output}: {rec.duration_s:.2f} s, events {counts}", file=sys.stderr)
    return 0


def _value_text(value) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{k}={v}" for k, v in value.items())
    return "-" if value is None else str(value)


def _list_suites() -> int:
    from cvstereo.simulate.suite import SUITES, load_suite

    for name in SUITES:
        suite = load_suite(name)
        around = f" around {suite.base}" if suite.base else ""
        print(f"{name} (v{suite.version}): {len(suite.recordings)} recordings of {suite.seconds:g} s{around}; "
              f"{suite.description}")
        for rec in suite.recordings:
            w, h = rec.rig.resolution
            if hasattr(rec, "summary"):  # a suite of scene families: what each recording drew
                print(f"  {rec.name:24s} {rec.summary()}")
            else:
                print(f"  {rec.name:22s} {rec.factor:16s} {_value_text(rec.value)}  [{w}x{h}]")
    return 0


def _run_suite(args: argparse.Namespace) -> int:
    from cvstereo.io.npz import read_recording_npz
    from cvstereo.simulate.suite import suite_recordings

    folder = Path(args.output) if args.output else None
    if folder is not None and folder.exists() and not folder.is_dir():
        raise ValueError(f"-o {folder}: with --suite the output is a folder, and this is a file")

    def report(rec, path, took):
        print(f"generated {rec.name} in {took:.1f} s", file=sys.stderr)

    start = time.perf_counter()
    paths = suite_recordings(args.suite, seconds=args.seconds, progress=progress_wanted(args), on_generate=report)
    total = time.perf_counter() - start
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    for name, path in paths:
        rec = read_recording_npz(path)
        label = rec.meta["suite"]
        w, h = rec.resolution
        target = path
        if folder is not None:
            target = folder / f"{name}.npz"
            shutil.copyfile(path, target)
        kind, value = ((label["factor"], label["value"]) if "factor" in label else
                       (f"{label['family']} {label['half']}", ", ".join(label["photos"])))
        print(f"{name:22s} {kind:16s} {_value_text(value):40s} {w}x{h} "
              f"{rec.left.size:>8d} {rec.right.size:>8d}  {target}")
    print(f"suite {args.suite}: {len(paths)} recordings ready in {total:.1f} s", file=sys.stderr)
    return 0
