"""The constants of the consistency checks the thesis does not make (neighbour support, left-right, border rule).

They live apart from the compiled checks (:mod:`cvstereo.matchers._shared.support`,
:mod:`cvstereo.matchers._shared.border`) so that the fast path and the independent references
(:mod:`cvstereo.matchers._shared.reference_checks`, :mod:`cvstereo.matchers._shared.reference_border`) read the
same numbers without the references importing a compiled kernel. The pixel ones are geometry (pixels of the
sensor, pixels of disparity), not signal: they stay absolute in every parameter set.
"""

from __future__ import annotations

__all__ = ["BORDER_OFF", "BORDER_VOTES", "LR_TOLERANCE_PX", "SUPPORT_RADIUS_PX", "SUPPORT_TOLERANCE_PX"]

#: Neighbours lie within this many pixels in x and in y (a 5x5 square around the match).
SUPPORT_RADIUS_PX = 2
#: A neighbour supports a match when their disparities differ by at most this, px.
SUPPORT_TOLERANCE_PX = 1.0
#: The left-right check keeps a disparity when the other camera's scan, at the pixel it names, lies within this, px.
LR_TOLERANCE_PX = 1.0

#: ``border_horizon_us`` of the ``thesis`` set: the border rule is off (the thesis answers everywhere).
BORDER_OFF = 0
#: How many rows (the nearest that hold evidence) vote on a match near the border.
BORDER_VOTES = 3
