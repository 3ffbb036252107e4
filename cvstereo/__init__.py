"""cvstereo: depth from a pair of event cameras without calibration.

The core (event model, recording I/O, simulator, frames, evaluation, depth, sensors, CLI), the matcher
registry (:mod:`cvstereo.matchers.registry`) and :func:`cvstereo.run.match`. The thesis' matchers live in the
sister package :mod:`calibration_free` and register through the entry-point group ``cvstereo.matchers``, so
that nothing here imports them by name.
"""

import importlib

from cvstereo import _compat, _numba_cache

# Before any module with numba kernels is imported: a read-only installation must still compile them.
_numba_cache.configure()
# The import paths of 0.2 that name moved modules keep working (CHANGELOG.md lists the moves).
_compat.install()

__version__ = "0.1.0"

#: The names this package exports -> the module that defines each. They are imported on first use, so that
#: ``import cvstereo`` (which every ``cvstereo`` command starts with) loads no numpy: the command line handles
#: Ctrl-C and SIGTERM from its first line on, and a stop during the heavy imports after that is a clean one.
_EXPORTS = {"EVENT_DTYPE": "cvstereo.model.events", "as_events": "cvstereo.model.events",
            "make_events": "cvstereo.model.events", "MATCH_DTYPE": "cvstereo.model.matches",
            "MatchResult": "cvstereo.model.matches", "Recording": "cvstereo.model.recording"}

__all__ = ["EVENT_DTYPE", "MATCH_DTYPE", "MatchResult", "Recording", "__version__", "as_events", "make_events"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cvstereo' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
