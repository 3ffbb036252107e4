"""cvstereo: depth from a pair of event cameras without calibration.

The core (event model, recording I/O, simulator, frames, evaluation, depth, sensors, CLI), the matcher
registry (:mod:`cvstereo.registry`) and :func:`cvstereo.pipeline.match`. The thesis' matchers live in the
sister package :mod:`calibration_free` and register through the entry-point group ``cvstereo.matchers``, so
that nothing here imports them by name.
"""

from cvstereo import _numba_cache

# Before any module with numba kernels is imported: a read-only installation must still compile them.
_numba_cache.configure()

from cvstereo.events import EVENT_DTYPE  # noqa: E402, as_events, make_events
from cvstereo.matches import MATCH_DTYPE, MatchResult  # noqa: E402
from cvstereo.recording import Recording  # noqa: E402

__version__ = "0.1.0"

__all__ = ["EVENT_DTYPE", "MATCH_DTYPE", "MatchResult", "Recording", "__version__", "as_events", "make_events"]
