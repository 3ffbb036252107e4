"""Matchers by name: the thesis' five, and the OpenCV baselines, looked up lazily.

The CLI, ``calibration_free.match`` and the benchmark find matchers here, so adding a matcher means
adding one line to :data:`METHODS`.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import typing

from cvstereo.matcher import StreamMatcher

#: method name (formats.md) -> "module:Class" of its StreamMatcher.
METHODS: dict[str, str] = {
    "frame": "calibration_free.frame_clusters:FrameClusterMatcher",
    "frame-area": "calibration_free.frame_area:FrameAreaMatcher",
    "event-time": "calibration_free.event_time:EventTimeMatcher",
    "event-area": "calibration_free.event_area:EventAreaMatcher",
    "event-vector": "calibration_free.event_vector:EventVectorMatcher",
    "stereobm": "cvstereo.baseline:StereoBMMatcher",
    "sgbm": "cvstereo.baseline:StereoSGBMMatcher",
    "dv-semidense": "cvstereo.compare_dv:DvSemiDenseMatcher",
}


def available_methods() -> list[str]:
    """Names of the methods whose module can be imported here."""
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
    module_name, cls_name = METHODS[method].split(":")
    return getattr(importlib.import_module(module_name), cls_name)


def create_matcher(method: str, variant: str | None = None, *, resolution=(128, 128), param_set: str = "adaptive",
                   **params) -> StreamMatcher:
    """Build a matcher by name, variant, parameter set and parameter overrides.

    ``param_set`` (:mod:`cvstereo.param_sets`): ``adaptive`` (default, thresholds relative to the recording's
    signal level, each method's best variant) or ``thesis`` (algorithms.md's constants and default variants).
    An explicit ``variant`` wins over the set's default variant; ``params`` override the set's values.

    Examples
    --------
    >>> m = create_matcher("frame", "separate", width_tolerance=0.25)  # doctest: +SKIP
    """
    from cvstereo.param_sets import resolve

    variant, set_params = resolve(method, variant, param_set)
    matcher = matcher_class(method).from_variant(variant, resolution=resolution, **{**set_params, **params})
    matcher.param_set = param_set
    return matcher


def parse_param_strings(params_cls: type, items: list[str]) -> dict:
    """Turn ``["key=value", ...]`` into typed overrides for the dataclass ``params_cls``.

    Raises
    ------
    ValueError
        Malformed item, unknown name (the allowed ones are listed) or a value of the wrong type.
    """
    fields = {f.name: f for f in dataclasses.fields(params_cls)}
    hints = typing.get_type_hints(params_cls)
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"--param '{item}' is not key=value.")
        if key not in fields:
            raise ValueError(f"unknown parameter '{key}'; allowed: {', '.join(sorted(fields))}.")
        out[key] = _parse_value(key, text.strip(), hints[key])
    return out


def _parse_value(key: str, text: str, hint):
    origin = typing.get_origin(hint)
    choices = typing.get_args(hint) if origin is typing.Literal else None
    base = type(choices[0]) if choices else hint
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
    if choices and value not in choices:
        raise ValueError(f"parameter '{key}' must be one of {', '.join(map(str, choices))}, got '{text}'.")
    return value
