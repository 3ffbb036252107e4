"""``cvstereo sweep``: a grid of methods x variants x parameter values over recordings, on Dask.

Each cell is one match plus evaluation (:mod:`cvstereo.sweep`). Results: ``OUT/results.parquet`` (one row
per cell), ``OUT/summary.md`` (best parameters per method) and ``OUT/cells/`` (one file per finished
cell, so that an interrupted sweep resumes where it stopped).
"""

from __future__ import annotations

import argparse

from cvstereo.cli._common import add_progress_option, progress_wanted

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

examples:
  cvstereo sweep preset:1arm-100cm:2 --method event-area --param threshold=1.5,2.5 -o sweep-out
  cvstereo sweep --grid grid.toml --workers 2 -o sweep-out
  cvstereo sweep --grid grid.toml --scheduler tcp://10.0.0.5:8786 -o sweep-out   (an existing cluster)
"""


def add_parser(sub, name: str) -> argparse.ArgumentParser:
    p = sub.add_parser(
        name, help="run a grid of matchers and parameters over recordings (Dask), one table of figures",
        description="Run every combination of methods, variants and parameter values on every recording "
        "(match + evaluate per cell) on a Dask cluster: a local one with one worker per core by default, or "
        "an existing one (--scheduler). Results go to OUT/results.parquet and OUT/summary.md; finished cells "
        "are kept in OUT/cells/, so running the same command again resumes an interrupted sweep. "
        "Needs the sweep extra: pip install 'cvstereo[sweep]'.",
        epilog=GRID_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
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


def _param_values(method_names: list[str], items: list[str]) -> tuple:
    """``["k=v1,v2"]`` -> ``(("k", (v1, v2)),)`` with values typed by the first method that has ``k``."""
    from cvstereo.registry import matcher_class, parse_param_strings

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


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from cvstereo.io._atomic import write_text_atomic
    from cvstereo.sweep import Grid, read_grid_file, resolve_recordings, run_sweep, summary_markdown, write_table

    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers {args.workers}: give 0 (no Dask) or a positive number of workers.")
    progress = progress_wanted(args)
    grids, specs, options = [], list(args.recordings), {}
    if args.grid:
        grids, file_specs, options = read_grid_file(args.grid)
        specs = specs or file_specs
    if args.method:
        sets = tuple(args.param_set.split(",")) if args.param_set else (None,)
        grids.append(Grid(tuple(args.method), tuple(args.variant), _param_values(args.method, args.param), sets))
    elif args.param or args.variant:
        raise ValueError("--param and --variant need --method (or put them in a --grid file).")
    if not grids:
        raise ValueError("nothing to sweep: give --method (with --param values) or --grid GRID.toml.")
    if not specs:
        raise ValueError("no recordings: give files, globs, preset:NAME or suite:NAME (or `recordings` in the grid "
                         "file).")
    figure = args.figure or options.get("figure", "bad2")
    recordings = resolve_recordings(specs, progress=progress)
    cells = [c for g in grids for c in g.cells(recordings)]
    out = Path(args.output)
    result = run_sweep(cells, out, workers=args.workers, scheduler=args.scheduler, progress=progress)
    summary = summary_markdown(result.rows, figure=figure)
    write_table(result.rows, out / "results.parquet")
    write_text_atomic(out / "summary.md", summary)
    print(summary, end="")
    print(f"{len(cells)} cells: {result.computed} run now, {result.reused} from an earlier run, {result.failed} "
          f"failed; table {out / 'results.parquet'}")
    return 0
