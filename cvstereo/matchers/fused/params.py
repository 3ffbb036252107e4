"""Parameters of the fused matcher (:mod:`cvstereo.matchers.fused.matcher`), apart so that the kernel and the reference
both import them without importing each other."""

from __future__ import annotations

from dataclasses import dataclass

from cvstereo.frames.windows import check_window_us

__all__ = ["FusedParams"]

#: The next window's prior is the answers of uncertainty at most this (the consistent ones) whatever
#: ``max_uncertainty`` keeps: a run with ``max_uncertainty=1`` (every answer, ranked) then gives the default run's
#: matches as its answers of uncertainty at most 0.5, and its ranking is that of the default output.
PRIOR_MAX_UNCERTAINTY = 0.5
#: The partner test (``border_rows``) judges a band of rows only when it has at least this many consistent answers:
#: the median of fewer is too often that of a few wrong ones.
BORDER_MIN_ANSWERS = 8


@dataclass(frozen=True)
class FusedParams:
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
    max_uncertainty : float
        Matches whose uncertainty exceeds this are dropped. Uncertainty = half the ratio of the best to the
        second-best aggregated cost more than 1 px away (0..0.5), plus 0.5 where the left-right check, the
        occlusion test or the partner test fails; the default 0.5 keeps the consistent matches, 1 keeps all.
    """

    window_us: int = 40_000
    tau_us: int = 80_000
    support_radius: int = 1
    max_disparity: int = 63
    row_tolerance: int = 1
    p1: float = 3.0
    p2: float = 12.0
    path_radius: int = 3
    sgm_paths: int = 4
    temporal_weight: float = 0.5
    lr_tolerance: int = 1
    fill_radius: int = 12
    fill_confirms: bool = True
    subpixel: bool = True
    min_neighbours: int = 2
    isolated_max_uncertainty: float = 0.1
    occlusion_margin: float = 1.0
    occlusion_support: int = 2
    border_rows: int = 2
    max_uncertainty: float = 0.5

    def __post_init__(self):
        where = type(self).__name__
        check_window_us(self.window_us, where)
        if int(self.tau_us) != self.tau_us or self.tau_us <= 0:
            raise ValueError(f"{where}: tau_us must be a positive whole number of microseconds (e.g. 80000), "
                             f"got {self.tau_us}.")
        if not 0 <= self.support_radius <= 5:
            raise ValueError(f"{where}: support_radius must be in 0..5 (e.g. 1), got {self.support_radius}.")
        if int(self.max_disparity) != self.max_disparity or not 1 <= self.max_disparity <= 255:
            raise ValueError(f"{where}: max_disparity must be a whole number in 1..255 (e.g. 63), "
                             f"got {self.max_disparity}.")
        if not 0 <= self.row_tolerance <= 3:
            raise ValueError(f"{where}: row_tolerance must be in 0..3 (e.g. 1), got {self.row_tolerance}.")
        if not (self.p1 >= 0 and self.p2 >= self.p1):
            raise ValueError(f"{where}: need 0 <= p1 <= p2 (e.g. p1=3, p2=12), got p1={self.p1}, p2={self.p2}.")
        if not 0 <= self.path_radius <= 5:
            raise ValueError(f"{where}: path_radius must be in 0..5 (e.g. 3), got {self.path_radius}.")
        if self.sgm_paths not in (0, 2, 4):
            raise ValueError(f"{where}: sgm_paths must be 0, 2 or 4, got {self.sgm_paths}.")
        if not self.temporal_weight >= 0:
            raise ValueError(f"{where}: temporal_weight must be >= 0 (0: off), got {self.temporal_weight}.")
        if int(self.lr_tolerance) != self.lr_tolerance or self.lr_tolerance < -1:
            raise ValueError(f"{where}: lr_tolerance must be a whole number >= -1 (-1: off), "
                             f"got {self.lr_tolerance}.")
        if not 0 <= self.fill_radius <= 16:
            raise ValueError(f"{where}: fill_radius must be in 0..16 (0: off), got {self.fill_radius}.")
        if not 1 <= self.min_neighbours <= 9:
            raise ValueError(f"{where}: min_neighbours must be in 1..9 (1: off), got {self.min_neighbours}.")
        if not 0 <= self.isolated_max_uncertainty <= 1:
            raise ValueError(f"{where}: isolated_max_uncertainty must be in [0, 1] (0: isolated pixels never answer), "
                             f"got {self.isolated_max_uncertainty}.")
        if not (self.occlusion_margin == -1 or 0 <= self.occlusion_margin <= 16):
            raise ValueError(f"{where}: occlusion_margin must be -1 (off) or in [0, 16] px (e.g. 1), "
                             f"got {self.occlusion_margin}.")
        if int(self.occlusion_support) != self.occlusion_support or not 1 <= self.occlusion_support <= 8:
            raise ValueError(f"{where}: occlusion_support must be a whole number in 1..8 (e.g. 2), "
                             f"got {self.occlusion_support}.")
        if int(self.border_rows) != self.border_rows or not -1 <= self.border_rows <= 16:
            raise ValueError(f"{where}: border_rows must be a whole number in -1..16 (-1: off; e.g. 2), "
                             f"got {self.border_rows}.")
        if not 0 < self.max_uncertainty <= 1:
            raise ValueError(f"{where}: max_uncertainty must be in (0, 1] (0.5: consistent matches, 1: all), "
                             f"got {self.max_uncertainty}.")
