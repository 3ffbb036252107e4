"""Event arrays as users have them, turned into cvstereo's event array (docs/formats.md).

Event-camera code hands events around in several shapes: structured arrays with fields named ``t`` or
``timestamp``, ``p`` or ``polarity`` in any order (tonic's ``x, y, t, p``, dv-processing's ``timestamp, x, y,
polarity``), plain ``(N, 4)`` number arrays or lists of rows whose column order only the user knows (MVSEC
stores ``x, y, t, p`` with ``t`` in seconds), and dv-processing ``EventStore`` objects. :func:`events_from`
takes all of them, so that ``match(left, right, method=...)`` works on what a user already has.

>>> import numpy as np
>>> rows = np.array([[10.0, 5.0, 0.000100, 1.0], [11.0, 5.0, 0.000250, -1.0]])
>>> events_from(rows, columns="xytp", time_unit="s")[["t", "x", "p"]].tolist()
[(100, 10, 1), (250, 11, 0)]
"""

from __future__ import annotations

import os

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.model.columns import FIELD_LABELS, TIME_UNITS, times_to_us, whole_numbers
from cvstereo.model.events import DEFAULT_RESOLUTION, events_from_columns

__all__ = ["FIELD_ALIASES", "events_from", "is_event_data"]

#: Other names of the four fields in common libraries (dv-processing, Prophesee/Metavision, ROS bags).
FIELD_ALIASES = {"timestamp": "t", "ts": "t", "time": "t", "polarity": "p", "pol": "p", "on": "p"}

#: How the message for a plain array without ``columns`` spells the calls that read the common layouts right.
_COLUMN_EXAMPLES = "columns='txyp' for integer microseconds, or columns='xytp', time_unit='s' for MVSEC's rows"


def is_event_data(obj) -> bool:
    """Whether ``obj`` looks like events rather than a file name or a Recording: an ndarray, a list or tuple of
    rows (not of file names), or an object with a ``numpy()`` method such as dv-processing's EventStore."""
    if isinstance(obj, np.ndarray):
        return True
    if isinstance(obj, list | tuple):
        return not any(isinstance(item, str | bytes | os.PathLike) for item in obj)
    return callable(getattr(obj, "numpy", None)) and not isinstance(obj, str)


def events_from(data, *, columns: str | None = None, time_unit: str | None = None,
                resolution: tuple[int, int] | None = DEFAULT_RESOLUTION, source: str = "events") -> np.ndarray:
    """Convert events in any common shape to a validated array of :data:`~cvstereo.model.events.EVENT_DTYPE`.

    Every value is checked as given before it is cast: float times need their unit (a cast would read seconds
    as microseconds), times that do not fit int64 microseconds, coordinates beyond the sensor (as given: 65535
    is reported as 65535) and polarities other than 0/1, -1/+1 or bool are refused, naming the first.

    Parameters
    ----------
    data : ndarray, list of rows or EventStore
        A structured array (fields ``t``/``timestamp``, ``x``, ``y``, ``p``/``polarity``, any order and
        widths; ``p`` as bool, 0/1 or -1/+1), an ``(N, 4)`` number array or list of 4-number rows (give
        ``columns``), or an object with a ``numpy()`` method returning such an array (dv-processing's
        ``EventStore``).
    columns : str, optional, keyword-only
        Column order of an ``(N, 4)`` array, a permutation of ``"txyp"`` (e.g. ``"xytp"`` for MVSEC).
        Required for plain arrays: a wrong guess would silently swap time and x.
    time_unit : {"s", "ms", "us", "ns"}, optional, keyword-only
        Unit of the time column or field; times are rounded to whole microseconds. Required for float times
        (their unit cannot be told from the values); integer times default to microseconds.
    resolution : (width, height) or (width, height, 2), optional, keyword-only
        Sensor size the coordinates must lie in; tonic's ``sensor_size`` is accepted as it is.
    source : str, keyword-only
        Named in error messages.

    Returns
    -------
    (N,) ndarray of :data:`~cvstereo.model.events.EVENT_DTYPE`
        A new array, time-ordered as given.

    Raises
    ------
    EventFormatError
        A plain array without ``columns``, a bad column order, fields missing, float times without
        ``time_unit``, non-integer coordinates, or any of :func:`~cvstereo.model.events.events_from_columns`' checks.
    ValueError
        An unknown ``time_unit`` or a resolution no sensor has.
    """
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit '{time_unit}' is not one of {', '.join(TIME_UNITS)}.")
    if not isinstance(data, np.ndarray | list | tuple) and callable(getattr(data, "numpy", None)):
        data = data.numpy()
    arr = _as_array(data, source)
    if arr.dtype.names is None:
        found = _plain_columns(arr, columns, time_unit, source)
    else:
        if columns is not None:
            raise EventFormatError(f"{source}: columns= is for plain (N, 4) arrays; this one has named fields "
                                   f"{', '.join(arr.dtype.names)}.")
        found = _named_fields(arr, source)
    t = found["t"]
    if time_unit is None and t.dtype.kind == "f":
        first = f" (the first is {float(t[0]):g})" if t.size else ""
        raise EventFormatError(f"{source}: the times are floats{first}, and their unit cannot be told from them; "
                               "say it with time_unit='s' (seconds, as MVSEC), 'ms', 'us' or 'ns'.")
    t_us = times_to_us(t, time_unit or "us", label=FIELD_LABELS["t"], source=source)
    x, y, p = (whole_numbers(found[f], label=FIELD_LABELS[f], source=source) for f in "xyp")
    return events_from_columns(t_us, x, y, p, resolution=resolution, source=source)


