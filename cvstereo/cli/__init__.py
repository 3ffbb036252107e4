"""The ``cvstereo`` command line: one module per subcommand, each with ``add_parser`` and ``run``.

User errors (bad files, bad values, missing extras, unplugged sensors) print one line on stderr and exit
1; usage errors exit 2 (argparse); nothing prints a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

import cvstereo

#: Subcommand name -> module under cvstereo.cli that implements it.
COMMANDS: dict[str, str] = {
    "info": "info",
    "convert": "convert",
    "evaluate": "evaluate",
    "demo": "demo",
    "bench": "bench",
    "depth-fit": "depth_fit",
    "match": "match",
    "plot": "plot",
    "video": "video",
    "record": "record",
    "live": "live",
    "rigcheck": "rigcheck",
    "simulate": "simulate",
    "sweep": "sweep",
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="cvstereo",
        description="Depth from a pair of event cameras (DVS128 / eDVS128) without calibration.",
    )
    parser.add_argument("--version", action="version", version=f"cvstereo {cvstereo.__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module in COMMANDS.items():
        mod = importlib.import_module(f"cvstereo.cli.{module}")
        p = mod.add_parser(sub, name)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("cvstereo: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, ImportError, TimeoutError, RuntimeError) as exc:
        print(f"cvstereo {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 1


def _one_line(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return " ".join(text.split())
