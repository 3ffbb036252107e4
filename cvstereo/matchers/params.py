"""The vocabulary of matcher parameters shared across matchers, and old names kept as aliases.

Every matcher's parameters are one frozen dataclass (docs/formats.md); fields that mean the same in several
matchers have one name, defined here once:

``polarity``
    How ON and OFF events enter the frames: ``shared``, ``separate``, ``on``, ``off`` (:mod:`cvstereo.model.polarity`,
    which also fixes the frame slot of each polarity).
``kernel_size``, ``kernel_sigma``
    Odd side and standard deviation (px) of the Gaussian: the 5x5, sigma 1 filter of a window's frames
    (eq. 3.6), or the 3x3, sigma 1 update of the dynamic frames (eq. 3.8).
``max_disparity``
    The largest disparity searched, px (inclusive); every matcher searches ``0 .. max_disparity``, the OpenCV
    baselines ``min_disparity .. max_disparity``.
``max_cost``
    A match needs a cost (SAD, vector distance) below this: the initial minimum of Algorithms 3 and 4.
``anchor_camera``
    Where a frame matcher reports: the camera whose pixels carry the results (0 left, 1 right); the search
    itself is symmetric (frame-based cluster matcher).
``reference_camera``
    Which camera is scanned, event by event or pixel by pixel, for partners in the other; its events or
    pixels carry the results (event-time, frame-area; 1 = right, the thesis' eDVS1).

When a field is renamed its old name stays accepted (docs/formats.md), in ``--param``, as a Python keyword and in
stored meta: a parameter class lists ``aliases = {old: new}`` (or ``{old: Alias(new, convert)}`` where the
value changes too), and :class:`AliasedParams`, the metaclass of every parameter class, renames the keywords
before the dataclass sees them.

>>> from cvstereo.matchers.event_area.params import EventAreaParams
>>> EventAreaParams(max_sad=500.0).max_cost
500.0
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

__all__ = ["Alias", "AliasedParams", "aliases_of", "canonical_params"]


class Alias(NamedTuple):
    """An old parameter name: the field it became and, where the value changed too, how to convert it.

    ``convert(old_value, given)`` gets the other values given (by their new names).
    """

    name: str
    convert: Callable[[Any, dict], Any] | None = None


def aliases_of(cls: type) -> dict[str, Alias]:
    """Old name -> :class:`Alias` of a parameter class, its bases' included."""
    out: dict[str, Alias] = {}
    for klass in reversed(cls.__mro__):
        for old, new in vars(klass).get("aliases", {}).items():
            out[old] = new if isinstance(new, Alias) else Alias(new)
    return out


def canonical_params(cls: type, given: Mapping[str, Any]) -> dict[str, Any]:
    """``given`` with old names of ``cls``'s fields replaced by the current ones (values converted).

    Raises
    ------
    ValueError
        A field given under both its old and its new name.
    """
    out = dict(given)
    for old, alias in aliases_of(cls).items():
        if old not in out:
            continue
        value = out.pop(old)
        if alias.name in out:
            raise ValueError(f"{cls.__name__}: give '{alias.name}' or its old name '{old}', not both.")
        out[alias.name] = alias.convert(value, out) if alias.convert is not None else value
    return out


class AliasedParams(type):
    """Metaclass of the parameter dataclasses: keywords under an old name (``aliases``) become the new one."""

    def __call__(cls, *args, **kwargs):
        return super().__call__(*args, **canonical_params(cls, kwargs))
