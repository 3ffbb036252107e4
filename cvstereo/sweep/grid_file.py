"""Grid files: the TOML a sweep can be written in, read with every key's type checked.

TOML has no schema, so a hand-written file can hold what reads fine and means something else: ``methods =
"frame"`` iterated letter by letter, ``grid = [5]``, a misspelt key silently ignored. Each is refused here in
one line naming the file, the ``[[grid]]`` table, the key and what to write instead.
"""

from __future__ import annotations

import json
import os
import tomllib

from cvstereo.sweep.grid import Grid, toml_text

__all__ = ["BLOCK_KEYS", "FILE_KEYS", "read_grid_file"]

#: Keys of a grid file's top level, and of each of its ``[[grid]]`` tables.
FILE_KEYS = ("recordings", "figure", "grid")
BLOCK_KEYS = ("methods", "method", "variants", "params", "param_sets")

#: A parameter value in a grid file: one of these TOML types (tables, dates and nested lists are not values).
_SCALARS = (bool, int, float, str)


def read_grid_file(path: str | os.PathLike) -> tuple[list[Grid], list[str], dict]:
    """Read a TOML grid file, checking the type of every key.

    The file has optional top-level ``recordings`` (list of specs, see :func:`resolve_recordings`) and
    ``figure``, and one ``[[grid]]`` table per block of methods::

        recordings = ["preset:1arm-100cm:2", "data/*.npz"]
        figure = "bad2"

        [[grid]]
        methods = ["event-area", "event-vector"]
        variants = ["all"]
        params = { threshold = [1.5, 2.5] }

    A parameter's values are a list (one value may be written alone); ``method = "frame"`` stands for
    ``methods = ["frame"]``. The values themselves are checked against the matchers by :meth:`Grid.configs`.

    Returns
    -------
    grids : list of Grid
    recordings : list of str
    options : dict
        ``figure``, when given.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        No such file, a directory, or no regular file (a FIFO would block).
    ValueError
        Not UTF-8 TOML, an unknown key, or a key of the wrong type; the message names the file, table and key.
    """
    from cvstereo.io.files import require_regular_file
    from cvstereo.sweep.report import check_figure

    path = require_regular_file(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a TOML grid file (not UTF-8 text: byte {exc.start} is "
                         f"{exc.object[exc.start]:#04x}).") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not a valid TOML grid file: {exc}") from None
    _known_keys(data, FILE_KEYS, f"{path}", "a grid file has")
    blocks = data.get("grid")
    if blocks is None:
        raise ValueError(f"{path}: needs at least one [[grid]] table with `methods = [...]`.")
    if not isinstance(blocks, list) or not blocks or not all(isinstance(b, dict) for b in blocks):
        raise ValueError(f"{path}: `grid` must be one or more [[grid]] tables with `methods = [...]`, got "
                         f"grid = {toml_text(blocks)}.")
    grids = [_grid_block(block, f"{path} [[grid]] {i + 1}") for i, block in enumerate(blocks)]
    recordings = _text_list(data.get("recordings", []), "recordings", f"{path}")
    options = {}
    if "figure" in data:
        figure = data["figure"]
        if not isinstance(figure, str):
            raise ValueError(f"{path}: `figure` must be the name of a figure, got figure = {toml_text(figure)}.")
        options["figure"] = check_figure(figure, where=f"{path}: figure")
    return grids, recordings, options


def _grid_block(block: dict, where: str) -> Grid:
    """One ``[[grid]]`` table as a :class:`Grid` whose messages start with ``where``."""
    _known_keys(block, BLOCK_KEYS, where, "a [[grid]] table has")
    if "method" in block:
        if "methods" in block:
            raise ValueError(f"{where}: give `methods = [...]` or `method = \"...\"`, not both.")
        if not isinstance(block["method"], str):
            raise ValueError(f"{where}: `method` must be one method name, got method = {toml_text(block['method'])}.")
        methods = [block["method"]]
    elif "methods" in block:
        methods = _text_list(block["methods"], "methods", where)
    else:
        methods = []
    if not methods:
        raise ValueError(f"{where}: has no methods; write methods = [\"frame\", ...].")
    params = block.get("params", {})
    if not isinstance(params, dict):
        raise ValueError(f"{where}: `params` must be a table of parameter = [values], e.g. params = "
                         f"{{ threshold = [1.5, 2.5] }}; got params = {toml_text(params)}.")
    sets = _text_list(block.get("param_sets", []), "param_sets", where)
    return Grid(tuple(methods), tuple(_text_list(block.get("variants", []), "variants", where)),
                tuple((k, _values(k, v, where)) for k, v in params.items()), tuple(sets) or (None,), origin=where)


def _values(key: str, value, where: str) -> tuple:
    """A parameter's values: a list of scalars (a scalar alone is a list of one)."""
    values = value if isinstance(value, list) else [value]
    bad = next((v for v in values if not isinstance(v, _SCALARS)), None)
    if bad is not None:
        raise ValueError(f"{where}: params.{key} = {toml_text(value)}: each value must be a number, true/false or "
                         f"text, not {toml_text(bad)}.")
    if not values:
        raise ValueError(f"{where}: params.{key} = []: give at least one value.")
    return tuple(values)


def _text_list(value, key: str, where: str) -> list[str]:
    """``value`` if it is a list of non-empty strings; a string alone is refused (it would be read letter by
    letter), with the list to write instead."""
    if isinstance(value, str):
        raise ValueError(f"{where}: `{key}` must be a list, got the text {json.dumps(value)}; write "
                         f"{key} = [{json.dumps(value)}].")
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise ValueError(f"{where}: `{key}` must be a list of names, e.g. {key} = [\"...\"]; got "
                         f"{key} = {toml_text(value)}.")
    return list(value)


def _known_keys(table: dict, known: tuple[str, ...], where: str, what: str) -> None:
    unknown = [k for k in table if k not in known]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(map(json.dumps, unknown))}; {what} "
                         f"{', '.join(known)}.")

