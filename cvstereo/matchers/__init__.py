"""The matchers: the registry by name, the streaming protocol, and one subpackage per matcher.

Everything about one matcher sits in its folder (``frame/``, ``frame_area/``, ``event_time/``, ``event_area/``,
``event_vector/``, ``fused/``, ``opencv/``, ``dv/``): the matcher, its kernels and its readable reference. The
machinery several matchers share is in ``_shared/``; :mod:`~cvstereo.matchers.protocol` defines what a matcher
is (:class:`~cvstereo.matchers.protocol.StreamMatcher`). This package imports the core; the core reaches it
only through the registry's names (:mod:`cvstereo.matchers._registry`), so nothing outside it imports a
matcher by name.

The registry API is importable from here and is loaded on first use:

>>> from cvstereo.matchers import available_methods
>>> "frame" in available_methods()
True
"""

import importlib

#: The registry API (:mod:`cvstereo.matchers.registry`), loaded on first use so that importing the protocol
#: (which the core's frame windows do) does not load the parameter sets and the registry.
_REGISTRY_NAMES = ("DEFAULT_METHOD", "ENTRY_POINT_GROUP", "METHODS", "available_methods", "check_param_item",
                   "create_matcher", "matcher_class", "matcher_params", "params_from_meta", "parse_param_strings")

__all__ = list(_REGISTRY_NAMES)


def __getattr__(name: str):
    if name not in _REGISTRY_NAMES:
        raise AttributeError(f"module 'cvstereo.matchers' has no attribute {name!r}")
    value = getattr(importlib.import_module("cvstereo.matchers.registry"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_REGISTRY_NAMES})
