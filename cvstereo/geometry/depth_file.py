"""The depth-model file: ``cvstereo depth-fit -o model.json`` writes it, ``--depth model.json`` reads it.

A JSON object::

    {"format": "cvstereo-depth-model", "version": 1, "model": "d = a/Z - c",
     "a": 16.1, "c": 2.9, "units": {"a": "px*m", "c": "px"},
     "points": [{"file": "arm50.npz", "distance_m": 0.5, "median_disparity_px": 29.0, "matches": 812}, ...]}

Only ``a`` is required (``c`` defaults to 0); ``points`` and any other keys are kept for the reader's
information, so files written before the format had a name (depth-fit's plain ``{"a", "c", "points"}``) load too.

>>> import tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "model.json")
>>> save_depth_model(path, DepthModel(a=16.1, c=2.9))
>>> load_depth_model(path)
DepthModel(a=16.1, c=2.9)
"""

from __future__ import annotations

import json
import math
import os

from cvstereo.geometry.depth import DepthModel
from cvstereo.io.atomic import write_text_atomic

__all__ = ["FORMAT", "VERSION", "WHAT", "load_depth_model", "save_depth_model"]

FORMAT = "cvstereo-depth-model"
VERSION = 1
#: What a depth-model file is, for a message about a missing one.
WHAT = "depth-model file (write one with `cvstereo depth-fit -o`)"


def save_depth_model(path: str | os.PathLike, model: DepthModel, *, points: list[dict] | None = None,
                     **extra) -> None:
    """Write a depth model as JSON (atomically).

    Parameters
    ----------
    path : path-like
    model : DepthModel
    points : list of dict, optional, keyword-only
        The measurements it was fitted to (file, distance_m, median_disparity_px, matches).
    **extra
        More JSON-serialisable keys (e.g. ``method``).
    """
    data = {"format": FORMAT, "version": VERSION, "model": "d = a/Z - c", **model.to_dict(),
            "units": {"a": "px*m", "c": "px"}, **extra}
    if points is not None:
        data["points"] = points
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def load_depth_model(path: str | os.PathLike) -> DepthModel:
    """Read a depth-model file.

    Raises
    ------
    FileNotFoundError
    ValueError
        Not JSON, another format, a newer version, or ``a`` / ``c`` missing or not finite numbers.
    """
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such {WHAT}.") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a depth-model file: not valid JSON ({exc}).") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a depth-model file: expected a JSON object with 'a' and 'c'.")
    if data.get("format", FORMAT) != FORMAT:
        raise ValueError(f"{path}: format '{data['format']}' is not '{FORMAT}'.")
    if int(data.get("version", VERSION)) > VERSION:
        raise ValueError(f"{path}: depth-model version {data['version']} is newer than this cvstereo reads "
                         f"({VERSION}); upgrade cvstereo.")
    values = {}
    for key, default in (("a", None), ("c", 0.0)):
        value = data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{path}: key '{key}' must be a finite number (d = a/Z - c), got {value!r}.")
        values[key] = float(value)
    return DepthModel(**values)
