"""Parameters of the fused matcher (:mod:`cvstereo.matchers.fused.matcher`), apart so that the kernel and the reference
both import them without importing each other."""

from __future__ import annotations

from dataclasses import dataclass

from cvstereo.matchers.constraints import DeclaredParams, param

__all__ = ["FusedParams"]

#: The next window's prior is the answers of uncertainty at most this (the consistent ones) whatever
#: ``max_uncertainty`` keeps: a run with ``max_uncertainty=1`` (every answer, ranked) then gives the default run's
#: matches as its answers of uncertainty at most 0.5, and its ranking is that of the default output.
PRIOR_MAX_UNCERTAINTY = 0.5
#: The partner test (``border_rows``) judges a band of rows only when it has at least this many consistent answers:
#: the median of fewer is too often that of a few wrong ones.
BORDER_MIN_ANSWERS = 8


@dataclass(frozen=True)
class FusedParams(metaclass=DeclaredParams):
    """Parameters of :class:`cvstereo.matchers.fused.matcher.FusedMatcher` (the module docstring gives each one's
    reason).

    Attributes
    ----------
    window_us : int
        Window length W, us; windows ``[k*W, (k+1)*W)`` on the absolute clock, stamped with their end.
    tau_us : int
        Time-surface decay, us: an event's surface value falls linearly from 1 to 0 over ``tau_us``.
    support_radius : int
        Half side of the square support each feature is summed over, px (1: 3x3); 0 disables it.
    max_disparity : int
        Largest disparity searched, px (0 .. max_disparity); 63 at 128 px wide, scaled with the sensor width
        (the OpenCV baselines' range: an arm at 0.3 m from the simulated rig is at 48..55 px, beyond 47).
    row_tolerance : int
        The right pixel may lie up to this many rows above or below the left one (the cost takes the best).
    p1, p2 : float
        Semi-global penalties for a disparity step of 1 px and of more, in units of the normalised feature
        (tuned on 2 s clips of the presets, bench/results/fused.md).
    path_radius : int
        The semi-global paths run through the left pixels within this many px (Chebyshev) of an event of the
        window: wide enough to carry support between the window's edges, narrow enough to stay fast.
    sgm_paths : {0, 2, 4}
        Scanline directions aggregated: 0 none (winner-takes-all on the pixel cost), 2 along rows, 4 rows and
        columns.
    temporal_weight : float
        Cost per pixel of disparity away from the pixel's estimate of the previous window (capped at 2 px);
        0 disables temporal coherence.
    lr_tolerance : int
        Left-right consistency: the right pixel's own winner must lie within this many px, else the match's
        uncertainty gets 0.5 added (and the default ``max_uncertainty`` drops it); -1 disables the check.
    fill_radius : int
        A match that fails the left-right check takes the median disparity of the consistent matches within
        this many px (Chebyshev) of it, where there are any; 0 disables. Wide (12), because the median of a wide
        square is right more often than that of the nearest answers (robustness suite, base: bad2 of every
        winner 2.1 % at 4 px, 1.3 % at 12 px; the nearest ring with an answer: 1.9 %).
    fill_confirms : bool
        A match that fails the left-right check but lies within ``lr_tolerance`` px of the median that would fill it
        is confirmed by the consistent answers around it: it keeps its own disparity and loses the left-right
        penalty of its uncertainty (so the default ``max_uncertainty`` keeps it). A failed check is often a
        near-tie of the right pixel, not a wrong left winner (Fan_disp8: 99.4 % of the confirmed are right).
    subpixel : bool
        Parabola fit of the aggregated cost around the winner.
    min_neighbours : int
        A left pixel answers only if at least this many pixels of its 3x3 neighbourhood (itself included) saw an
        event in the last two windows (isolated noise events get no answer); 1 disables.
    isolated_max_uncertainty : float
        An isolated pixel (fewer than ``min_neighbours``) still answers when its uncertainty is below this: a clear,
        unique and left-right consistent match is evidence enough that the event is not noise; 0: every isolated
        pixel is dropped.
    occlusion_margin : float
        Occlusion test, px: an answer of uncertainty at most 0.5 (left-right consistent or confirmed) lies in the
        left view's half-occlusion when ``occlusion_support`` such answers further right in its row map to right
        pixels at least this far left of its own (``x' - d' <= x - d - margin``: a nearer surface hides it from
        the right camera); its uncertainty then gets the left-right penalty 0.5. -1 disables.
    occlusion_support : int
        How many answers must cross an answer for the occlusion test to hide it: a surface has more than one,
        while a single crossing answer is often an outlier (a noise event's) that would hide a whole run of
        its row.
    border_rows : int
        Partner test, rows: an answer at column ``x`` left of ``D``, the median disparity of the consistent answers
        (uncertainty at most 0.5) in rows ``y - border_rows .. y + border_rows`` of its window, has its true partner
        outside the right image (``x - D < 0``): its uncertainty gets the left-right penalty 0.5, and it is not the
        next window's prior. Bands with fewer than :data:`BORDER_MIN_ANSWERS` consistent answers are not judged.
        -1 disables.
    segment_min_answers : int
        Segment test: the consistent answers of a window (uncertainty at most 0.5 after the occlusion and partner
        tests) form segments, answers within 2 px of each other (Chebyshev) whose disparities differ by at most
        1 px joined; an answer whose segment holds fewer than this many answers at a 128 px wide sensor (scaled
        with the width: 250 at 640 px) ranks behind the other consistent answers and before the inconsistent ones
        (uncertainty ``0.5 + u / 2``; an inconsistent answer's becomes ``0.75 + (u - 0.5) / 2``), unless it is below
        ``isolated_max_uncertainty`` (a clear match stands on its own, as in the noise filter). A surface's answers
        form large segments, a wrong answer's few neighbours rarely agree with it (SGBM's speckle filter, on the
        answers). The next window's prior is the answers before the test. 0 (the default) disables: 50, chosen on
        the generalization suite's tuning half, did not carry to its evaluation half (fewer wins against the peers,
        some large scenes almost without default answers; bench/results/fused-segments.md).
    max_uncertainty : float
        Matches whose uncertainty exceeds this are dropped. Uncertainty = half the ratio of the best to the
        second-best aggregated cost more than 1 px away (0..0.5), plus 0.5 where the left-right check, the
        occlusion test or the partner test fails (with the segment test on, in three tiers: see
        ``segment_min_answers``); the default 0.5 keeps the consistent matches, 1 keeps all.
    """

    window_us: int = param(40_000, gt=0, note="the thesis uses 40000")
    tau_us: int = param(80_000, gt=0, note="e.g. 80000")
    support_radius: int = param(1, ge=0, le=5, note="e.g. 1")
    max_disparity: int = param(63, ge=1, le=255, note="e.g. 63")
    row_tolerance: int = param(1, ge=0, le=3, note="e.g. 1")
    p1: float = param(3.0, ge=0, note="e.g. 3")
    p2: float = param(12.0, ge=0, note="e.g. 12, at least p1")
    path_radius: int = param(3, ge=0, le=5, note="e.g. 3")
    sgm_paths: int = param(4, choices=(0, 2, 4))
    temporal_weight: float = param(0.5, ge=0, note="0: off")
    lr_tolerance: int = param(1, ge=-1, note="-1: off")
    fill_radius: int = param(12, ge=0, le=16, note="0: off")
    fill_confirms: bool = True
    subpixel: bool = True
    min_neighbours: int = param(2, ge=1, le=9, note="1: off")
    isolated_max_uncertainty: float = param(0.1, ge=0, le=1, note="0: isolated pixels never answer")
    occlusion_margin: float = param(1.0, ge=0, le=16, off=-1, note="px, e.g. 1")
    occlusion_support: int = param(2, ge=1, le=8, note="e.g. 2")
    border_rows: int = param(2, ge=-1, le=16, note="-1: off; e.g. 2")
    segment_min_answers: int = param(0, ge=0, le=10_000, note="0: off; at 128 px wide, e.g. 50")
    max_uncertainty: float = param(0.5, gt=0, le=1, note="0.5: consistent matches, 1: all")

    def check_rules(self):
        """The rule between fields: the penalty of a larger step is at least that of a 1 px step."""
        if self.p2 < self.p1:
            raise ValueError(f"{type(self).__name__}: need 0 <= p1 <= p2 (e.g. p1=3, p2=12), got p1={self.p1}, "
                             f"p2={self.p2}.")
