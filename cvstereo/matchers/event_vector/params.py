"""The parameters of the event-vector matcher (method ``event-vector``): fields, declared constraints and sets."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams
from cvstereo.matchers.constraints import param
from cvstereo.matchers.sets import ADAPTIVE_THESIS, AdaptiveDefaults

__all__ = ["EventVectorParams"]


@dataclass(frozen=True, kw_only=True)
class EventVectorParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-vector matcher, Algorithm 4 (docs/algorithms.md section 5). The class defaults are the
    ``thesis`` set and :attr:`adaptive` says what the ``adaptive`` set changes; the fields of the dynamic frames
    (:class:`~cvstereo.frames.dynamic.DynamicFrameParams`), of the relative thresholds and of the border rule come
    from the bases.

    Attributes
    ----------
    threshold : float
        Minimum ``|D|`` at the event's pixel, and what makes a pixel part of an accumulation.
    require_candidate_threshold : bool
        Candidates must pass the threshold with the sign of D at the event; False: every x2 (Algorithm 4).
    max_disparity : int
        Largest disparity searched.
    max_cost : float
        A match needs a cost below this (Algorithm 4's initial minimum).
    run_ends : bool
        False (the thesis): the vector is (a, b). True: it also holds how many pixels of the pixel's own run lie
        left and right of it (0, 0 below the threshold), and the cost adds their differences. Without them
        every pixel of a candidate run costs the same wherever it lies in the run (the cost depends only on
        the two neighbouring runs), and a row with one run in each camera has nothing to compare at all.
    cost_ratio : float
        0 (the thesis): ``max_cost`` alone bounds the cost. Otherwise the least cost must also be at most
        ``cost_slack + cost_ratio * length``, the length being the sum of the absolute entries of the event's
        vector: the distances of a right match disagree by more the longer they are (runs of the two cameras
        differ in width, edges move between events), a wrong match's by about their size.
    cost_slack : float
        The part of that bound that does not grow with the length, px (only with ``cost_ratio > 0``): short
        vectors of a right match still differ by a pixel or two.
    tie_break : {"smallest", "centre"}
        Among disparities of equal least cost, the smallest (the thesis) or the middle of the smallest and the
        largest: the cost is flat between the disparities that the left and the right neighbour imply, and
        the smallest one lies at the low end of that range.
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="default",
        why="its only variant; adaptive matches OFF and ON frames apart (a fan's blades cancel in one frame), "
            "places each candidate within its own run (run_ends: a row with one run per camera then still "
            "has something to compare), reports the middle of equally good disparities (the smallest sat at "
            "the low end of a flat cost) and bounds the cost by 2 px + 0.3 x the vector's length, which made it "
            "right far more often on Fan_disp8 and cut the density sweep's bad2 at thresholds x3; it splats each "
            "event with a 5x5 Gaussian of sigma 1.5 px (thesis 3x3, sigma 1): with fewer events per edge a 3x3 "
            "splat leaves holes where no event fell within a pixel, which split the runs the vectors measure, so "
            "dropping every second event lost a quarter of the coverage; the 5x5 splat keeps more of it and "
            "covers more of the density sweep",
        params={**ADAPTIVE_THESIS, "threshold_scale": 0.5, "level_floor": 0.5, "polarity": "separate", "run_ends": True,
                "tie_break": "centre", "cost_ratio": 0.3, "cost_slack": 2.0, "kernel_size": 5, "kernel_sigma": 1.5},
    )

    threshold: float = param(0.8, ge=0)
    require_candidate_threshold: bool = True
    max_disparity: int = param(64, ge=0)
    max_cost: float = 1000.0
    run_ends: bool = False
    cost_ratio: float = param(0.0, ge=0, note="0: off, the thesis")
    cost_slack: float = param(0.0, ge=0)
    tie_break: Literal["smallest", "centre"] = "smallest"
