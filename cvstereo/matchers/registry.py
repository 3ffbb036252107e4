"""Matchers by name: the built-in table, and the entry-point group ``cvstereo.matchers`` for plugins.

The matchers of this distribution are listed in :mod:`cvstereo.matchers._registry` as ``"module:Class"``
strings, so that a plain checkout on ``sys.path`` (no installed metadata) lists every one of them. Other
distributions add matchers in their ``pyproject.toml``::

    [project.entry-points."cvstereo.matchers"]
    my-method = "my_package.matcher:MyMatcher"

The CLI, :func:`cvstereo.match` and the benchmark find every matcher through this module, and the core never
imports a matcher by name. A matcher's module is imported only when it is used.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
import importlib.util
import typing
from collections.abc import Iterator, Mapping

from cvstereo.matchers._registry import BUILTIN_METHODS
from cvstereo.matchers.params import aliases_of, canonical_params
from cvstereo.matchers.protocol import StreamMatcher, check_param_value
from cvstereo.matchers.sets import resolve

__all__ = ["DEFAULT_METHOD", "ENTRY_POINT_GROUP", "LISTING_ORDER", "METHODS", "available_methods",
           "check_param_item", "create_matcher", "matcher_class", "matcher_params", "params_from_meta",
           "parse_param_strings"]

#: The entry-point group in which other distributions register matchers: name (docs/formats.md) -> "module:Class".
ENTRY_POINT_GROUP = "cvstereo.matchers"

#: The method run when none is named (`cvstereo match`, `cvstereo live`, :func:`cvstereo.match`): the thesis'
#: frame matcher, the one that answers on the most recordings.
DEFAULT_METHOD = "frame"

#: The order in which tables and listings show the methods: the built-in table's, then plugins by name.
LISTING_ORDER = tuple(BUILTIN_METHODS)


@functools.cache
def _methods() -> dict[str, str]:
    """name -> "module:Class": the built-in table, then the plugins' entry points (a plugin cannot replace a
    built-in name: the name would mean two matchers, and the thesis' names are fixed by docs/formats.md)."""
    found = dict(BUILTIN_METHODS)
    plugins = {ep.name: ep.value for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
    for name in sorted(plugins):
        found.setdefault(name, plugins[name])
    return found


def _load(target: str) -> type[StreamMatcher]:
    """The object a ``"module:Qualified.name"`` string names (the entry-point syntax)."""
    module, _, qualname = target.partition(":")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


class _Methods(Mapping):
    """The registered methods, read on first use: name -> "module:Class"."""

    def __getitem__(self, name: str) -> str:
        return _methods()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(_methods())

    def __len__(self) -> int:
        return len(_methods())

    def __repr__(self) -> str:
        return f"METHODS({dict(self)!r})"


#: method name (docs/formats.md) -> "module:Class" of its StreamMatcher, in listing order.
METHODS: Mapping[str, str] = _Methods()


def available_methods() -> list[str]:
    """Names of the methods whose module, and the optional extras it needs, can be imported here."""
    out = []
    for name in METHODS:
        try:
            cls = matcher_class(name)
        except ImportError:
            continue
        # Optional extras (e.g. dv-processing for the comparison) are only imported when a matcher is built.
        if all(importlib.util.find_spec(mod) is not None for mod in getattr(cls, "requires", ())):
            out.append(name)
    return out


def matcher_class(method: str) -> type[StreamMatcher]:
    """The StreamMatcher class registered under ``method``.

    Raises
    ------
    ValueError
        Unknown method; the message lists the known ones.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method '{method}'; choose one of: {', '.join(METHODS)}.")
    return _load(_methods()[method])


def create_matcher(method: str, variant: str | None = None, *, resolution=(128, 128), param_set: str = "adaptive",
                   **params) -> StreamMatcher:
    """Build a matcher by name, variant, parameter set and parameter overrides.

    ``param_set`` (:mod:`cvstereo.matchers.sets`): ``adaptive`` (default, thresholds relative to the recording's
    signal level, each method's best variant) or ``thesis`` (docs/algorithms.md's constants and default variants).
    An explicit ``variant`` wins over the set's default variant; ``params`` override the set's values. The first
    matcher of a built-in method in a process has its kernels compiled or loaded first
    (:func:`cvstereo._compile_watch.prepare`), so that no caller times their compilation.

    Examples
    --------
    >>> m = create_matcher("frame", "separate", width_tolerance=0.25)
    >>> m.params.polarity, m.params.width_tolerance
    ('separate', 0.25)
    """
    variant, set_params = resolve(method, variant, param_set)
    cls = matcher_class(method)

    if method in BUILTIN_METHODS:
        from cvstereo import _compile_watch

        # The set's default matcher on the built-in clip: its kernels compiled or loaded before any caller's clock.
        default, default_params = resolve(method, None, param_set)
        _compile_watch.prepare(method, param_set,
                               lambda size: cls.from_variant(default, resolution=size, **default_params))
    matcher = cls.from_variant(variant, resolution=resolution, **{**set_params, **params})
    matcher.param_set = param_set
    return matcher


def matcher_params(method: str, variant: str | None = None, *, resolution=(128, 128), param_set: str = "adaptive",
                   **params):
    """The parameter object :func:`create_matcher` would give the matcher, without building the matcher.

    Every check of the values runs (the generic range rule and the dataclass' own), so a grid of
    configurations can be checked whole before any is run (:mod:`cvstereo.sweep`).

    Raises
    ------
    ValueError
        Unknown method, variant, parameter set or parameter, or a value the matcher refuses.
    """
    variant, set_params = resolve(method, variant, param_set)
    return matcher_class(method).params_for(variant, resolution=resolution, **{**set_params, **params})


def check_param_item(params_cls: type, key: str, value, *, where: str = "parameter"):
    """Check one parameter value given already typed (Python, TOML, JSON) against its field; return it.

    The field's type decides: a bool field takes only ``True``/``False`` (not 1), a text field only text, a
    numeric one what :func:`~cvstereo.matchers.protocol.check_param_value` accepts, a ``Literal`` field one of its
    values. Old field names are accepted (:mod:`cvstereo.matchers.params`).

    Raises
    ------
    ValueError
        Unknown name (the allowed ones listed) or a value of the wrong type or range, naming ``where`` and ``key``.
    """
    aliases = aliases_of(params_cls)
    field = aliases[key].name if key in aliases else key
    hints = typing.get_type_hints(params_cls)
    if field not in {f.name for f in dataclasses.fields(params_cls)}:
        names = ", ".join(sorted(f.name for f in dataclasses.fields(params_cls)))
        raise ValueError(f"unknown parameter '{key}'; allowed: {names}.")
    return _checked_value(key, value, hints[field], where)


def parse_param_strings(params_cls: type, items: list[str]) -> dict:
    """Turn ``["key=value", ...]`` into typed overrides for the dataclass ``params_cls``.

    Old names of renamed fields (:mod:`cvstereo.matchers.params`) are accepted and come back under the new name.

    Raises
    ------
    ValueError
        Malformed item, unknown name (the allowed ones are listed) or a value of the wrong type.
    """
    fields = {f.name: f for f in dataclasses.fields(params_cls)}
    aliases = aliases_of(params_cls)
    hints = typing.get_type_hints(params_cls)
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"--param '{item}' is not key=value.")
        field = aliases[key].name if key in aliases else key
        if field not in fields:
            raise ValueError(f"unknown parameter '{key}'; allowed: {', '.join(sorted(fields))}.")
        out[key] = _parse_value(key, text.strip(), hints[field])
    return canonical_params(params_cls, out)


def params_from_meta(meta: dict):
    """The parameter object a matches file's meta describes (``method`` and ``params``; old names accepted).

    Examples
    --------
    >>> params_from_meta({"method": "event-area", "params": {"max_sad": 500.0}}).max_cost
    500.0
    """
    return matcher_class(meta["method"]).Params(**meta["params"])


def _parse_value(key: str, text: str, hint):
    _, base = _field_base(hint)
    try:
        if base is bool:
            low = text.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            value = low in ("true", "1", "yes")
        elif base is int:
            value = int(text)
        elif base is float:
            value = float(text)
        else:
            value = text
    except ValueError:
        raise ValueError(f"parameter '{key}' needs a {getattr(base, '__name__', base)}, got '{text}'.") from None
    return _checked_value(key, value, hint, "--param")


def _field_base(hint) -> tuple[tuple, type]:
    """The choices of a ``Literal`` field (else empty) and the type its values have."""
    choices = typing.get_args(hint) if typing.get_origin(hint) is typing.Literal else ()
    return choices, type(choices[0]) if choices else hint


def _checked_value(key: str, value, hint, where: str):
    """``value`` checked against a field's type: the generic range rule of every matcher's numbers (finite
    floats, ints a C int holds), bools and text by type, a ``Literal``'s choices; ``where`` names the source."""
    choices, base = _field_base(hint)
    if base is bool and not isinstance(value, bool):
        raise ValueError(f"{where} '{key}' must be true or false, got {value!r}.")
    if base in (int, float):
        value = check_param_value(key, value, base, where=where)
    elif base is str and not isinstance(value, str):
        raise ValueError(f"{where} '{key}' must be text, got {value!r}.")
    if choices and value not in choices:
        raise ValueError(f"{where} '{key}' must be one of {', '.join(map(str, choices))}, got {value!r}.")
    return value
