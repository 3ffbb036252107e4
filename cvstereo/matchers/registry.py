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
import importlib
import importlib.metadata
import importlib.util
import typing
from collections.abc import Iterator, Mapping

from cvstereo.matchers._registry import BUILTIN_METHODS, ENTRY_POINT_GROUP, matcher_class
from cvstereo.matchers._registry import registered_methods as _methods
from cvstereo.matchers.constraints import check_value
from cvstereo.matchers.params import aliases_of, canonical_params
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.matchers.sets import resolve

__all__ = ["DEFAULT_METHOD", "ENTRY_POINT_GROUP", "LISTING_ORDER", "METHODS", "available_methods",
           "check_param_item", "create_matcher", "matcher_class", "matcher_params", "params_from_meta",
           "parse_param_strings"]

#: The method run when none is named (`cvstereo match`, `cvstereo live`, :func:`cvstereo.match`): the thesis'
#: frame matcher, the one that answers on the most recordings.
DEFAULT_METHOD = "frame"

#: The order in which tables and listings show the methods: the built-in table's, then plugins by name.
LISTING_ORDER = tuple(BUILTIN_METHODS)


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


def create_matcher(method: str, variant: str | None = None, *, resolution=(128, 128), param_set: str = "adaptive",
                   threads: int | None = None, **params) -> StreamMatcher:
    """Build a matcher by name, variant, parameter set and parameter overrides.

    ``param_set`` (:mod:`cvstereo.matchers.sets`): ``adaptive`` (default, thresholds relative to the recording's
    signal level, each method's best variant) or ``thesis`` (docs/algorithms.md's constants and default variants).
    An explicit ``variant`` wins over the set's default variant; ``params`` override the set's values. A
    built-in method's matcher has the kernels it runs compiled or loaded before it is returned (a copy of it run
    on a small clip, once per process and compiled path: :func:`cvstereo._compile_watch.prepare`), so that no
    caller times their compilation.

    ``threads`` (:attr:`StreamMatcher.threads <cvstereo.matchers.protocol.StreamMatcher.threads>`): the threads
    it may run on, a whole number >= 1; default :func:`cvstereo._threads.default_threads` (the cores this process
    may use). The matches do not depend on it (docs/guide/threads.md).

    Examples
    --------
    >>> m = create_matcher("frame", "separate", width_tolerance=0.25)
    >>> m.params.polarity, m.params.width_tolerance
    ('separate', 0.25)
    """
    from cvstereo._threads import check_threads, default_threads

    threads = default_threads() if threads is None else check_threads(threads)  # refused before any compiling
    variant, set_params = resolve(method, variant, param_set)
    cls = matcher_class(method)
    matcher = cls.from_variant(variant, resolution=resolution, **{**set_params, **params})
    matcher.param_set = param_set
    matcher.threads = threads  # before the preparation: parallel kernels are compiled apart from the serial ones
    if method in BUILTIN_METHODS:
        from cvstereo import _compile_watch

        # A copy of this very matcher on the built-in clip: the kernels it runs compiled or loaded before any
        # caller's clock (once per process and compiled path).
        _compile_watch.prepare(matcher, method)
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

    The same rules as at construction (:func:`cvstereo.matchers.constraints.check_value`: the field's type, then
    its declared constraint), so that a grid of configurations is checked value by value before any is run. Old
    field names are accepted (:mod:`cvstereo.matchers.params`).

    Raises
    ------
    ValueError
        Unknown name (the allowed ones listed) or a value of the wrong type or range, naming ``where`` and ``key``.
    """
    return check_value(params_cls, _field_named(params_cls, key), value, where=where, given_as=key)


def parse_param_strings(params_cls: type, items: list[str]) -> dict:
    """Turn ``["key=value", ...]`` into typed overrides for the dataclass ``params_cls``.

    Old names of renamed fields (:mod:`cvstereo.matchers.params`) are accepted and come back under the new name.
    Each value is checked as at construction (:func:`cvstereo.matchers.constraints.check_value`).

    Raises
    ------
    ValueError
        Malformed item, unknown name (the allowed ones are listed) or a value of the wrong type.
    """
    hints = typing.get_type_hints(params_cls)
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"--param '{item}' is not key=value.")
        field = _field_named(params_cls, key)
        value = _parse_value(key, text.strip(), hints[field])
        out[key] = check_value(params_cls, field, value, where="--param", given_as=key)
    return canonical_params(params_cls, out)


def params_from_meta(meta: dict):
    """The parameter object a matches file's meta describes (``method`` and ``params``; old names accepted).

    Examples
    --------
    >>> params_from_meta({"method": "event-area", "params": {"max_sad": 500.0}}).max_cost
    500.0
    """
    return matcher_class(meta["method"]).Params(**meta["params"])


def _field_named(params_cls: type, key: str) -> str:
    """The field ``key`` names (an old name gives the new one); ValueError listing the fields otherwise."""
    aliases = aliases_of(params_cls)
    field = aliases[key].name if key in aliases else key
    names = [f.name for f in dataclasses.fields(params_cls)]
    if field not in names:
        from cvstereo._threads import NOT_A_PARAMETER

        raise ValueError(f"unknown parameter '{key}'; allowed: {', '.join(sorted(names))}"
                         + (f" ({NOT_A_PARAMETER})." if key == "threads" else "."))
    return field


def _parse_value(key: str, text: str, hint):
    """The value ``text`` stands for in a field of type ``hint`` (a ``Literal``'s values' type); checked later."""
    choices = typing.get_args(hint) if typing.get_origin(hint) is typing.Literal else ()
    base = type(choices[0]) if choices else hint
    try:
        if base is bool:
            low = text.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            return low in ("true", "1", "yes")
        if base is int:
            return int(text)
        if base is float:
            return float(text)
    except ValueError:
        raise ValueError(f"parameter '{key}' needs a {getattr(base, '__name__', base)}, got '{text}'.") from None
    return text