def _as_array(data, source: str) -> np.ndarray:
    """``data`` as an ndarray; a list of rows of unequal length or of non-numbers is refused, not objectified."""
    if isinstance(data, np.ndarray):
        return data
    try:
        arr = np.asarray(data)
    except ValueError as exc:  # ragged rows
        raise EventFormatError(f"{source}: the rows do not form an (N, 4) array of numbers ({exc}).") from None
    if arr.dtype.kind not in "iufb" and arr.dtype.names is None:
        raise EventFormatError(f"{source}: expected events as numbers (an (N, 4) array or rows of 4 numbers), got "
                               f"dtype {arr.dtype} and shape {arr.shape}.")
    return arr


def _named_fields(arr: np.ndarray, source: str) -> dict[str, np.ndarray]:
    if arr.ndim != 1:
        raise EventFormatError(f"{source}: expected a 1-D event array, got shape {arr.shape}.")
    names = [FIELD_ALIASES.get(n, n) for n in arr.dtype.names]
    dup = sorted({n for n in names if names.count(n) > 1 and n in "txyp"})
    if dup:
        raise EventFormatError(f"{source}: fields {', '.join(arr.dtype.names)} name {', '.join(dup)} twice.")
    missing = [f for f in "txyp" if f not in names]
    if missing:
        raise EventFormatError(f"{source}: missing field(s) {', '.join(missing)}; an event array needs t, x, y, p "
                               f"(it has {', '.join(arr.dtype.names)}).")
    return {f: arr[arr.dtype.names[names.index(f)]] for f in "txyp"}


def _plain_columns(arr: np.ndarray, columns: str | None, time_unit: str | None, source: str) -> dict[str, np.ndarray]:
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise EventFormatError(f"{source}: expected a structured event array or an (N, 4) array, got shape "
                               f"{arr.shape} and dtype {arr.dtype}.")
    if columns is None:
        unit = "" if time_unit is not None else " and, for float times, their unit"
        raise EventFormatError(f"{source}: a plain (N, 4) array needs its column order{unit}, e.g. "
                               f"{_COLUMN_EXAMPLES}; they cannot be guessed safely.")
    if sorted(columns) != sorted("txyp"):
        raise EventFormatError(f"{source}: columns='{columns}' must be an order of the letters t, x, y, p.")
    return {name: arr[:, i] for i, name in enumerate(columns)}
