"""Declared parameter constraints, and the one validator that reads them.

Every matcher's parameters are one frozen dataclass (docs/formats.md). What a value may be is said once, beside
its field, with :func:`param` (``field(metadata=...)`` with a small vocabulary: bounds, odd, a pixel side, a value
that switches the step off, choices), and the field's annotated type says the rest: a ``float`` is a finite
number, an ``int`` a whole number a C int holds (:data:`MAX_PARAM_INT`; a whole float such as ``40000.0`` from
JSON or YAML becomes the int), a ``bool`` only ``True``/``False``, a ``Literal`` one of its values.

:func:`check_value` checks one value against its field and :func:`validate` a whole object: the same rules at
construction (the metaclass :class:`DeclaredParams` runs :func:`validate` on every parameter object built),
for ``--param`` strings and for a sweep's grid (:mod:`cvstereo.matchers.registry`). A rule between fields that
no declaration can say is a method ``check_rules(self)`` of the class, which :func:`validate` calls last.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True, kw_only=True)
... class Demo(metaclass=DeclaredParams):
...     threshold: float = param(1.2, gt=0, note="the thesis uses 1.2")
...     block: int = param(5, side=True)
>>> Demo(block=4)
Traceback (most recent call last):
...
ValueError: Demo: parameter 'block' must be a positive odd number of px, got 4.
>>> Demo(threshold=0.0)
Traceback (most recent call last):
...
ValueError: Demo: parameter 'threshold' must be > 0 (the thesis uses 1.2), got 0.0.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import typing
from dataclasses import dataclass
from typing import Any

from cvstereo.matchers.params import AliasedParams
from cvstereo.model.events import MAX_RESOLUTION

__all__ = ["MAX_EXTENT", "MAX_PARAM_INT", "Constraint", "DeclaredParams", "check_value", "constraint_of",
           "finite_number", "param", "validate", "whole_number"]

#: Largest magnitude of an integer parameter: a C int. Kernels, OpenCV and products of windows and counts
#: stay far from int64 overflow below it (a window of 2**31 us is 36 minutes).
MAX_PARAM_INT = 2**31 - 1

#: Largest side of a square filter or block in pixels (:func:`param` ``side=True``): a side beyond the largest
#: sensor is meaningless and would allocate side**2 values (99999: 75 GB).
MAX_EXTENT = max(MAX_RESOLUTION) - 1

#: The key of a field's metadata that holds its :class:`Constraint`.
_KEY = "cvstereo.constraint"


@dataclass(frozen=True)
class Constraint:
    """What a field's value may be, besides its type (the module docstring).

    Attributes
    ----------
    ge, gt, le, lt : number or None
        Bounds (``>=``, ``>``, ``<=``, ``<``).
    odd : bool
        An odd number.
    side : bool
        The side of a square filter or block in pixels: odd, at least 1, at most :data:`MAX_EXTENT`.
    off : number or None
        A value that switches the step off and is allowed besides the bounds (``-1``).
    choices : tuple
        The allowed values, where the type does not list them.
    note : str
        What the message adds in brackets (a typical value, what an edge value means).
    """

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    odd: bool = False
    side: bool = False
    off: float | None = None
    choices: tuple = ()
    note: str = ""

    def allows(self, value) -> bool:
        """Whether ``value`` (already of the field's type) keeps the declaration."""
        if self.off is not None and value == self.off:
            return True
        if self.choices:
            return value in self.choices
        return all((
            self.ge is None or value >= self.ge, self.gt is None or value > self.gt,
            self.le is None or value <= self.le, self.lt is None or value < self.lt,
            not (self.odd or self.side) or value % 2 == 1,
        ))

    def describe(self, integer: bool) -> str:
        """The rule in words, as a message says it after "must be"."""
        if self.choices:
            text = f"one of {', '.join(map(str, self.choices))}"
        else:
            lo = f"> {self.gt}" if self.gt is not None else f">= {self.ge}" if self.ge is not None else ""
            hi = f"< {self.lt}" if self.lt is not None else f"<= {self.le}" if self.le is not None else ""
            if integer and self.ge is not None and self.le is not None:
                text = f"in {self.ge}..{self.le}"
            elif lo and hi:
                low, high = lo.split(" ", 1)[1], hi.split(" ", 1)[1]
                text = f"in {'(' if self.gt is not None else '['}{low}, {high}{')' if self.lt is not None else ']'}"
            else:
                text = lo or hi
            kind = "an odd number" if self.odd or self.side else "a whole number" if integer else ""
            text = " ".join(part for part in (kind, text) if part)
        if self.off is not None:
            text = f"{self.off} (off) or {text}"
        return f"{text} ({self.note})" if self.note else text


def param(default, *, ge=None, gt=None, le=None, lt=None, odd: bool = False, side: bool = False, off=None,
          choices: tuple = (), note: str = ""):
    """A dataclass field with its default and its :class:`Constraint` (keywords as its attributes).

    Bounds on a ``side`` field narrow its range (StereoBM's block: ``side=True, ge=5, le=255``).
    """
    check = Constraint(ge=ge, gt=gt, le=le, lt=lt, odd=odd, side=side, off=off, choices=tuple(choices), note=note)
    return dataclasses.field(default=default, metadata={_KEY: check})


def constraint_of(field: dataclasses.Field) -> Constraint | None:
    """The declared :class:`Constraint` of a dataclass field, or None (a field without one: its type alone)."""
    return field.metadata.get(_KEY)


def check_value(params_cls: type, name: str, value, *, where: str = "parameter", given_as: str | None = None) -> Any:
    """Return ``value`` checked against the field ``name`` of ``params_cls``: its type, then its declaration.

    The one rule of every matcher's parameters, at construction, in ``--param`` and in a sweep's grid: floats
    finite (a NaN threshold compares false with everything and silently disables a test), ints whole and of at
    most :data:`MAX_PARAM_INT` in magnitude (a larger window overflows the kernels' int64 clock arithmetic),
    bools only ``True``/``False``, text only text, a ``Literal`` one of its values, and then the bounds, odd,
    side and choices :func:`param` declared.

    Parameters
    ----------
    params_cls : type
        A parameter dataclass (any: a plugin's without declarations gets the type rules).
    name : str
        The field (its current name).
    value
        The value given.
    where : str, keyword-only
        How the message names the source ("parameter", "--param", "FrameAreaParams: parameter").
    given_as : str, keyword-only
        The name the value was given under, if an old one (:mod:`cvstereo.matchers.params`): the message uses it.

    Returns
    -------
    The value (an int for int fields).

    Raises
    ------
    ValueError
        Naming ``where`` and the field, the rule and the value.
    """
    hint, check = _fields(params_cls)[name]
    choices = typing.get_args(hint) if typing.get_origin(hint) is typing.Literal else ()
    kind = type(choices[0]) if choices else hint
    label = f"{where} '{given_as or name}'"
    if kind is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{label} must be true or false, got {_shown(value)}.")
    elif kind is float:
        value = finite_number(label, value)
    elif kind is int:
        value = whole_number(label, value)
    elif kind is str and not isinstance(value, str):
        raise ValueError(f"{label} must be text, got {_shown(value)}.")
    if choices and value not in choices:
        note = f" ({check.note})" if check is not None and check.note else ""
        raise ValueError(f"{label} must be one of {', '.join(map(str, choices))}{note}, got {value!r}.")
    if check is not None:
        if check.side and value > MAX_EXTENT:
            raise ValueError(f"{label} must be at most {MAX_EXTENT} px (the largest sensor's side), got {value}.")
        if not check.allows(value) or (check.side and value < 1):
            rule = check.describe(kind is int)
            if check.side and check.ge is None:
                rule = "a positive odd number of px" + (f" ({check.note})" if check.note else "")
            raise ValueError(f"{label} must be {rule}, got {_shown(value)}.")
    return value


def validate(params) -> None:
    """Check every field of a parameter object (:func:`check_value`), then its ``check_rules()`` if it has one.

    Whole floats in int fields are replaced by the int (a frozen object: set as its constructor would).

    Raises
    ------
    ValueError
        The first field, or the first rule between fields, that the object breaks, naming its class.
    """
    cls = type(params)
    where = f"{cls.__name__}: parameter"
    for name in _fields(cls):
        value = getattr(params, name)
        checked = check_value(cls, name, value, where=where)
        if checked is not value:
            object.__setattr__(params, name, checked)
    rules = getattr(params, "check_rules", None)
    if rules is not None:
        rules()


class DeclaredParams(AliasedParams):
    """Metaclass of the parameter dataclasses: old keyword names accepted (:class:`AliasedParams`), and every
    object built validated once (:func:`validate`), whichever way it is built (``Params(...)``,
    ``dataclasses.replace``, :meth:`~cvstereo.matchers.protocol.StreamMatcher.make_params`)."""

    def __call__(cls, *args, **kwargs):
        params = super().__call__(*args, **kwargs)
        validate(params)
        return params


@functools.cache
def _fields(params_cls: type) -> dict[str, tuple[Any, Constraint | None]]:
    """Field name -> (annotated type, declared constraint) of a parameter dataclass, in field order."""
    hints = typing.get_type_hints(params_cls)
    return {f.name: (hints[f.name], constraint_of(f)) for f in dataclasses.fields(params_cls)}


def finite_number(label: str, value) -> float:
    """``value`` if it is a finite real number (not a bool); ValueError starting with ``label`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{label} must be a number, got {_shown(value)}.")
    try:
        finite = math.isfinite(value)
    except OverflowError:  # an int beyond any float
        finite = False
    if not finite:
        raise ValueError(f"{label} must be a finite number, got {_shown(value)}.")
    return value


def whole_number(label: str, value) -> int:
    """``value`` as an int if it is a whole number a C int holds (a whole float too, not a bool); ValueError
    starting with ``label`` otherwise."""
    if isinstance(value, bool):
        raise ValueError(f"{label} must be an integer, got {value}.")
    if isinstance(value, numbers.Integral):
        value = int(value)
    elif isinstance(value, numbers.Real) and math.isfinite(value) and value == int(value) \
            and abs(value) <= MAX_PARAM_INT:
        value = int(value)
    if not isinstance(value, int):
        raise ValueError(f"{label} must be an integer, got {_shown(value)}.")
    if abs(value) > MAX_PARAM_INT:
        raise ValueError(f"{label} must be at most {MAX_PARAM_INT} in magnitude, got {_shown(value)}.")
    return value


def _shown(value, limit: int = 40) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
