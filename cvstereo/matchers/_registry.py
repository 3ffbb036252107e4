"""The matchers this distribution ships, by name (the same ``"module:Class"`` strings as its entry points), and the
lookup of a name's class.

This table is read first, then the matchers other distributions register in the entry-point group
``cvstereo.matchers``. A plain checkout on ``sys.path``, with only the dependencies installed and no metadata of its
own, therefore lists every built-in method; installing a plugin adds its names. Nothing here is imported until a
method is used: the strings are only names. The registry (:mod:`cvstereo.matchers.registry`) builds on this module,
and so does :mod:`cvstereo.matchers.sets`, which asks a method's class for its parameter sets (the registry imports
the sets, so they cannot import the registry).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata

__all__ = ["BUILTIN_METHODS", "ENTRY_POINT_GROUP", "matcher_class", "registered_methods"]

#: The entry-point group in which other distributions register matchers: name (docs/formats.md) -> "module:Class".
ENTRY_POINT_GROUP = "cvstereo.matchers"

#: method name (docs/formats.md) -> "module:Class" of its matcher, in listing order. ``pyproject.toml`` registers
#: the same strings as entry points (test_matchers_registry checks that they agree).
BUILTIN_METHODS: dict[str, str] = {
    "frame": "cvstereo.matchers.frame:FrameClusterMatcher",
    "frame-area": "cvstereo.matchers.frame_area:FrameAreaMatcher",
    "event-time": "cvstereo.matchers.event_time:EventTimeMatcher",
    "event-area": "cvstereo.matchers.event_area:EventAreaMatcher",
    "event-vector": "cvstereo.matchers.event_vector:EventVectorMatcher",
    "stereobm": "cvstereo.matchers.opencv:StereoBMMatcher",
    "sgbm": "cvstereo.matchers.opencv:StereoSGBMMatcher",
    "dv-semidense": "cvstereo.matchers.dv:DvSemiDenseMatcher",
    "fused": "cvstereo.matchers.fused:FusedMatcher",
}


@functools.cache
def registered_methods() -> dict[str, str]:
    """name -> "module:Class": the built-in table, then the plugins' entry points (a plugin cannot replace a
    built-in name: the name would mean two matchers, and the thesis' names are fixed by docs/formats.md)."""
    found = dict(BUILTIN_METHODS)
    plugins = {ep.name: ep.value for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}
    for name in sorted(plugins):
        found.setdefault(name, plugins[name])
    return found


def matcher_class(method: str) -> type:
    """The StreamMatcher class registered under ``method`` (its module imported now).

    Raises
    ------
    ValueError
        Unknown method; the message lists the known ones.
    """
    methods = registered_methods()
    if method not in methods:
        raise ValueError(f"unknown method '{method}'; choose one of: {', '.join(methods)}.")
    module, _, qualname = methods[method].partition(":")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj
