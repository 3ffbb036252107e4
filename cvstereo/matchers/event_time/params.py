"""The parameters of the event-time matcher (method ``event-time``): fields, declared constraints and sets."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams, level_params
from cvstereo.matchers.constraints import param
from cvstereo.matchers.sets import ADAPTIVE_THESIS, AdaptiveDefaults

__all__ = ["EventTimeParams"]


@dataclass(frozen=True, kw_only=True)
class EventTimeParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-time matcher: its own below, those of the dynamic frames, the signal level and the
    border rule from its bases; thesis defaults.

    Attributes
    ----------
    threshold : float
        Minimum ``|D|`` at the event's pixel, in both frames.
    value_tolerance : float
        Maximum ``|D1 - D2|``.
    value_tolerance_scale : float
        In relative mode, the maximum ``|D1 - D2|`` as a multiple of the reference camera's signal level.
    time_window_us : int
        Maximum ``|t2 - t|``.
    row_tolerance : int
        Maximum ``|y2 - y|`` (corresponding events may lie one row apart).
    reference_camera : {0, 1}
        The camera scanned (:mod:`cvstereo.matchers.params`), event by event; default 1 (right, the thesis' eDVS1).
    restrict_side : bool
        Keep only candidates on the geometrically possible side.
    max_disparity : int
        Maximum ``|x2 - x|``.
    reference_read : {"before", "after"}
        When D1 is read for the threshold and value tests: ``before`` e1 updates its frame (the thesis), or
        just ``after``, as D2 is read after e2's own update. ``before`` makes D2 - D1 of two corresponding
        events one update larger than it is (one event's centre weight, 0.41), which is small against the values
        of a dense edge but as large as the values themselves when an edge gives a pixel one or two events.
    time_window_scale : float
        0 (the thesis): the window is ``time_window_us``. Otherwise, in relative mode, the window in force is
        this many times the other camera's pace (:meth:`pace_params`): the median time from an event back to
        the last earlier event of its polarity in its 3x3 neighbourhood (intervals up to ``level_window_us``),
        over the last level windows, estimated as the signal level is; ``time_window_us`` during warm-up, and
        never less: the sensors' latency jitter does not shrink with a fast pace (on a 640x480 sensor the pace
        fell to 0.3 ms and a shorter window lost a quarter of the coverage). With fewer events per edge (or a
        slower edge) the corresponding events of the two cameras lie further apart in time, and so do the
        events of one edge: a fixed window keeps ever fewer true partners.
    consensus_radius : int
        0 (the thesis): off. Otherwise a veto: the last match of each reference pixel within this many px
        (own pixel included) counts when at most ``consensus_window_us`` old; where at least ``consensus_min``
        of them, and more than half, lie within 1 px of their lower median m and the smallest distance lies more
        than 1 px from m, the candidate nearest m is taken if within 1 px of it, else the event is not matched.
        Without recent neighbour matches a match stands, so sparse or large sensors keep their coverage.
    consensus_window_us : int
        How old a neighbour's last match may be to count (``consensus_radius``).
    consensus_min : int
        How many recent neighbour matches within 1 px of their median make a consensus (``consensus_radius``).
    value_units : {"own", "reference"}
        ``own`` (the thesis): D2 is compared with D1 as its camera gives it. ``reference``: in relative mode, once
        both cameras have a signal level, D2 is first multiplied by the reference camera's level over the other's,
        so that the value test compares the two cameras' events in one unit: sensors of different contrast
        thresholds give one edge D values several times apart (a camera with 4x the events of the other), and
        the test then passed look-alikes and refused the true partner.
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="separate",
        why="ON and OFF events cancel in a shared dynamic frame as in a shared frame: on Fan_disp8 separate "
            "frames gave 15932 estimates, 84 % within 1 px of 8, shared 2180, 73 % (when the variant was chosen, "
            "before the checks below); adaptive reads D1 after "
            "e1's update as D2 is read (reading it before put one event's weight between corresponding values: "
            "NSTlogo gave nothing) and lets the time window follow the events' pace (a fixed 300 us kept 20 % of "
            "the true partners at thresholds x1, 6 % at x3); where the recent matches within 4 px agree on "
            "another disparity it takes the candidate nearest theirs or none (consensus_radius: the nearest "
            "partner was a look-alike one texture period off in 10-12 % of the matches on 1arm-50cm; it cut bad2 "
            "there and made more cells agree when every second event is dropped), which lets the threshold fall "
            "from 0.65 to 0.55 x the level, covering more of the density sweep and Fan_disp8; it compares D2 with "
            "D1 in the reference camera's units (value_units: the cameras' level ratio; sensors of different "
            "contrast thresholds gave one edge D values several times apart), which raised coverage and lowered "
            "bad2 on the objects of suite v2's tuning half at 346x260",
        params={**ADAPTIVE_THESIS, "threshold_scale": 0.55, "value_tolerance_scale": 0.4, "reference_read": "after",
                "time_window_scale": 0.5, "consensus_radius": 4, "value_units": "reference"},
    )

    threshold: float = param(0.8, ge=0)
    value_tolerance: float = param(0.3, ge=0)
    value_tolerance_scale: float = param(0.3, ge=0)
    time_window_us: int = param(300, ge=0)
    row_tolerance: int = param(1, ge=0)
    reference_camera: Literal[0, 1] = param(1, note="0: left, 1: right")
    restrict_side: bool = True
    max_disparity: int = param(64, ge=0)
    reference_read: Literal["before", "after"] = "before"
    time_window_scale: float = param(0.0, ge=0)
    consensus_radius: int = param(0, ge=0, note="0: off, the thesis")
    consensus_window_us: int = param(40_000, ge=0)
    consensus_min: int = param(2, ge=0)
    value_units: Literal["own", "reference"] = "own"


    @property
    def paced(self) -> bool:
        """Whether the time window follows the pace of the events (``time_window_scale``, relative mode)."""
        return self.relative and self.time_window_scale > 0

    def pace_params(self) -> SignalLevelParams:
        """The estimator of the pace: the signal level's windows and warm-up, the median, no floor."""
        return dataclasses.replace(level_params(self), level_quantile=0.5, level_floor=0.0)

    @property
    def scales_values(self) -> bool:
        """Whether D2 is brought into the reference camera's units (``value_units``, relative mode only)."""
        return self.relative and self.value_units == "reference"

    def value_gain(self, levels) -> float:
        """The factor D2 is multiplied by before the value test (``value_units``), given the cameras' levels
        in force (NaN while warming up): the reference camera's level over the other's, or 1.

        Callers ask for it only where :attr:`scales_values` holds (1 otherwise): in absolute mode the signal
        level is not otherwise estimated, and estimating it per window would cost every event."""
        if not self.scales_values:
            return 1.0
        ref = self.reference_camera
        mine, other = float(levels[ref]), float(levels[1 - ref])
        return mine / other if np.isfinite(mine) and np.isfinite(other) and other > 0 else 1.0

    def max_time_window_us(self) -> int:
        """The longest window that can be in force: intervals longer than ``level_window_us`` are not counted."""
        if not self.paced:
            return int(self.time_window_us)
        return max(int(self.time_window_us), int(self.time_window_scale * self.level_window_us))
