"""Event arrays as users have them, turned into cvstereo's event array (formats.md).

Event-camera code hands events around in several shapes: structured arrays with fields named ``t`` or
``timestamp``, ``p`` or ``polarity`` in any order (tonic's ``x, y, t, p``, dv-processing's ``timestamp, x, y,
polarity``), plain ``(N, 4)`` number arrays whose column order only the user knows (MVSEC stores
``x, y, t, p`` with ``t`` in seconds), and dv-processing ``EventStore`` objects. :func:`events_from` takes all
of them, so that ``match(left, right, method=...)`` works on what a user already has.

>>> import numpy as np
>>> rows = np.array([[10.0, 5.0, 0.000100, 1.0], [11.0, 5.0, 0.000250, -1.0]])
>>> events_from(rows, columns="xytp", time_unit="s")[["t", "x", "p"]].tolist()
[(100, 10, 1), (250, 11, 0)]
"""

from __future__ import annotations

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.events import DEFAULT_RESOLUTION, as_events

#: Other names of the four fields in common libraries (dv-processing, Prophesee/Metavision, ROS bags).
FIELD_ALIASES = {"timestamp": "t", "ts": "t", "time": "t", "polarity": "p", "pol": "p", "on": "p"}

#: Microseconds per unit of a time column.
TIME_UNITS = {"us": 1, "ms": 1_000, "s": 1_000_000, "ns": 1e-3}


def is_event_data(obj) -> bool:
    """Whether ``obj`` looks like events (an ndarray, or an object with a ``numpy()`` method such as
    dv-processing's EventStore) rather than a file name or a Recording."""
    return isinstance(obj, np.ndarray) or (callable(getattr(obj, "numpy", None)) and not isinstance(obj, str))


def events_from(data, *, columns: str | None = None, time_unit: str = "us",
                resolution: tuple[int, int] | None = DEFAULT_RESOLUTION, source: str = "events") -> np.ndarray:
    """Convert events in any common shape to a validated array of :data:`~cvstereo.events.EVENT_DTYPE`.

    Parameters
    ----------
    data : ndarray or EventStore
        A structured array (fields ``t``/``timestamp``, ``x``, ``y``, ``p``/``polarity``, any order and
        widths; ``p`` as bool, 0/1 or -1/+1), an ``(N, 4)`` number array (give ``columns``), or an object
        with a ``numpy()`` method returning such an array (dv-processing's ``EventStore``).
    columns : str, optional, keyword-only
        Column order of an ``(N, 4)`` array, a permutation of ``"txyp"`` (e.g. ``"xytp"`` for MVSEC).
        Required for plain arrays: a wrong guess would silently swap time and x.
    time_unit : {"us", "ms", "s", "ns"}, keyword-only
        Unit of the time column or field; times are rounded to whole microseconds.
    resolution : (width, height) or None, keyword-only
        Sensor size the coordinates must lie in.
    source : str, keyword-only
        Named in error messages.

    Returns
    -------
    (N,) ndarray of :data:`~cvstereo.events.EVENT_DTYPE`
        A new array, time-ordered as given.

    Raises
    ------
    EventFormatError
        A plain array without ``columns``, a bad column order, fields missing, non-integer coordinates,
        or any of :func:`~cvstereo.events.as_events`' checks.
    """
    if time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit '{time_unit}' is not one of {', '.join(TIME_UNITS)}.")
    if not isinstance(data, np.ndarray) and callable(getattr(data, "numpy", None)):
        data = data.numpy()
    arr = np.asarray(data)
    if arr.dtype.names is None:
        arr = _from_columns(arr, columns, source)
    else:
        if columns is not None:
            raise EventFormatError(f"{source}: columns= is for plain (N, 4) arrays; this one has named fields "
                                   f"{', '.join(arr.dtype.names)}.")
        arr = _renamed(arr, source)
    if time_unit != "us" or arr.dtype["t"].kind == "f":
        arr = _integral_times(arr, TIME_UNITS[time_unit], source)
    return as_events(arr, resolution=resolution, source=source)


def _renamed(arr: np.ndarray, source: str) -> np.ndarray:
    names = [FIELD_ALIASES.get(n, n) for n in arr.dtype.names]
    dup = sorted({n for n in names if names.count(n) > 1 and n in "txyp"})
    if dup:
        raise EventFormatError(f"{source}: fields {', '.join(arr.dtype.names)} name {', '.join(dup)} twice.")
    out = arr.copy()
    out.dtype.names = names
    return out


def _from_columns(arr: np.ndarray, columns: str | None, source: str) -> np.ndarray:
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise EventFormatError(f"{source}: expected a structured event array or an (N, 4) array, got shape "
                               f"{arr.shape} and dtype {arr.dtype}.")
    if columns is None:
        raise EventFormatError(f"{source}: a plain (N, 4) array needs its column order, e.g. columns='txyp' or "
                               "columns='xytp' (MVSEC); it cannot be guessed safely.")
    if sorted(columns) != sorted("txyp"):
        raise EventFormatError(f"{source}: columns='{columns}' must be an order of the letters t, x, y, p.")
    out = np.empty(arr.shape[0], dtype=[("t", arr.dtype), ("x", arr.dtype), ("y", arr.dtype), ("p", arr.dtype)])
    for i, name in enumerate(columns):
        out[name] = arr[:, i]
    if arr.dtype.kind == "f":
        out = _integral(out, ("x", "y", "p"), source)
    return out


def _integral(arr: np.ndarray, fields, source: str) -> np.ndarray:
    """Float coordinate and polarity columns that hold whole numbers, as integers."""
    dtype = [(n, np.int64 if n in fields else arr.dtype[n]) for n in arr.dtype.names]
    out = np.empty(arr.shape, dtype=dtype)
    for n in arr.dtype.names:
        values = arr[n]
        if n in fields:
            bad = np.flatnonzero(~np.isfinite(values) | (values != np.round(values)))
            if bad.size:
                raise EventFormatError(f"{source}: field '{n}' at index {int(bad[0])} is {float(values[bad[0]]):g}, "
                                       "not a whole number.")
            values = values.astype(np.int64)
        out[n] = values
    return out


def _integral_times(arr: np.ndarray, us_per_unit: float, source: str) -> np.ndarray:
    t = arr["t"].astype(np.float64) * us_per_unit
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise EventFormatError(f"{source}: field 't' at index {int(bad[0])} is not a finite time.")
    dtype = [(n, np.int64 if n == "t" else arr.dtype[n]) for n in arr.dtype.names]
    out = np.empty(arr.shape, dtype=dtype)
    for n in arr.dtype.names:
        out[n] = np.rint(t).astype(np.int64) if n == "t" else arr[n]
    return out
