"""The matchers this distribution ships, by name: the same ``"module:Class"`` strings as its entry points.

The registry (:mod:`cvstereo.matchers.registry`) reads this table first and adds the matchers other
distributions register in the entry-point group ``cvstereo.matchers``. A plain checkout on ``sys.path``, with
only the dependencies installed and no metadata of its own, therefore lists every built-in method; installing
a plugin adds its names. Nothing here is imported until a method is used: the strings are only names.
"""

from __future__ import annotations

__all__ = ["BUILTIN_METHODS"]

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
