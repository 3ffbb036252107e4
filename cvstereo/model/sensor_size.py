"""Sensor sizes: the default, the largest accepted, and the one check every resolution passes where it comes in.

>>> check_resolution((346, 260, 2))  # tonic's sensor_size
(346, 260)
"""

from __future__ import annotations

__all__ = ["DEFAULT_RESOLUTION", "MAX_RESOLUTION", "TONIC_POLARITIES", "check_resolution"]

#: Sensor size of the DVS128 / eDVS128, (width, height).
DEFAULT_RESOLUTION = (128, 128)

#: The largest sensor size accepted anywhere a resolution comes in (files, options, matchers), (width, height).
MAX_RESOLUTION = (2048, 2048)

#: The last item of tonic's ``sensor_size = (width, height, polarities)``: event cameras have two polarities.
TONIC_POLARITIES = 2


def check_resolution(resolution, *, source: str = "resolution", error: type[Exception] = ValueError) -> tuple[int, int]:
    """Return ``resolution`` as two ints, or raise unless it is a sensor size this library accepts.

    Width and height must be whole numbers with ``1 <= width <= MAX_RESOLUTION[0]`` and
    ``1 <= height <= MAX_RESOLUTION[1]``: every buffer a matcher or reader allocates is sized by it, so
    a size no sensor has (100000x100000 would ask for tens of GB) is refused where it comes in.
    tonic's ``sensor_size`` is accepted wherever a resolution is: a 3-tuple ``(width, height, 2)`` whose last
    item counts the polarities (any other third item is refused, as it is not a sensor size).

    Parameters
    ----------
    resolution : (width, height) or (width, height, 2)
    source : str, keyword-only
        What to name in the message (a file and key, an option).
    error : exception class, keyword-only
        Raised on a bad value (a ValueError subclass, e.g. CorruptFileError for a file's header).

    Examples
    --------
    >>> check_resolution((240, 180))
    (240, 180)
    >>> check_resolution((0, 0))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: resolution (0, 0): width and height must be whole numbers in 1..2048 ...
    """
    try:
        items = tuple(resolution)
    except TypeError:
        items = ()
    if len(items) == 3 and _whole(items[2]) and int(items[2]) == TONIC_POLARITIES:
        items = items[:2]
    ok = len(items) == 2 and all(_whole(v) for v in items)
    if ok:
        width, height = int(items[0]), int(items[1])
        ok = 1 <= width <= MAX_RESOLUTION[0] and 1 <= height <= MAX_RESOLUTION[1]
    if not ok:
        shown = resolution if isinstance(resolution, tuple | list) else repr(resolution)
        raise error(
            f"{source} {_short(shown)}: width and height must be whole numbers in 1..{MAX_RESOLUTION[0]} and "
            f"1..{MAX_RESOLUTION[1]} (the largest supported sensor is {MAX_RESOLUTION[0]}x{MAX_RESOLUTION[1]}); "
            f"give (width, height), or tonic's sensor_size (width, height, {TONIC_POLARITIES})."
        )
    return width, height


def _whole(value) -> bool:
    """Whether ``value`` is a number with a whole value (not a bool, which is no size)."""
    try:
        return not isinstance(value, bool) and float(value) == int(value)
    except (TypeError, ValueError, OverflowError):
        return False


def _short(value, limit: int = 60) -> str:
    text = str(tuple(value) if isinstance(value, list) else value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
