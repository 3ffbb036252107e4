"""The parameters of the thesis' five matchers: one frozen dataclass per matcher, with the thesis' defaults.

They live apart from the matchers so that the fast kernels (:mod:`cvstereo.matchers.frame.matcher`, ...)
and their reference twins (:mod:`calibration_free.reference`) both import them without the one importing
the other. Variants (ON/OFF handling, Gaussian or not) are values of their fields (docs/formats.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.frames.windows import WindowFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers._shared.signal_level import SignalLevelParams, level_params
from cvstereo.model.polarity import Polarity, check_polarity

#: Comparisons of integer widths against a float fraction (the frame matcher's width rule) tolerate the
#: rounding of 0.3 * w, so that the rule holds exactly at its edge (|10 - 7| <= 0.3 * 10 must pass although
#: 0.3 * 10 may round below 3).
WIDTH_EPS = 1e-9


@dataclass(frozen=True, kw_only=True)
class FrameClusterParams(BorderParams, SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-based cluster matcher (thesis defaults; docs/algorithms.md section 1).

    The window and Gaussian fields (window_us, gaussian, kernel_sigma, kernel_size) are those of
    :class:`~cvstereo.frames.windows.WindowFrameParams`, the relative-threshold fields (threshold_mode,
    threshold_scale, level_*) those of :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams`, the
    border rule's (border_horizon_us, border_rows) those of :class:`~cvstereo.matchers._shared.border.BorderParams`.

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

    polarity: Polarity = "shared"
    threshold: float = 1.2
    width_tolerance: float = 0.3
    max_disparity: int = 64
    anchor_camera: Literal[0, 1] = 0
    min_support: int = 0

    def __post_init__(self):
        super().__post_init__()
        where = type(self).__name__
        check_polarity(self.polarity, where)
        if not self.threshold > 0:
            raise ValueError(f"{where}: threshold must be > 0 (the thesis uses 1.2), got {self.threshold}.")
        if not self.width_tolerance >= 0:
            raise ValueError(f"{where}: width_tolerance must be >= 0 (the thesis uses 0.3), "
                             f"got {self.width_tolerance}.")
        if not self.max_disparity >= 0:
            raise ValueError(f"{where}: max_disparity must be >= 0 (e.g. 64), got {self.max_disparity}.")
        if self.anchor_camera not in (0, 1):
            raise ValueError(f"{where}: anchor_camera must be 0 (left) or 1 (right), got {self.anchor_camera}.")
        if int(self.min_support) != self.min_support or self.min_support < 0:
            raise ValueError(f"{where}: min_support must be a whole number >= 0 (0: off, the thesis), "
                             f"got {self.min_support}.")


@dataclass(frozen=True, kw_only=True)
class FrameAreaParams(BorderParams, SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-area SAD matcher (thesis defaults; docs/algorithms.md section 3).

    The window and Gaussian fields (window_us, gaussian, kernel_sigma, kernel_size) are those of
    :class:`~cvstereo.frames.windows.WindowFrameParams`, the relative-threshold fields (threshold_mode,
    threshold_scale, level_*) those of :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams`, the
    border rule's (border_horizon_us, border_rows) those of :class:`~cvstereo.matchers._shared.border.BorderParams`.

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
    """

    threshold: float = 2.0
    block: int = 5
    max_disparity: int = 64
    reference_camera: Literal[0, 1] = 1
    polarity: Polarity = "shared"
    lr_check: bool = False

    def __post_init__(self):
        super().__post_init__()
        where = type(self).__name__
        if not self.threshold > 0:
            raise ValueError(f"{where}: threshold must be > 0 (the thesis uses 2, or 4 without the Gaussian), "
                             f"got {self.threshold}.")
        if self.block < 1 or self.block % 2 == 0:
            raise ValueError(f"{where}: block must be a positive odd number (the thesis uses 5), got {self.block}.")
        if int(self.max_disparity) != self.max_disparity or self.max_disparity < 0:
            raise ValueError(f"{where}: max_disparity must be a whole number >= 0 (e.g. 64), "
                             f"got {self.max_disparity}.")
        if self.reference_camera not in (0, 1):
            raise ValueError(f"{where}: reference_camera must be 0 (left) or 1 (right), "
                             f"got {self.reference_camera}.")
        check_polarity(self.polarity, where)


