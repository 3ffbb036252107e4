"""``cvstereo warm-up``: compile every matcher's kernels into numba's cache now, not at the first match."""

from __future__ import annotations

import argparse

from cvstereo.cli._subcommand import subcommand

__all__ = ["add_parser", "run"]


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    from cvstereo.warmup import PARAM_SETS

    p = subcommand(
        sub, name, "fill the compile cache, so that no later process compiles the matchers' kernels", __doc__,
        description="Run every available method (or those given) on a small built-in clip, with its default "
        f"variant under each parameter set ({', '.join(PARAM_SETS)}), so that numba compiles its kernels into "
        "its cache now: later processes load them instead of compiling at their first match. `make` runs it "
        "after installing. Kernels already cached are only loaded.",
    )
    p.add_argument("-m", "--method", action="append", default=None, metavar="METHOD",
                   help="only this method (repeatable); default: every available one")
    return p


def run(args: argparse.Namespace) -> int:
    from cvstereo.matchers.registry import available_methods
    from cvstereo.warmup import warm_up

    known = available_methods()
    unknown = [m for m in args.method or () if m not in known]
    if unknown:
        raise ValueError(f"--method {unknown[0]}: not available here; available: {', '.join(known)}.")

    def report(method: str, param_set: str, compile_s: float) -> None:
        what = f"compiled in {compile_s:.1f} s" if compile_s else "cached"
        print(f"{method} ({param_set}): {what}")

    total = warm_up(args.method, on_method=report)
    print(f"warm-up done: {total:.1f} s compiling" if total else "warm-up done: every kernel was cached already")
    return 0
