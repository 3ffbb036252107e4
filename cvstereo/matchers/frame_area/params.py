"""The parameters of the frame-area SAD matcher (method ``frame-area``): fields, declared constraints and sets."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from cvstereo.frames.windows import WindowFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams
from cvstereo.matchers.constraints import param
from cvstereo.matchers.sets import ADAPTIVE_THESIS, AdaptiveDefaults
from cvstereo.model.polarity import Polarity

__all__ = ["FrameAreaParams"]


@dataclass(frozen=True, kw_only=True)
class FrameAreaParams(BorderParams, SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-area SAD matcher (docs/algorithms.md section 3), the thesis' values as defaults, with
    the window and Gaussian of :class:`~cvstereo.frames.windows.WindowFrameParams`, the relative thresholds of
    :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams` and the border rule of
    :class:`~cvstereo.matchers._shared.border.BorderParams`.

    Attributes
    ----------
    threshold : float
        Reference pixels with ``|value| >= threshold`` are searched (2, or 4 without the Gaussian).
    block : int
        Odd side of the SAD block, and of the neighbourhood the winner is written into.
    max_disparity : int
        Largest disparity searched, px (the search also stops where the block would leave the sensor).
    reference_camera : {0, 1}
        The camera scanned (:mod:`cvstereo.matchers.params`), pixel by pixel; default 1 (right, the thesis' eDVS1).
    polarity : {"shared", "separate", "on", "off"}
        ``shared`` (the thesis): one signed frame per camera. ``separate``: an OFF and an ON frame per camera,
        each scanned and matched on its own (:func:`cvstereo.frames.accumulate.polarity_frames`), so that ON and OFF
        events of one window cannot cancel (a fan's blades); ``on`` / ``off``: that polarity only.
    lr_check : bool
        False (the thesis): every scanned winner stands. True: the other camera's frame is scanned too, as the
        reference, and a pixel keeps its disparity d only where the other scan's disparity at the pixel it
        names (``x + d`` in the left frame, ``x - d`` in the right) lies within 1 px of d (left-right check).
    value_units : {"own", "camera", "polarity"}
        ``own`` (the thesis): each camera's frame as accumulated. Otherwise the other camera's frame is brought
        into the scanning camera's units before the SAD (the reference camera's; the left-right check's scan the
        other way by the inverse): two sensors of different contrast thresholds fire different numbers of events
        at one edge, and the SAD would count the difference in amplitude. ``camera``: one factor, the ratio of
        the two cameras' thresholds in force; ``polarity``: one per frame (OFF and ON apart with separate frames),
        the ratio of the thresholds each frame's own signal level implies
        (:class:`~cvstereo.matchers._shared.frame_gains.FrameGains`).
    uniqueness : float
        0 (the thesis): off. Otherwise a search whose winner has a rival, a candidate more than 1 px away with a
        SAD at most ``1 + uniqueness`` times the winner's, writes no disparity into its block (ambiguous: a
        repeating texture, a horizontal edge), as event-area's check of the same name and OpenCV's
        ``uniquenessRatio`` / 100 (:mod:`cvstereo.matchers._shared.uniqueness`).
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="gaussian",
        why="filtered frames give the SAD smooth blocks; unfiltered ones covered a third as much of the density "
            "sweep (0.09 vs 0.42 at x1) and were half as often right on Fan_disp8; adaptive matches OFF and ON "
            "frames apart (a fan's blades cancel in one frame) and "
            "keeps disparities the left-right check confirms; it compares the other camera's frame in the reference "
            "camera's units, one gain per frame (sensors of other contrast thresholds, which differ by polarity; "
            "bench/results/thesis-generalization.md); the no-gaussian variant has the same scale (the level "
            "is that of its own unfiltered values; at 1.6 x it kept 556 estimates on movingPersons against the thesis "
            "set's 4613, now 3720, of which 3670 within 1 px of 13: 111 % of the thesis set's 3320); it drops a search "
            "whose winner has a rival within 1.2 x its SAD more than 1 px away (uniqueness, as event-area: a "
            "repeating texture or a horizontal edge fits many disparities), which on suite v2's tuning recordings "
            "dropped about half of the wrong answers for a fifth of the right ones; 0.2 is the largest ratio tried "
            "that kept every family's median coverage above 5 % (bench/results/uniqueness-frame-area.md)",
        params={**ADAPTIVE_THESIS, "threshold_scale": 0.6, "polarity": "separate", "lr_check": True,
                "value_units": "polarity", "uniqueness": 0.2},
    )

    threshold: float = param(2.0, gt=0, note="the thesis uses 2, or 4 without the Gaussian")
    block: int = param(5, side=True, note="the thesis uses 5")
    max_disparity: int = param(64, ge=0, note="e.g. 64")
    reference_camera: Literal[0, 1] = param(1, note="0: left, 1: right")
    polarity: Polarity = "shared"
    lr_check: bool = False
    value_units: Literal["own", "camera", "polarity"] = "own"
    uniqueness: float = param(0.0, ge=0, note="0: off, the thesis")
