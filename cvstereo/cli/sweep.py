"""``cvstereo sweep``: a grid of methods x variants x parameter values over recordings, on Dask.

Run every combination of methods, variants and parameter values on every recording (match + evaluate per cell) on a
Dask cluster: a local one with one worker per core by default, or an existing one (--scheduler). Results go to
OUT/results.parquet and OUT/summary.md; finished cells are kept in OUT/cells/, so running the same command again
resumes an interrupted sweep (Ctrl-C or SIGTERM stops the cluster and keeps the finished cells). Needs the sweep
extra: pip install 'cvstereo[sweep]'.

Each cell is one match plus evaluation (:mod:`cvstereo.sweep`): ``OUT/results.parquet`` holds one row per cell,
``OUT/summary.md`` the best parameters per method.
"""

from __future__ import annotations

import argparse
import sys

from cvstereo.cli._common import add_progress_option, progress_wanted
from cvstereo.cli._subcommand import subcommand

__all__ = ["GRID_EXAMPLE", "SHOWN_FAILURES", "add_parser", "run"]

GRID_EXAMPLE = """\
grid file example (TOML):
  recordings = ["preset:1arm-100cm:2", "recordings/*.npz"]
  figure = "bad2"

  [[grid]]
  methods = ["event-area"]
  variants = ["gaussian", "no-gaussian"]
  params = { threshold = [1.5, 2.5] }

  [[grid]]
  methods = ["frame"]
  variants = ["all"]
  param_sets = ["thesis", "adaptive"]

checked before any cell runs (refused in one line naming the file, key and value):
  recordings: regular files in a known format (no FIFO, device or folder), known presets and suites,
    preset lengths the simulator accepts
  grid file: only the keys above; methods, variants, param_sets and recordings are lists of names (never
    one string); params a table of lists of numbers, true/false or text; every value of every cell
    passes the matcher's own checks (type, range, choices), as -p values do
  -o: a folder or nothing yet (not a file, /dev/null or a FIFO); --figure a figure of the table
  a cell file in OUT/cells that is not a whole row of its cell is recomputed, and counted on stderr;
  a failing cell's reason is printed (the first 3, then a count) and kept in the error column

examples:
  cvstereo sweep preset:1arm-100cm:2 --method event-area --param threshold=1.5,2.5 -o sweep-out
  cvstereo sweep --grid grid.toml --workers 2 -o sweep-out
  cvstereo sweep --grid grid.toml --scheduler tcp://10.0.0.5:8786 -o sweep-out   (an existing cluster)
"""


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = subcommand(sub, name, "run a grid of matchers and parameters over recordings (Dask), one table of figures",
                   __doc__, epilog=GRID_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("recordings", nargs="*", metavar="RECORDING",
                   help="recording files, globs, preset:NAME[:SECONDS] or suite:NAME")
    p.add_argument("--grid", metavar="GRID.toml", default=None, help="grid file (see the example below)")
    p.add_argument("--method", "-m", action="append", default=[], help="method to sweep (repeatable)")
    p.add_argument("--variant", "-v", action="append", default=[],
                   help="variant (repeatable; 'all' for every variant; default: each method's default)")
    p.add_argument("--param", "-p", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="parameter values to try (repeatable)")
    p.add_argument("--param-set", default=None, metavar="SET[,SET]",
                   help="parameter set(s) of the thesis' matchers to run: thesis, adaptive or both "
                   "(thesis,adaptive); default: the default set")
    p.add_argument("--figure", default=None, help="figure the summary ranks by (default: bad2)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes (default: one per core; 0: run here without Dask)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    add_progress_option(p)
    return p


#: Failing cells whose reasons are printed; the rest are counted (every reason is in the table's error column).
SHOWN_FAILURES = 3


def _param_values(method_names: list[str], items: list[str]) -> tuple:
    """``["k=v1,v2"]`` -> ``(("k", (v1, v2)),)`` with values typed by the first method that has ``k``."""
    from cvstereo.matchers.registry import matcher_class, parse_param_strings

    out = []
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not text:
            raise ValueError(f"--param '{item}' is not KEY=V1,V2,...")
        owners = [m for m in method_names if key.strip() in matcher_class(m).Params.__dataclass_fields__]
        if not owners:
            raise ValueError(f"--param '{key}' is a parameter of none of the methods {', '.join(method_names)}; "
                             "see `cvstereo match --list-methods`.")
        cls = matcher_class(owners[0]).Params
        values = tuple(parse_param_strings(cls, [f"{key}={v}"])[key.strip()] for v in text.split(","))
        out.append((key.strip(), values))
    return tuple(out)


def _command_line_grid(args: argparse.Namespace):
    """The grid of ``--method``/``--variant``/``--param``/``--param-set``, or None without ``--method``."""
    from cvstereo.matchers.registry import matcher_class
    from cvstereo.matchers.sets import check_param_set
    from cvstereo.sweep import Grid

    if not args.method:
        if args.param or args.variant:
            raise ValueError("--param and --variant need --method (or put them in a --grid file).")
        return None
    for method in args.method:
        matcher_class(method)  # an unknown method is named before its parameters are looked up
    sets = tuple(args.param_set.split(",")) if args.param_set else (None,)
    for name in sets if args.param_set else ():
        try:
            check_param_set(name)
        except ValueError as exc:
            raise ValueError(f"--param-set {args.param_set}: {exc}") from None
    return Grid(tuple(args.method), tuple(args.variant), _param_values(args.method, args.param), sets,
                origin="--method/--param")


def _report_failures(rows: list[dict], table) -> None:
    """The first :data:`SHOWN_FAILURES` failing cells' reasons on stderr, then how many more failed."""
    from pathlib import Path

    from cvstereo.cli._text import printable

    failed = [r for r in rows if r["error"] is not None]
    for r in failed[:SHOWN_FAILURES]:
        config = f"{r['method']}/{r['variant']}" + (f" {r['params']}" if r["params"] != "{}" else "")
        print(printable(f"cvstereo sweep: warning: cell failed: {config} on {Path(r['recording']).name}: "
                        f"{r['error']}"), file=sys.stderr)
    if len(failed) > SHOWN_FAILURES:
        print(f"cvstereo sweep: warning: ... and {len(failed) - SHOWN_FAILURES} more failed cells; the error column "
              f"of {table} has every reason", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from cvstereo.io.atomic import write_text_atomic
    from cvstereo.sweep import (
        check_figure,
        check_output_folder,
        read_grid_file,
        resolve_recordings,
        run_sweep,
        summary_markdown,
        write_table,
    )
    from cvstereo.sweep.cells import CELLS

    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: give 0 (no Dask) or a positive number of workers.")
    out = Path(args.output)
    check_output_folder(out, what="-o")
    progress = progress_wanted(args)
    grids, specs, options = [], list(args.recordings), {}
    if args.grid:
        grids, file_specs, options = read_grid_file(args.grid)
        specs = specs or file_specs
    given = _command_line_grid(args)
    grids += [given] if given is not None else []
    if not grids:
        raise ValueError("nothing to sweep: give --method (with --param values) or --grid GRID.toml.")
    if not specs:
        raise ValueError("no recordings: give files, globs, preset:NAME or suite:NAME (or `recordings` in the grid "
                         "file).")
    figure = check_figure(args.figure, where="--figure") if args.figure else options.get("figure", "bad2")
    for grid in grids:
        grid.configs()  # every configuration checked before a recording is simulated or a cell runs
    recordings = resolve_recordings(specs, progress=progress)
    cells = [c for g in grids for c in g.cells(recordings)]
    result = run_sweep(cells, out, workers=args.workers, scheduler=args.scheduler, progress=progress,
                       log=lambda text: print(text, file=sys.stderr, flush=True))
    summary = summary_markdown(result.rows, figure=figure)
    table = out / "results.parquet"
    write_table(result.rows, table)
    write_text_atomic(out / "summary.md", summary)
    print(summary, end="")
    print(f"{len(cells)} cells: {result.computed} run now, {result.reused} from an earlier run, {result.failed} "
          f"failed; table {table}")
    if result.recomputed:
        print(f"cvstereo sweep: warning: {result.recomputed} cell file{'s' if result.recomputed > 1 else ''} in "
              f"{out / CELLS} held no whole row of its cell (cut short or edited) and "
              f"{'were' if result.recomputed > 1 else 'was'} recomputed", file=sys.stderr)
    _report_failures(result.rows, table)
    return 0
