"""The parameters of the event-area matcher (method ``event-area``): fields, declared constraints and sets."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams
from cvstereo.matchers.constraints import param
from cvstereo.matchers.sets import ADAPTIVE_THESIS, AdaptiveDefaults

__all__ = ["EventAreaParams"]


@dataclass(frozen=True, kw_only=True)
class EventAreaParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-area matcher (thesis defaults; dynamic-frame, signal-level and border fields inherited).

    Attributes
    ----------
    threshold : float
        Minimum ``|D|`` at the event's pixel (1.2; 4 for single-pixel updates).
    block : int
        Odd side of the compared patches (thesis: 5).
    max_disparity : int
        Largest disparity searched.
    max_cost : float
        A match needs a SAD below this (Algorithm 3's initial minimum; old name: ``max_sad``).
    cost_scale : float
        0 (the thesis): ``max_cost`` alone bounds the SAD. Otherwise the SAD must also lie below ``cost_scale``
        times the block's pixel count times the threshold in force for the event's camera
        (:meth:`max_costs`): a bound on the mean difference per pixel relative to the signal level, since the
        SAD of a wrong patch grows with the dynamic-frame values as the threshold does.
    sad_frames : {"own", "all"}
        ``own`` (the thesis): the SAD compares the event's own dynamic frame with the other camera's frame of
        the same slot. ``all``: it sums over all of a camera's frames, which with ``polarity="separate"`` is
        the OFF and the ON frame: ON and OFF events cannot cancel (as in a shared frame, a fan's blades), yet
        both inform the match (an edge pair of a bar, which one polarity alone leaves ambiguous). With one
        frame per camera both are the same.
    own_ratio : float
        0 (the thesis): off. Otherwise the SAD must also lie below ``own_ratio`` times the sum of |D| over the
        event's own patch (the frames compared), which is the SAD of an empty candidate patch: the match must
        explain part of the patch.
    uniqueness : float
        0 (the thesis): off. Otherwise a match is dropped when a candidate more than 1 px from the winner has a
        SAD at most ``1 + uniqueness`` times the winner's (ambiguous), as OpenCV's ``uniquenessRatio`` / 100.
    value_units : {"own", "camera", "polarity"}
        ``own`` (the thesis): each camera's frame values as accumulated. Otherwise the other camera's values are
        brought into the units of the event's camera before the SAD: two sensors of different contrast thresholds
        fire different numbers of events at one edge, and their frames differ in amplitude by about the ratio of
        the thresholds, which the SAD would count as a mismatch. ``camera``: one factor per camera, the ratio of
        the two cameras' thresholds in force; ``polarity``: one per frame (OFF and ON apart with separate frames),
        the ratio of the thresholds each frame's own signal level implies
        (:class:`~cvstereo.matchers._shared.frame_gains.FrameGains`).
    """

    aliases: ClassVar[dict] = {"max_sad": "max_cost"}

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="gaussian",
        why="the 3x3 update spreads each event over its neighbours, so a 5x5 block holds a signal after a few "
            "events; with single-pixel updates the density sweep and Fan_disp8 gave (almost) nothing; adaptive "
            "sums the SAD over separate OFF and ON frames (one shared frame cancels a fan's blades; the own "
            "polarity's frame alone confuses a bar's edge with the next bar's) and drops matches that explain "
            "little of the patch or have a rival (they made most of the density sweep's bad2 at thresholds x3), and "
            "compares the other camera's frames in the event's camera's units, one gain per camera (sensors of "
            "other contrast thresholds; bench/results/thesis-generalization.md; one gain per frame cost the "
            "no-gaussian variant a third of its correct answers on movingPersons); "
            "the no-gaussian variant has the same scale (at 1.5 x it kept 288 "
            "estimates on movingPersons, now 1471, of which 1467 within 1 px of 13: 71 % of the thesis set's 2079)",
        params={**ADAPTIVE_THESIS, "threshold_scale": 0.5, "level_floor": 0.5, "cost_scale": 0.6,
                "polarity": "separate", "sad_frames": "all", "own_ratio": 0.6, "uniqueness": 0.2,
                "value_units": "camera"},
    )

    threshold: float = param(1.2, ge=0)
    block: int = param(5, side=True, note="the thesis uses 5")
    max_disparity: int = param(64, ge=0)
    max_cost: float = 1000.0
    cost_scale: float = param(0.0, ge=0, note="0: off, the thesis")
    sad_frames: Literal["own", "all"] = "own"
    own_ratio: float = param(0.0, ge=0, note="0: off, the thesis")
    uniqueness: float = param(0.0, ge=0, note="0: off, the thesis")
    value_units: Literal["own", "camera", "polarity"] = "own"


    @property
    def compared_frames(self) -> int:
        """How many frames per camera one SAD sums over (2 only for ``sad_frames="all"`` with separate frames)."""
        return 2 if self.sad_frames == "all" and self.polarity == "separate" else 1

    def max_costs(self, thresholds: np.ndarray) -> np.ndarray:
        """The SAD bound of each camera's events, given the (2,) thresholds in force (see ``cost_scale``): per
        value compared, of ``block**2`` times :attr:`compared_frames` values."""
        costs = np.full(2, float(self.max_cost))
        if self.cost_scale > 0:
            n_values = self.block * self.block * self.compared_frames
            costs = np.minimum(costs, self.cost_scale * n_values * np.asarray(thresholds, float))
        return costs
