"""Compatibility: the reference implementations moved beside their matchers (``cvstereo.matchers.<name>.reference``).

``from calibration_free.reference import frame_clusters_reference`` keeps working through 0.x; the module names
of 0.2 (``calibration_free.reference.frame_clusters``, ...) are answered by :mod:`cvstereo._compat`.
"""

from cvstereo.matchers.event_area.reference import event_area_reference
from cvstereo.matchers.event_time.reference import event_time_reference
from cvstereo.matchers.event_vector.reference import event_vector_reference
from cvstereo.matchers.frame.reference import frame_clusters_reference
from cvstereo.matchers.frame_area.reference import frame_area_reference
from cvstereo.matchers.fused.reference import fused_reference

__all__ = ["event_area_reference", "event_time_reference", "event_vector_reference", "frame_area_reference",
           "frame_clusters_reference", "fused_reference"]
