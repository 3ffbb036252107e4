"""cvstereo: depth from a pair of event cameras without calibration.

The core (event model, recording I/O, simulator, frames, evaluation, depth, sensors, CLI), the matcher
registry (:mod:`cvstereo.registry`) and :func:`cvstereo.pipeline.match`. The thesis' matchers live in the
sister package :mod:`calibration_free` and register through the entry-point group ``cvstereo.matchers``, so
that nothing here imports them by name.
"""

from cvstereo.events import EVENT_DTYPE, as_events, make_events
from cvstereo.matches import MATCH_DTYPE, MatchResult
from cvstereo.recording import Recording

__version__ = "0.1.0"

__all__ = ["EVENT_DTYPE", "MATCH_DTYPE", "MatchResult", "Recording", "__version__", "as_events", "make_events"]
