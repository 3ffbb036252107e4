"""Raw event columns checked value by value before they are cast into the event dtype.

A cast hides what it cannot hold: int32 65541 becomes int16 5, uint16 65535 becomes -1, uint64 2**63 becomes
a negative time, a polarity of 256 becomes 0 in int8, float seconds become whole microseconds of 0 or 1, and
1e300 s becomes INT64_MIN. Readers and the array API therefore hand their columns, in whatever dtype the file
or the caller has them, to these checks first: an error names the value as stored (65535, never -1) and the
first index that holds it. Each check is one vectorised pass over a chunk, so files are checked as they are
streamed, never read whole to be checked.

>>> import numpy as np
>>> check_coordinates(np.array([3, 65535], np.uint16), np.array([0, 0], np.uint16), (640, 480), source="f.h5")
Traceback (most recent call last):
...
cvstereo.errors.EventFormatError: f.h5: field 'x' at index 1 is 65535, outside the 640x480 sensor (valid 0..639); ...
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from cvstereo.errors import EventFormatError

__all__ = ["FIELD_LABELS", "INT16_MAX", "INT64_MAX", "INT64_MIN", "TIME_UNITS", "check_coordinates", "check_polarity",
           "check_times", "first_bad", "labelled", "times_to_us", "whole_numbers"]

#: The range of the int64 microsecond times of the event dtype.
INT64_MIN, INT64_MAX = int(np.iinfo(np.int64).min), int(np.iinfo(np.int64).max)
#: The int16 coordinates of the event dtype hold 0..INT16_MAX (negative coordinates are refused everywhere).
INT16_MAX = int(np.iinfo(np.int16).max)

#: How a field is named in messages, unless a reader names its own dataset or column (``labels=``).
FIELD_LABELS = {f: f"field '{f}'" for f in ("t", "x", "y", "p")}

#: Microseconds per unit of a time column (exact fractions, so that integer times convert exactly).
TIME_UNITS = {"s": Fraction(1_000_000), "ms": Fraction(1_000), "us": Fraction(1), "ns": Fraction(1, 1_000)}

#: Float64 has no integer above this that is exact and below 2**63: times in float beyond it do not fit int64.
_FLOAT_INT64_LIMIT = float(2**63)


def first_bad(bad: np.ndarray) -> int | None:
    """Index of the first True in ``bad`` (a boolean mask), or None."""
    return int(np.argmax(bad)) if bad.any() else None


def labelled(labels: dict[str, str] | None) -> dict[str, str]:
    """:data:`FIELD_LABELS` with a reader's own names (e.g. ``{"x": "/events/x"}``) in place."""
    return FIELD_LABELS if not labels else {**FIELD_LABELS, **labels}


def _refuse(source: str, label: str, index: int, value, why: str) -> EventFormatError:
    return EventFormatError(f"{source}: {label} at index {index} is {value}{why}")


def _outside_range(values: np.ndarray, lo: int, hi: int) -> np.ndarray | None:
    """Mask of ``values`` outside ``lo..hi``, or None when the dtype cannot hold such a value (no pass)."""
    info = np.iinfo(values.dtype)
    below, above = info.min < lo, info.max > hi
    if below and above:
        return (values < lo) | (values > hi)
    if below:
        return values < lo
    if above:
        return values > hi
    return None


def whole_numbers(values: np.ndarray, *, label: str, source: str, index_offset: int = 0) -> np.ndarray:
    """Float ``values`` that hold whole numbers, as int64; integer and bool arrays are returned as they are.

    Coordinates and polarities stored as floats are accepted when every value is whole (their unit cannot be
    misread); NaN, infinities, fractions and values beyond int64 are refused, naming the first.

    Raises
    ------
    EventFormatError
    """
    if values.dtype.kind != "f":
        return values
    bad = ~np.isfinite(values) | (values != np.round(values)) | (np.abs(values) >= _FLOAT_INT64_LIMIT)
    i = first_bad(bad)
    if i is not None:
        raise _refuse(source, label, i + index_offset, f"{float(values[i]):g}", ", not a whole number.")
    return values.astype(np.int64)


