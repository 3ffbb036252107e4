"""The thesis' five parameter classes under one name, for code written against 0.2's ``calibration_free.params``.

Each class lives in its matcher's package (``cvstereo.matchers.<name>.params``), beside its matcher; this module
only re-exports them (``cvstereo._compat.MOVED`` answers the old module names with it).
"""

from __future__ import annotations

from cvstereo.matchers.event_area.params import EventAreaParams
from cvstereo.matchers.event_time.params import EventTimeParams
from cvstereo.matchers.event_vector.params import EventVectorParams
from cvstereo.matchers.frame.params import WIDTH_EPS, FrameClusterParams
from cvstereo.matchers.frame_area.params import FrameAreaParams

__all__ = ["WIDTH_EPS", "EventAreaParams", "EventTimeParams", "EventVectorParams", "FrameAreaParams",
           "FrameClusterParams"]
