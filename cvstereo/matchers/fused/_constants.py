"""The fixed numbers of the fused matcher's method (:mod:`cvstereo.matchers.fused.matcher` gives the design), in one
place for the kernels and the reference alike.

They are not parameters (:class:`~cvstereo.matchers.fused.params.FusedParams`): each one is part of how a
quantity is defined (the uncertainty's scale, the noise filter's neighbourhood), so that changing one changes the
method, not a setting of it. A plain module (no numba), so that the reference imports them without compiling
anything; numba reads them as compile-time constants.
"""

from __future__ import annotations

__all__ = ["CONSISTENT_MAX_UNCERTAINTY", "LR_PENALTY", "NOISE_RADIUS", "RATIO_UNCERTAINTY", "RECENT_WINDOWS",
           "SECOND_BEST_GAP_PX", "SEGMENT_RADIUS", "SEGMENT_STEP_PX", "SEGMENT_TIER", "SEGMENT_WIDTH_PX",
           "SUBPIXEL_MAX_SHIFT_PX", "TEMPORAL_CAP_PX"]

#: The temporal term's distance from the prior is capped at this many px: beyond it the prior says nothing more
#: (a surface that moved that far is another surface), so a new depth pays at most ``2 * temporal_weight``.
TEMPORAL_CAP_PX = 2.0

#: The runner-up cost of the uncertainty ratio is the least more than this many px from the winner (its
#: neighbours belong to the same minimum).
SECOND_BEST_GAP_PX = 1

#: Uncertainty per unit of the cost ratio (best over runner-up, 0..1): a clear winner is near 0, a tie 0.5.
RATIO_UNCERTAINTY = 0.5

#: Added to the uncertainty where the left-right check, the occlusion test or the partner test fails (and taken
#: off again where the fill confirms a winner): every such answer then ranks behind every consistent one.
LR_PENALTY = 0.5

#: The consistent answers: uncertainty at most this (the ratio's range, no penalty). The occlusion and partner
#: tests judge with them.
CONSISTENT_MAX_UNCERTAINTY = RATIO_UNCERTAINTY

#: The sub-pixel parabola may move the winner by at most this many px: further, its vertex lies nearer a
#: neighbouring disparity, which did not win.
SUBPIXEL_MAX_SHIFT_PX = 0.5

#: The noise filter counts the recent pixels within this Chebyshev distance of a pixel (1: its 3x3 neighbourhood).
NOISE_RADIUS = 1

#: A pixel is *recent* for the noise filter when it saw an event within this many windows up to the current
#: one's end.
RECENT_WINDOWS = 2

#: The segment test joins two consistent answers of a window into one segment when they lie within this Chebyshev
#: distance (px) of each other: 2 bridges the one-pixel gaps between the event pixels of an edge.
SEGMENT_RADIUS = 2

#: ... and their disparities differ by at most this many px: a surface's disparity changes little from pixel to
#: pixel, a wrong answer's jumps.
SEGMENT_STEP_PX = 1.0

#: ``segment_min_answers`` is given for a sensor this many px wide and scaled with the width (an edge's answers
#: grow with it).
SEGMENT_WIDTH_PX = 128

#: With the segment test on, the uncertainty has three tiers: the consistent answers [0, 0.5] as before, those of a
#: small segment ``0.5 + u / 2`` in (0.5, SEGMENT_TIER], the inconsistent ones ``SEGMENT_TIER + (u - 0.5) / 2`` in
#: (SEGMENT_TIER, 1]: an answer in a small segment is still more often right than one that fails the left-right
#: check, so it ranks between them.
SEGMENT_TIER = 0.75