def times_to_us(values: np.ndarray, unit: str, *, label: str, source: str, index_offset: int = 0) -> np.ndarray:
    """Times in ``unit`` (a key of :data:`TIME_UNITS`) as int64 microseconds, refusing what does not fit.

    Integer times are scaled exactly (nanoseconds rounded half up by integer division: float64 would lose
    the last digits of epoch nanoseconds); float times are scaled and rounded to the nearest microsecond.
    Nothing wraps: a time beyond int64 microseconds is an error, not INT64_MIN.

    Raises
    ------
    EventFormatError
        NaN or infinite times, or times beyond int64 microseconds, naming the first.

    Examples
    --------
    >>> times_to_us(np.array([0.5, 1.25]), "s", label="t", source="demo").tolist()
    [500000, 1250000]
    """
    k = TIME_UNITS[unit]
    kind = values.dtype.kind
    if kind in "iu" and k.denominator == 1:
        bound = INT64_MAX // k.numerator
        _raise_first(_outside_range(values, -bound, bound), values, source, label, index_offset,
                     ", beyond int64 microseconds.")
        as_int64 = values.astype(np.int64, copy=False)
        return as_int64 * k.numerator if k.numerator != 1 else as_int64
    if kind in "iu":
        whole, rest = np.divmod(values, k.denominator)
        return whole.astype(np.int64) + (rest >= (k.denominator + 1) // 2)
    if kind != "f":
        raise EventFormatError(f"{source}: {label} has dtype {values.dtype}; times must be numbers.")
    scaled = values.astype(np.float64) * float(k)
    bad = ~np.isfinite(scaled) | (np.abs(scaled) >= _FLOAT_INT64_LIMIT)
    i = first_bad(bad)
    if i is not None:
        why = ", not a finite time." if not np.isfinite(scaled[i]) else ", beyond int64 microseconds."
        raise _refuse(source, label, i + index_offset, f"{float(values[i]):g}", why)
    return np.rint(scaled).astype(np.int64)


def _raise_first(bad: np.ndarray | None, values: np.ndarray, source: str, label: str, index_offset: int,
                 why: str) -> None:
    i = None if bad is None else first_bad(bad)
    if i is not None:
        raise _refuse(source, label, i + index_offset, values[i].item(), why)


def check_times(t: np.ndarray, *, t_offset: int = 0, source: str, label: str = FIELD_LABELS["t"],
                index_offset: int = 0) -> None:
    """Raise unless every integer time plus ``t_offset`` fits the int64 microseconds of the event dtype.

    ``uint64`` times of 2**63 and above would become negative in a cast, and a file's time offset added to
    large relative times could wrap; the first such time is named as stored.
    """
    lo = INT64_MIN - t_offset if t_offset < 0 else INT64_MIN
    hi = INT64_MAX - t_offset if t_offset > 0 else INT64_MAX
    why = ", beyond int64 microseconds" + (f" once the time offset {t_offset} is added." if t_offset else ".")
    _raise_first(_outside_range(t, lo, hi), t, source, label, index_offset, why)


def check_coordinates(x: np.ndarray, y: np.ndarray, resolution: tuple[int, int] | None, *, source: str,
                      labels: dict[str, str] | None = None, index_offset: int = 0) -> None:
    """Raise naming the first event (and of it, x before y) whose coordinate is negative or off the sensor.

    Values are compared as stored, before any cast (so uint16 65535 is reported as 65535). Without a
    resolution, coordinates must still fit the event dtype's int16 (0..32767).
    """
    names = labelled(labels)
    firsts = []
    for k, (field, column) in enumerate((("x", x), ("y", y))):
        size = INT16_MAX + 1 if resolution is None else resolution[k]
        if column.dtype.kind == "i":
            # Read as unsigned, a negative value is beyond any sensor: one comparison tests both bounds (this runs
            # on every packet a matcher is fed and every chunk a reader reads, so it is kept to one pass).
            bad = column.view(column.dtype.str.replace("i", "u")) >= size
        else:
            bad = column >= size
        i = first_bad(bad)
        if i is not None:
            firsts.append((i, k, field, column))
    if not firsts:
        return
    i, k, field, column = min(firsts, key=lambda item: item[:2])
    value = column[i].item()
    if value < 0:
        raise _refuse(source, names[field], i + index_offset, value,
                      "; coordinates must be >= 0 (one-based files need the one-based option).")
    if resolution is None:
        raise _refuse(source, names[field], i + index_offset, value,
                      f", beyond the int16 coordinates (0..{INT16_MAX}).")
    raise _refuse(source, names[field], i + index_offset, value,
                  f", outside the {resolution[0]}x{resolution[1]} sensor (valid 0..{resolution[k] - 1}); give the "
                  "right resolution, or the one-based option if the file counts from 1.")


def check_polarity(p: np.ndarray, *, source: str, label: str = FIELD_LABELS["p"], index_offset: int = 0) -> None:
    """Raise unless every polarity is 1 (ON), 0 or -1 (OFF), or the array is bool; names the first as stored."""
    if p.dtype.kind == "b":
        return
    _raise_first(_outside_range(p, -1 if p.dtype.kind == "i" else 0, 1), p, source, label, index_offset,
                 "; polarity must be 1/0 or +1/-1.")
