"""The fused matcher (method ``fused``): the thesis' event cues in a semi-global matcher, with an uncertainty.

Design, part by part, with the reason for each (bench/results/fused.md measures each part's contribution):

1. **Windows on the absolute clock** (``window_us``, 40 ms) anchored at the left camera's pixels that saw
   events, stamped with the window's end: the same cells as the OpenCV baselines and dv-processing
   (:mod:`cvstereo.matchers.opencv.matcher`), so that coverage, bad2 and false rate compare on equal terms; and a window
   is matched once from all its events, which makes the result independent of the packet cuts.
2. **Features: two time surfaces per camera**, one per polarity, ``max(0, 1 - (t_end - t_last) / tau)``
   (Lagorce et al. 2017's surfaces with a linear decay; Ieng et al. 2018 and Zhou et al. 2018 match
   event stereo on them). They carry the thesis' cues: *event-time* (corresponding pixels fire at the same
   time in both cameras, so their surfaces agree; an edge seen earlier has decayed further) and *polarity*
   (ON and OFF never match each other, thesis 3.4's separate handling). Unlike a count frame, a surface
   keeps the *order* of events within and across windows, which is what tells two nearby edges apart.
   Each surface is summed over a ``(2r+1)^2`` support square (``support_radius``): the frame matchers'
   Gaussian (thesis eq. 3.6) in its cheapest form, done once per image rather than once per disparity.
3. **Signal level** (:func:`cvstereo.matchers.fused.signal.signal_level`): each camera's features are
   divided by a robust level of the window (the 90th percentile of its non-zero values), so that costs and
   penalties mean the same at any event density and for two sensors of different sensitivity. Every value the
   matcher compares (``p1``, ``p2``, ``temporal_weight``) is thus in units of the level: it has no absolute
   threshold for :mod:`cvstereo.matchers._shared.signal_level` to replace. That module's causal one-second level would
   steady the
   level of sparse windows, but its quantile over 25 windows' values costs about as much as a whole window's
   matching; it is worth adopting once that estimate is incremental.
4. **Cost**: the L1 distance of the two cameras' feature vectors at ``(x, y)`` and ``(x - d, y + dy)``, the
   least over ``|dy| <= row_tolerance``: the thesis' event-time matcher's row tolerance, because real rigs
   are off by about a row (thesis 3.2; the simulator's rig by one); :mod:`cvstereo.geometry.rigcorrect` corrects
   larger offsets before matching.
5. **Temporal coherence** (``temporal_weight``): the cost grows with the distance (capped at 2 px) from the
   pixel's disparity in the previous window; objects move little in 40 ms, and the prior resolves
   repetitive texture that one window leaves ambiguous (the thesis' event-by-event continuity).
6. **Semi-global aggregation** (Hirschmüller 2008; ``sgm_paths`` 2 or 4, ``p1``, ``p2``) along the rows and
   columns of *active* pixels only: the left pixels within ``path_radius`` px of an event of the window.
   Event images are sparse, so paths end where nothing happened instead of carrying the cost of empty
   background as SGBM does, which is where SGBM's matches at noise and background come from; and the work
   is proportional to the active pixels, not the sensor. The sums of the paths live in a compact
   (pixels x disparities) float32 array; costs and paths are float32 too (:mod:`cvstereo.matchers.fused._kernels`
   says why).
7. **Winner, uniqueness and uncertainty**: the disparity of least aggregated cost. Its *uncertainty* is half
   the ratio of that cost to the best cost more than 1 px away (0: unambiguous, 0.5: a tie; the uniqueness
   ratio of block matching as a number), plus 0.5 where the left-right check (part 8), the occlusion test
   (part 9) or the partner test (part 10) fails, so that every inconsistent, hidden or unpartnered match ranks
   behind every consistent one; the segment test (part 11) puts the consistent answers of small segments between
   the two. Users threshold it (``max_uncertainty``, default 0.5: the consistent matches) or keep the most
   certain ones (:meth:`FusedMatcher.take_uncertainty` gives it per match).
8. **Left-right consistency** (``lr_tolerance``): the right pixel the winner points to must choose the same
   disparity (within 1 px) from the same aggregated volume; occlusions and half-matched edges fail it.
   A winner that fails it takes the median of the consistent answers within ``fill_radius`` (12) px (when
   there are any), the usual filling of SGM's invalidated pixels (Hirschmüller 2008, section 3.4) restricted
   to the event pixels; it keeps its high uncertainty, so it only counts when a user asks for high coverage.
   A winner that agrees with that median (within ``lr_tolerance``) is *confirmed* instead (``fill_confirms``):
   it keeps its own disparity and loses the penalty, since a failed check is then more often the right pixel's
   near-tie than a wrong left winner (Fan_disp8: 99.4 % of them right; on the robustness suite it raised the
   coverage at almost the same bad2).
9. **Occlusion test** (``occlusion_margin``, ``occlusion_support``): the left view's half-occlusion, the
   background just left of a nearer surface's left edge, often passes the left-right check, and where it fails
   it (the right pixel prefers the nearer surface's larger disparity, Hirschmüller's sign of an occlusion) it is
   mostly confirmed by its background neighbours (part 8). The answers themselves show it: when answers further
   right in the row map to right pixels at least ``occlusion_margin`` (1) px left of this answer's
   (``x' - d' <= x - d - margin``, so they are nearer), their rays cross this answer's in front of the right
   camera and its point is hidden; it gets the left-right penalty 0.5. A surface crosses with several answers,
   an outlier with one (a noise event's, at a random disparity, would hide a run of its row as long as its
   disparity): ``occlusion_support`` (2) answers must cross (with one, noise cost coverage on the robustness
   suite; with two, little). Both sides of the test are the answers of
   uncertainty at most 0.5; the next window's prior is the answers before the test (a hidden pixel's
   disparity is still the best guess there: taking the prior after it, the motorcycle's bad2 is 16.9 % instead
   of 16.2 %). Motorcycle (2 s clip of bench_fused): 3.1 % of the answers flagged, 39 % of them left-right
   consistent and 61 % confirmed; 26 % of them on pixels without truth (all answers: 10.3 %) and 45 % of the
   rest off by more than 2 px (17 %); the test lowers bad2 at some cost in coverage. A false-rate gain on that
   clip is the clip's: most pixels without truth are surfaces the Middlebury scanner did not measure, not
   occlusions, and with other pan phases the false rate stays about the same while bad2 falls.
10. **Partner test** (``border_rows``): a left pixel at column ``x`` whose surface lies at disparity ``D > x`` has
    its true partner outside the right image (``x - D < 0``), yet the search only offers partners inside it (or
    the zeros beyond its edge), so such a pixel answers with the best of the wrong ones, often 0 px, and
    often with a clear minimum (the generalization suite's tuning half: 11 % of all answers on a slanted ground
    plane at 346x260, 95 % of them wrong, ranked in the middle by the ratio). ``D`` is read from the answers
    themselves: the median disparity of the consistent answers in the pixel's band of rows (``y +- border_rows``)
    of the window, where it has at least 8 (a median of fewer is too often that of a few wrong ones); an answer
    left of it gets the left-right penalty 0.5 and is not the next window's prior. The median, not a lower
    quantile: the strip's own wrong answers (smaller disparities) are in the band too. Tuning half, ground plane
    at 346x260: 91 % of the answers without a partner caught, 99 % of the flagged ones without one; the default
    output's bad2 falls at a small cost in coverage.
11. **Segment test** (``segment_min_answers``): the consistent answers left after parts 9 and 10 form segments
    (answers within 2 px of each other whose disparities differ by at most 1 px, joined one to the next); an answer
    whose segment has fewer than ``segment_min_answers`` (e.g. 50 at 128 px wide, scaled with the width) is ranked
    behind the other consistent answers and before the inconsistent ones (its uncertainty ``u`` becomes
    ``0.5 + u / 2``, an inconsistent answer's ``0.75 + (u - 0.5) / 2``), unless its match is clear enough to answer
    alone (uncertainty below ``isolated_max_uncertainty``, as in the noise filter, part 13). A surface's edges
    give long runs of like answers, a wrong answer's neighbours rarely agree with it: OpenCV's speckle filter
    (which dv-processing's matcher runs) on the event answers, in the uncertainty instead of a deletion, so that
    users who keep every answer still have them. The next window's prior is the answers before the test. Off by
    default (``segment_min_answers=0``): 50, chosen on the generalization suite's tuning half, did not carry to its
    evaluation half (bench/results/fused-segments.md); it is there for users who want fewer, surer answers.
12. **Sub-pixel refinement** (``subpixel``): a parabola through the aggregated costs at ``d - 1, d, d + 1``.
13. **Noise filter** (``min_neighbours``): a pixel answers only if another pixel of its 3x3 neighbourhood saw
    an event in the last two windows, or if its match is clear (uncertainty below
    ``isolated_max_uncertainty``, 0.1). Isolated events are mostly noise; the thesis' event matchers owe
    their low false rate to the same kind of local support. But a sparse real sensor has isolated signal too
    (Fan_disp8: 99 % of the isolated pixels' matches are right), and a clear, left-right consistent match is
    evidence of its own; the cost is a higher false rate on simulated noise (robustness suite noise-1hz and
    threshold-x3, still below SGBM's and dv-semidense's).

The numba kernels are in :mod:`cvstereo.matchers.fused._features` and :mod:`cvstereo.matchers.fused._kernels`;
the plain reference in :mod:`cvstereo.matchers.fused.reference` gives identical matches (tests/test_fused.py).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numba import njit

from cvstereo._threads import both_cameras
from cvstereo.frames.windows import FrameMatcher, Window
from cvstereo.matchers.fused._constants import CONSISTENT_MAX_UNCERTAINTY, LR_PENALTY, RECENT_WINDOWS, SEGMENT_TIER
from cvstereo.matchers.fused._features import (
    NEVER,
    divide,
    nonzero_values,
    surface_features,
    window_masks_parallel,
)
from cvstereo.matchers.fused._features import window_masks as window_masks_serial
from cvstereo.matchers.fused._kernels import (
    KernelScratch,
    kernel_params,
    match_features,
    match_features_parallel,
    way_for,
)
from cvstereo.matchers.fused._parallel import chunks_for
from cvstereo.matchers.fused._partner import unpartnered, unpartnered_parallel
from cvstereo.matchers.fused._segments import segment_min_for, small_segments
from cvstereo.matchers.fused.params import PRIOR_MAX_UNCERTAINTY, FusedParams
from cvstereo.matchers.fused.signal import level_of
from cvstereo.model.matches import MATCH_DTYPE

#: Planes of the kernel's per-pixel storage: path sums, costs (split passes), the backward pass's sums or the column
#: paths from below (KernelScratch).
KERNEL_PLANES = 3

__all__ = ["FusedMatcher", "Scratch", "WindowState", "finish_window", "occluded", "unpartnered"]


@njit(cache=True, nogil=True)
def occluded(x, y, disparity, uncertainty, margin, support):
    """The occlusion test (design part 9): which answers nearer answers further right in the row hide from the
    right camera.

    Parameters
    ----------
    x, y : (M,) int ndarrays
        Answers in raster order (row, then column), as :func:`~cvstereo.matchers.fused._kernels.match_features`
        returns them.
    disparity, uncertainty : (M,) float64 ndarrays
    margin : float
        ``occlusion_margin``.
    support : int
        ``occlusion_support``.

    Returns
    -------
    (M,) bool ndarray
        True for an answer of uncertainty at most 0.5 when at least ``support`` such answers of its row, further
        right, have ``x' - d' <= x - d - margin``.
    """
    m = x.size
    out = np.zeros(m, np.bool_)
    lowest = np.empty(support)  # the least x' - d' of the row's answers right of answer i, ascending
    for i in range(m - 1, -1, -1):
        if i == m - 1 or y[i] != y[i + 1]:
            lowest[:] = np.inf
        if uncertainty[i] <= CONSISTENT_MAX_UNCERTAINTY:
            r = x[i] - disparity[i]
            out[i] = lowest[support - 1] <= r - margin
            k = support - 1
            if r < lowest[k]:
                while k > 0 and lowest[k - 1] > r:
                    lowest[k] = lowest[k - 1]
                    k -= 1
                lowest[k] = r
    return out


@njit(cache=True, nogil=True)
def finish_window(t_end, x, y, pol, disparity, uncertainty, outside, max_uncertainty, margin, support, segment_min,
                  clear_below, grid, prior, prior_x, prior_y):
    """What follows the kernel, in loops over its answers: the next window's prior (the answers of uncertainty at
    most ``min(max_uncertainty, PRIOR_MAX_UNCERTAINTY)`` before the occlusion test, design part 9), the occlusion
    test (when ``margin >= 0``), the segment test (when ``segment_min > 0``, design part 11) and the matches
    kept. Numpy's dozen calls for the same (masks, fancy indexing, a structured array filled column by column)
    were a visible share of a small window's time.

    Parameters
    ----------
    t_end : int
        The window's end: the matches' time stamp.
    x, y, pol : (M,) int ndarrays; disparity, uncertainty : (M,) float64 ndarrays
        The kernel's answers (:func:`~cvstereo.matchers.fused._kernels.match_features`), raster order.
    outside : (M,) bool ndarray
        The answers the partner test flags (:func:`unpartnered`; all False without the test).
    max_uncertainty, margin, support
        ``max_uncertainty``, ``occlusion_margin`` and ``occlusion_support``.
    segment_min : int
        The segment test's least answers (:func:`segment_min_for`); where it is on, the uncertainties end in three
        tiers (:data:`~cvstereo.matchers.fused._constants.SEGMENT_TIER`).
    clear_below : float
        ``isolated_max_uncertainty``: answers of lower uncertainty are not judged by their segment.
    grid : (H, W) int64 ndarray
        All -1: :func:`small_segments`' scratch.
    prior : (H, W) float64 ndarray
        The prior plane, updated in place: NaN at ``(prior_x, prior_y)`` (the pixels the last window set), then
        the new prior.
    prior_x, prior_y : (K,) int ndarrays

    Returns
    -------
    matches : (N,) ndarray of MATCH_DTYPE
    uncertainty : (N,) float64 ndarray
        The matches' uncertainties (after the occlusion and segment tests).
    prior_x, prior_y : int ndarrays
        The pixels that now hold a prior.
    """
    for i in range(prior_x.size):
        prior[prior_y[i], prior_x[i]] = np.nan
    m = x.size
    prior_cut = min(max_uncertainty, PRIOR_MAX_UNCERTAINTY)
    n_prior = 0
    for i in range(m):
        n_prior += uncertainty[i] <= prior_cut and not outside[i]
    px = np.empty(n_prior, np.int64)
    py = np.empty(n_prior, np.int64)
    j = 0
    for i in range(m):
        if uncertainty[i] <= prior_cut and not outside[i]:
            prior[y[i], x[i]] = disparity[i]
            px[j] = x[i]
            py[j] = y[i]
            j += 1
    unc = uncertainty.copy()
    hidden = occluded(x, y, disparity, uncertainty, margin, support) if margin >= 0 else np.zeros(m, np.bool_)
    for i in range(m):
        # One penalty at most: the uncertainty stays <= 1.
        if hidden[i] or (outside[i] and uncertainty[i] <= CONSISTENT_MAX_UNCERTAINTY):
            unc[i] = uncertainty[i] + LR_PENALTY
    if segment_min > 0:
        # The segments of the answers still consistent after those tests; one in a small segment moves to the
        # middle tier (SEGMENT_TIER), unless it is clear enough to answer on its own (the noise filter's rule,
        # design part 13); the inconsistent ones to the last.
        small = small_segments(x, y, disparity, unc <= CONSISTENT_MAX_UNCERTAINTY, grid, segment_min)
        for i in range(m):
            if small[i] and not unc[i] < clear_below:
                unc[i] = CONSISTENT_MAX_UNCERTAINTY + unc[i] / 2.0
            elif unc[i] > CONSISTENT_MAX_UNCERTAINTY:
                unc[i] = SEGMENT_TIER + (unc[i] - CONSISTENT_MAX_UNCERTAINTY) / 2.0
    n = 0
    for i in range(m):
        n += unc[i] <= max_uncertainty
    matches = np.empty(n, MATCH_DTYPE)
    kept = np.empty(n)
    j = 0
    for i in range(m):
        if unc[i] <= max_uncertainty:
            matches[j]["t"] = t_end
            matches[j]["x"] = x[i]
            matches[j]["y"] = y[i]
            matches[j]["p"] = pol[i]
            matches[j]["camera"] = 0
            matches[j]["disparity"] = np.float32(disparity[i])
            kept[j] = unc[i]
            j += 1
    return matches, kept, px, py


class WindowState:
    """What the fused matcher carries from window to window: last event times and the previous disparities.

    Parameters
    ----------
    resolution : (width, height)
    """

    def __init__(self, resolution: tuple[int, int]):
        w, h = resolution
        self.last = np.full((2, 2, h, w), NEVER, dtype=np.int64)  # camera, polarity, row, column
        self.prior = np.full((h, w), np.nan)
        self.prior_end: int | None = None
        self._no_prior = np.full((h, w), np.nan)  # never written: the prior after a gap
        self._prior_at = (np.zeros(0, np.int64), np.zeros(0, np.int64))  # the pixels that hold one
        self._grid = np.full((h, w), -1, np.int64)  # the segment test's scratch

    def prior_for(self, t_end: int, window_us: int) -> np.ndarray:
        """The previous window's disparities if it is the window just before ``t_end``, else all NaN."""
        if self.prior_end == t_end - window_us:
            return self.prior
        return self._no_prior

    def settle(self, t_end: int, answers: tuple, prm: FusedParams, threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """A window's matches and their uncertainties from the kernel's answers (:func:`finish_window`, after the
        partner test on ``threads`` threads); keeps its answers before the occlusion test as the next window's
        prior."""
        x, y, _, disparity, uncertainty = answers
        if prm.border_rows >= 0:
            partner_test = unpartnered_parallel if threads > 1 else unpartnered
            outside = partner_test(x, y, disparity, uncertainty, prm.border_rows, chunks_for(threads))
        else:
            outside = np.zeros(x.size, np.bool_)
        matches, uncertainty, px, py = finish_window(t_end, *answers, outside, prm.max_uncertainty,
                                                     prm.occlusion_margin, prm.occlusion_support,
                                                     segment_min_for(prm, self._grid.shape[1]),
                                                     prm.isolated_max_uncertainty, self._grid,
                                                     self.prior, *self._prior_at)
        self._prior_at = (px, py)
        self.prior_end = t_end
        return matches, uncertainty


class Scratch:
    """The per-window arrays of the kernels, kept between windows (fresh pages cost more than the arithmetic).

    Parameters
    ----------
    resolution : (width, height)
    n_disparities : int
    """

    def __init__(self, resolution: tuple[int, int], n_disparities: int):
        w, h = resolution
        self.nd = n_disparities
        # One of each per camera (camera first): the two cameras' features may be computed at once.
        self.ts = np.empty((2, 2, h, w))
        self.rows = np.empty((2, 2, h, w))
        self.features = np.empty((2, 2, h, w))  # camera, polarity, row, column
        self.values = np.empty((2, 2 * h * w))
        self.value_at = np.empty((2, 2 * h * w), np.int32)
        self.counts = np.empty((2, h, w), np.int64)
        self.active = np.empty((h, w), np.bool_)
        self.recent = np.empty((h, w), np.bool_)
        # Path vectors, one set per pass direction: disparity d at column d + 1, between columns of inf
        # (KernelScratch).
        cols, vecs = (np.zeros((2, rows, n_disparities + 2), np.float32) for rows in (2 * w + 1, 3))
        for path in (cols, vecs):
            path[:, :, 0] = path[:, :, -1] = np.inf
        self.kernel = KernelScratch(np.empty((KERNEL_PLANES, 0, n_disparities), np.float32), cols, vecs,
                                    np.zeros((h, 2, w + n_disparities), np.float32), np.empty((h, w), np.int64))

    def kernel_for(self, n_active: int) -> KernelScratch:
        """The kernel's scratch with path-sum, cost and column-path storage for ``n_active`` pixels (grown by
        doubling, never shrunk)."""
        work = self.kernel.work
        if n_active > work.shape[1]:
            work = np.empty((KERNEL_PLANES, max(n_active, 2 * work.shape[1]), self.nd), np.float32)
            self.kernel = self.kernel._replace(work=work)
        return self.kernel


class FusedMatcher(FrameMatcher):
    """Time-surface semi-global matcher with left-right check, temporal prior and uncertainty (``fused``).

    The module docstring gives the design. Matches are anchored at the left camera's event pixels of each
    window (``anchor = "window"``), like the OpenCV baselines.

    Parameters
    ----------
    params : FusedParams, optional
    resolution : (width, height), keyword-only
    """

    Params = FusedParams
    variants: ClassVar[dict[str, dict]] = {"default": {}}
    method = "fused"

    @classmethod
    def max_disparity_for(cls, default: int, width: int, given: dict) -> int:
        """The scaled range, within the 255 px the kernel's cost arrays are sized for."""
        return min(255, super().max_disparity_for(default, width, given))

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._state = WindowState(self.resolution)
        self._uncertainty: list[np.ndarray] = []
        self._scratch = Scratch(self.resolution, self.params.max_disparity + 1)
        self._kernel_params = kernel_params(self.params)

    def anchor_cameras(self) -> tuple[int, ...]:
        return (0,)

    def take_uncertainty(self) -> np.ndarray:
        """Uncertainty (0..1, lower is more certain) of every match returned since the last call, in order.

        Returns
        -------
        (M,) float32 ndarray
            One value per match that :meth:`feed` and :meth:`flush` returned since the last call (docs/formats.md's
            optional per-match array ``uncertainty``).
        """
        parts, self._uncertainty = self._uncertainty, []
        return np.concatenate(parts).astype(np.float32) if parts else np.zeros(0, np.float32)

    def _camera_features(self, cam: int, window: Window) -> None:
        """Camera ``cam``'s normalised features of ``window``, into its own scratch and last-event times: the
        cameras' calls are independent."""
        prm, buf = self.params, self._scratch
        f = buf.features[cam]
        events = window.left if cam == 0 else window.right
        surface_features(events["t"], events["x"], events["y"], events["p"], self._state.last[cam], window.t_end,
                         prm.tau_us, prm.support_radius, buf.ts[cam], buf.rows[cam], f)
        n = nonzero_values(f, buf.values[cam], buf.value_at[cam])
        if n:
            divide(f, buf.values[cam], buf.value_at[cam], n, level_of(buf.values[cam, :n]))

    def match_window(self, window: Window) -> np.ndarray:
        prm, state, buf = self.params, self._state, self._scratch
        threads = getattr(self, "threads", 1)
        # With several threads each camera's features on a thread of its own (serial kernels that release the GIL).
        both_cameras(self._camera_features, window, side_by_side=threads > 1)
        window_masks = window_masks_parallel if threads > 1 else window_masks_serial
        left = window.left
        n_active = window_masks(left["x"], left["y"], left["p"], state.last[0],
                                window.t_end - RECENT_WINDOWS * prm.window_us, prm.path_radius, buf.counts,
                                buf.active, buf.recent)
        kernel = match_features_parallel if threads > 1 else match_features
        answers = kernel(buf.features[0], buf.features[1], buf.counts, buf.active, buf.recent,
                         state.prior_for(window.t_end, prm.window_us), self._kernel_params, buf.kernel_for(n_active),
                         way_for(threads, prm.sgm_paths, n_active * (prm.max_disparity + 1) * 4), chunks_for(threads))
        matches, uncertainty = state.settle(window.t_end, answers, prm, threads)
        self._uncertainty.append(uncertainty)
        return matches
