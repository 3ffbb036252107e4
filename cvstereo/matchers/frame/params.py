"""The parameters of the frame-based cluster matcher (method ``frame``): fields, declared constraints and sets."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from cvstereo.frames.windows import WindowFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams
from cvstereo.matchers.constraints import param
from cvstereo.matchers.sets import ADAPTIVE_THESIS, AdaptiveDefaults
from cvstereo.model.polarity import Polarity

__all__ = ["WIDTH_EPS", "FrameClusterParams"]

#: Comparisons of integer widths against a float fraction (the frame matcher's width rule) tolerate the
#: rounding of 0.3 * w, so that the rule holds exactly at its edge (|10 - 7| <= 0.3 * 10 must pass although
#: 0.3 * 10 may round below 3).
WIDTH_EPS = 1e-9


@dataclass(frozen=True, kw_only=True)
class FrameClusterParams(BorderParams, SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-based cluster matcher (docs/algorithms.md section 1): the defaults are the thesis'
    constants, :attr:`adaptive` the default set; the window, Gaussian, signal-level and border fields are its bases'.

    Attributes
    ----------
    polarity : {"shared", "separate", "on", "off"}
        ON and OFF events in one frame (sum of signs), in two frames matched each on its own, ON only, OFF only.
    threshold : float
        Pixels with ``|filtered value| >= threshold`` form clusters (eq. 3.7, on the magnitude).
    width_tolerance : float
        Paired clusters count only if ``|wL - wR| <= width_tolerance * max(wL, wR)``.
    max_disparity : int
        Pairs with disparity outside ``[0, max_disparity]`` are dropped, px.
    anchor_camera : {0, 1}
        Where the matches are reported (:mod:`cvstereo.matchers.params`): its cluster pixels; default 0 (left).
    min_support : int
        0 (the thesis): every match stands. Otherwise a match stands only with at least this many other matches
        of its window within 2 px that agree on the disparity within 1 px (:mod:`cvstereo.matchers._shared.support`).
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="separate",
        why="ON and OFF events in one frame cancel where both fall in a window (a fan's blades): on Fan_disp8 "
            "shared gave 631 estimates, 74 % within 1 px of 8, separate 8358, 99 %; separate also covered more "
            "of the density sweep (0.35 vs 0.23 at thresholds x3)",
        params={**ADAPTIVE_THESIS, "threshold_scale": 0.42, "min_support": 3},
    )

    polarity: Polarity = "shared"
    threshold: float = param(1.2, gt=0, note="the thesis uses 1.2")
    width_tolerance: float = param(0.3, ge=0, note="the thesis uses 0.3")
    max_disparity: int = param(64, ge=0, note="e.g. 64")
    anchor_camera: Literal[0, 1] = param(0, note="0: left, 1: right")
    min_support: int = param(0, ge=0, note="0: off, the thesis")
