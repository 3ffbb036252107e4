"""Types of the front door's lazily imported names (cvstereo/__init__.py), for IDEs and type checkers."""

from cvstereo.evaluation.metrics import evaluate as evaluate
from cvstereo.geometry.disparity_maps import disparity_images as disparity_images
from cvstereo.io import open_recording as open_recording
from cvstereo.io import read_matches as read_matches
from cvstereo.io import read_recording as read_recording
from cvstereo.io import write_matches as write_matches
from cvstereo.matchers.registry import available_methods as available_methods
from cvstereo.matchers.registry import create_matcher as create_matcher
from cvstereo.model.events import EVENT_DTYPE as EVENT_DTYPE
from cvstereo.model.events import as_events as as_events
from cvstereo.model.events import make_events as make_events
from cvstereo.model.matches import MATCH_DTYPE as MATCH_DTYPE
from cvstereo.model.matches import MatchResult as MatchResult
from cvstereo.model.matches import concat_matches as concat_matches
from cvstereo.model.recording import Recording as Recording
from cvstereo.run import match as match
from cvstereo.simulate import simulate_preset as simulate_preset

__version__: str
__all__ = ["EVENT_DTYPE", "MATCH_DTYPE", "MatchResult", "Recording", "__version__", "as_events",
           "available_methods", "concat_matches", "create_matcher", "disparity_images", "evaluate", "make_events",
           "match", "open_recording", "read_matches", "read_recording", "simulate_preset", "write_matches"]