@dataclass(frozen=True, kw_only=True)
class EventTimeParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-time matcher (thesis defaults), besides those of the dynamic frames and the
    relative-threshold fields of :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams` and the
    border rule's of :class:`~cvstereo.matchers._shared.border.BorderParams`.

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

    threshold: float = 0.8
    value_tolerance: float = 0.3
    value_tolerance_scale: float = 0.3
    time_window_us: int = 300
    row_tolerance: int = 1
    reference_camera: Literal[0, 1] = 1
    restrict_side: bool = True
    max_disparity: int = 64
    reference_read: Literal["before", "after"] = "before"
    time_window_scale: float = 0.0
    consensus_radius: int = 0
    consensus_window_us: int = 40_000
    consensus_min: int = 2
    value_units: Literal["own", "reference"] = "own"

    def __post_init__(self):
        super().__post_init__()
        if self.value_units not in ("own", "reference"):
            raise ValueError(f"value_units must be 'own' or 'reference', got {self.value_units!r}.")
        if self.reference_read not in ("before", "after"):
            raise ValueError(f"reference_read must be 'before' or 'after', got {self.reference_read!r}.")
        if self.reference_camera not in (0, 1):
            raise ValueError(f"reference_camera must be 0 (left) or 1 (right), got {self.reference_camera}.")
        for name in ("threshold", "value_tolerance", "value_tolerance_scale", "time_window_us", "row_tolerance",
                     "max_disparity", "time_window_scale", "consensus_radius", "consensus_window_us",
                     "consensus_min"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}.")

    @property
    def paced(self) -> bool:
        """Whether the time window follows the pace of the events (``time_window_scale``, relative mode)."""
        return self.relative and self.time_window_scale > 0

    def pace_params(self) -> SignalLevelParams:
        """The estimator of the pace: the signal level's windows and warm-up, the median, no floor."""
        return dataclasses.replace(level_params(self), level_quantile=0.5, level_floor=0.0)

    def value_gain(self, levels) -> float:
        """The factor D2 is multiplied by before the value test (``value_units``), given the cameras' levels
        in force (NaN while warming up): the reference camera's level over the other's, or 1."""
        ref = self.reference_camera
        if not (self.relative and self.value_units == "reference"):
            return 1.0
        mine, other = float(levels[ref]), float(levels[1 - ref])
        return mine / other if np.isfinite(mine) and np.isfinite(other) and other > 0 else 1.0

    def max_time_window_us(self) -> int:
        """The longest window that can be in force: intervals longer than ``level_window_us`` are not counted."""
        if not self.paced:
            return int(self.time_window_us)
        return max(int(self.time_window_us), int(self.time_window_scale * self.level_window_us))


@dataclass(frozen=True, kw_only=True)
class EventAreaParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-area matcher (thesis defaults), besides those of the dynamic frames and the
    relative-threshold fields of :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams` and the
    border rule's of :class:`~cvstereo.matchers._shared.border.BorderParams`.

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
    """

    aliases: ClassVar[dict] = {"max_sad": "max_cost"}

    threshold: float = 1.2
    block: int = 5
    max_disparity: int = 64
    max_cost: float = 1000.0
    cost_scale: float = 0.0
    sad_frames: Literal["own", "all"] = "own"
    own_ratio: float = 0.0
    uniqueness: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        if self.block < 1 or self.block % 2 == 0:
            raise ValueError(f"block must be odd and positive, got {self.block}.")
        for name in ("threshold", "max_disparity", "cost_scale", "own_ratio", "uniqueness"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}.")
        if self.sad_frames not in ("own", "all"):
            raise ValueError(f"sad_frames must be 'own' (the thesis) or 'all', got {self.sad_frames!r}.")

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


@dataclass(frozen=True, kw_only=True)
class EventVectorParams(BorderParams, SignalLevelParams, DynamicFrameParams):
    """Parameters of the event-vector matcher (thesis defaults), besides those of the dynamic frames and the
    relative-threshold fields of :class:`~cvstereo.matchers._shared.signal_level.SignalLevelParams` and the
    border rule's of :class:`~cvstereo.matchers._shared.border.BorderParams`.

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

    threshold: float = 0.8
    require_candidate_threshold: bool = True
    max_disparity: int = 64
    max_cost: float = 1000.0
    run_ends: bool = False
    cost_ratio: float = 0.0
    cost_slack: float = 0.0
    tie_break: Literal["smallest", "centre"] = "smallest"

    def __post_init__(self):
        super().__post_init__()
        for name in ("threshold", "max_disparity", "cost_ratio", "cost_slack"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}.")
        if self.tie_break not in ("smallest", "centre"):
            raise ValueError(f"tie_break must be 'smallest' or 'centre', got {self.tie_break!r}.")
