"""``cvstereo bench``: every matcher on the same recordings; results.json and results.md.

Run every matcher and variant (and the OpenCV / dv-processing baselines where installed) on the thesis' six presets,
the motorcycle scene and the real TUM recordings when present; write results.json and results.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cvstereo.cli._common import add_progress_option, add_threads_option, matcher_threads, progress_wanted
from cvstereo.cli._subcommand import subcommand

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "benchmark every matcher: accuracy vs truth, thesis tables, speed, memory, distance",
                   __doc__)
    p.add_argument("-o", "--output", default="bench",
                   help="folder for results.json and results.md (default: %(default)s)")
    p.add_argument("--quick", action="store_true",
                   help="1.5 s clips of every recording: about a minute once the recordings are cached")
    p.add_argument("-m", "--methods", nargs="+", default=None, metavar="METHOD", help="matchers to run (default: all)")
    p.add_argument("--no-distance", action="store_true", help="skip the distance fit")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes for the accuracy cells (sweep engine, Dask; default: one per core; "
                   "0: in this process). Speed and memory are measured afterwards in this process, alone")
    p.add_argument("--shared", default=None,
                   help="shared data folder with data/tum-stereo (default: $CVSTEREO_SHARED or ../shared)")
    add_threads_option(p, default="1, every figure one core's; the accuracy cells run on one thread each")
    add_progress_option(p)
    return p


def run(args: argparse.Namespace) -> int:
    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: give 0 (in this process) or a positive number of workers.")
    threads = matcher_threads(args, default=1)
    import cv2

    from cvstereo.benchmark.harness import RESULT_FILES, BenchConfig, run_bench, write_results
    from cvstereo.cli.demo import shared_folder
    from cvstereo.io.output_plan import ANY_FILE, OutputPlan

    plan = OutputPlan()
    plan.write_folder(args.output, RESULT_FILES, ANY_FILE)

    # OpenCV's own work outside the matchers (which set it for themselves: --threads) stays on one core.
    cv2.setNumThreads(1)
    config = BenchConfig(quick=args.quick, methods=tuple(args.methods) if args.methods else None,
                         shared=shared_folder(args.shared), distance=not args.no_distance,
                         workers=args.workers, threads=threads)
    with plan:  # the folder checked before the long run; both files published together
        results = run_bench(config, progress=progress_wanted(args), log=lambda msg: print(msg, file=sys.stderr))
        json_path, md_path = write_results(results, Path(args.output))
    print(md_path.read_text())
    print(f"written: {json_path}, {md_path}", file=sys.stderr)
    return 0
