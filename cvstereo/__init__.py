"""cvstereo: depth from a pair of event cameras without calibration.

The front door: ``import cvstereo as cvs``, then

>>> import cvstereo as cvs
>>> rec = cvs.simulate_preset("1arm-50cm", seconds=0.2, seed=0)          # doctest: +SKIP
>>> result = cvs.match(rec, method="frame")                              # doctest: +SKIP
>>> cvs.evaluate(rec, result)["coverage"]                                # doctest: +SKIP
>>> "frame" in cvs.available_methods()
True

Every name of :data:`__all__` is imported on first use, so that ``import cvstereo`` (which every ``cvstereo``
command starts with) loads no numpy: the command line handles Ctrl-C and SIGTERM from its first line on, and a
stop during the heavy imports after that is a clean one. The packages behind the names: :mod:`cvstereo.model`
(events, matches, recordings), :mod:`cvstereo.io`, :mod:`cvstereo.frames`, :mod:`cvstereo.matchers` (the
registry, the streaming protocol, one subpackage per matcher), :mod:`cvstereo.run` (the one feed loop),
:mod:`cvstereo.geometry`, :mod:`cvstereo.evaluation`, :mod:`cvstereo.simulate`, :mod:`cvstereo.sensors`,
:mod:`cvstereo.sweep`, :mod:`cvstereo.viz`, :mod:`cvstereo.cli`.
"""

import importlib

from cvstereo import _compat, _numba_cache

# Before any module with numba kernels is imported: a read-only installation must still compile them.
_numba_cache.configure()
# The import paths of 0.2 that name moved modules keep working (CHANGELOG.md lists the moves).
_compat.install()

__version__ = "0.3.0"

#: The names this package exports -> the module that defines each, imported on first use.
_EXPORTS = {
    "EVENT_DTYPE": "cvstereo.model.events", "as_events": "cvstereo.model.events",
    "make_events": "cvstereo.model.events",
    "MATCH_DTYPE": "cvstereo.model.matches", "MatchResult": "cvstereo.model.matches",
    "concat_matches": "cvstereo.model.matches",
    "Recording": "cvstereo.model.recording",
    "read_recording": "cvstereo.io", "open_recording": "cvstereo.io", "read_matches": "cvstereo.io",
    "write_matches": "cvstereo.io",
    "match": "cvstereo.run",
    "available_methods": "cvstereo.matchers.registry", "create_matcher": "cvstereo.matchers.registry",
    "evaluate": "cvstereo.evaluation.metrics", "disparity_images": "cvstereo.geometry.disparity_maps",
    "simulate_preset": "cvstereo.simulate",
}

__all__ = ["EVENT_DTYPE", "MATCH_DTYPE", "MatchResult", "Recording", "__version__", "as_events",
           "available_methods", "concat_matches", "create_matcher", "disparity_images", "evaluate", "make_events",
           "match", "open_recording", "read_matches", "read_recording", "simulate_preset", "write_matches"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cvstereo' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
