"""The frame-area SAD matcher (thesis 3.5.1, Algorithm 2; docs/algorithms.md section 3).

Per 40 ms window: signed frames as for the cluster matcher (Gaussian-filtered, or not in the variant
``no-gaussian``). The reference frame (default: the right camera, the thesis' eDVS1) is scanned row by row,
x ascending; a pixel with ``|value| >= threshold`` and no disparity yet gets the disparity whose 5x5 block in
the other frame, on the same row and on the geometrically possible side, has the least sum of absolute
differences (ties: the smaller disparity); the winner is written into the whole 5x5 neighbourhood of the
disparity map, overwriting, so that those pixels are not searched again. With ``polarity="separate"`` (not
the thesis': its frame is ``shared``) each camera has an OFF and an ON frame, and each pair is scanned and
matched on its own, so that ON and OFF events of one window cannot cancel each other. With ``lr_check`` (not
the thesis') the other camera's frame is scanned as well and a disparity stands only where both scans agree
(:func:`cvstereo.matchers._shared.support.lr_consistent`). With ``uniqueness`` > 0 (not the thesis') a search whose
winner has a rival (:mod:`cvstereo.matchers._shared.uniqueness`) still fills its block, with no disparity, so
the scan visits the same pixels.

The scan is one numba kernel (:func:`scan_sad`) that computes the SAD only for the pixels it actually searches
(each search fills a whole block of the disparity map, so most above-threshold pixels are never searched). On
sparse frames (:mod:`cvstereo.matchers._shared.sparse_frames`) the matcher uses :func:`_scan_sparse`, with the same
result: it
first replays the scan order without any SAD (which pixels are searched depends only on the threshold and the
blocks written before), then searches only where a reported pixel keeps the disparity, skipping the
disparities whose block in the other frame is empty (but the first: all of them give the same SAD) and
stopping a sum once it reaches the best so far; it serves every polarity mode (each frame pair its own planes)
and ``lr_check`` (both scans sparse). The dense path stays for the cases the sparse frames do not reproduce
(another kernel size, thresholds <= 0).
Its readable twin, a full cost volume from OpenCV kernels (``cv2.absdiff`` and an unnormalised
``cv2.boxFilter`` per disparity) and the scan over it, is :mod:`cvstereo.matchers.frame_area.reference`.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.matchers._shared.signal_level`): the search
threshold (2 on
the filtered frame, 4 unfiltered) becomes ``threshold_scale`` times the reference camera's signal level (the 0.9
quantile of |frame value| at its pixels with events over the last second), since a frame's values grow with
the events per pixel. The SAD needs no threshold of its own: candidates are compared with each other (least
SAD wins); block size and disparity range are geometry.
"""

from __future__ import annotations

from typing import ClassVar

import numba
import numpy as np

from cvstereo.frames.accumulate import event_mask, filtered_unit, gaussian_filter, polarity_counts, polarity_frames
from cvstereo.frames.windows import FrameMatcher, Window
from cvstereo.matchers._shared.frame_gains import FrameGains
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers._shared.sparse_frames import SparseFrames, band_of_rows, bit_positions
from cvstereo.matchers._shared.support import lr_consistent
from cvstereo.matchers._shared.uniqueness import ambiguous
from cvstereo.matchers.frame_area.params import FrameAreaParams
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import slot_of_p

__all__ = ["FrameAreaMatcher", "scan_sad"]


def scan_sad(reference: np.ndarray, other: np.ndarray, *, threshold: float, max_disparity: int, block: int = 5,
             reference_camera: int = 1, gain: float = 1.0, uniqueness: float = 0.0) -> np.ndarray:
    """Algorithm 2 with the SAD computed only for the pixels the scan actually searches (numba).

    Same result as the reference ``scan_disparity_map(reference, sad_volume(reference, other, ...), ...)``
    (:mod:`cvstereo.matchers.frame_area.reference`), but much faster: each search fills a whole block of the
    disparity map, so only a small part of the above-threshold pixels is ever searched.

    Parameters
    ----------
    reference, other : (height, width) float ndarray
    threshold, max_disparity, block, reference_camera : keyword-only
        See :class:`FrameAreaParams`.
    gain : float, keyword-only
        ``other`` is multiplied by it (in float64) before the SAD (``value_units`` of :class:`FrameAreaParams`).
    uniqueness : float, keyword-only
        0: off (the thesis). Otherwise an ambiguous search (:mod:`cvstereo.matchers._shared.uniqueness`) writes
        NaN into its block.

    Returns
    -------
    (height, width) float32 ndarray
        Disparity, NaN where none was written.
    """
    ref = np.ascontiguousarray(reference, dtype=np.float64)
    oth = np.ascontiguousarray(other, dtype=np.float64) * gain
    h, w = ref.shape
    r = block // 2
    inner = np.zeros((h, w), dtype=bool)
    inner[r: h - r, r: w - r] = True
    ys, xs = np.nonzero((np.abs(ref) >= threshold) & inner)
    step = 1 if reference_camera == 1 else -1
    return _scan_sad_kernel(ref, oth, ys, xs, int(max_disparity), r, step, float(uniqueness))


@numba.njit(cache=True, nogil=True)
def _scan_sad_kernel(ref, oth, ys, xs, max_disparity, r, step, uniqueness):  # pragma: no cover - compiled
    h, w = ref.shape
    disp = np.full((h, w), np.nan, dtype=np.float32)
    done = np.zeros((h, w), dtype=np.bool_)
    cand_d = np.empty(max_disparity + 1, np.int64)  # every candidate's SAD, for the uniqueness check
    cand_sad = np.empty(max_disparity + 1)
    for k in range(ys.size):
        y = ys[k]
        x = xs[k]
        if done[y, x]:
            continue
        best = np.inf
        best_d = 0
        n_cand = 0
        for d in range(max_disparity + 1):
            xo = x + step * d
            if xo - r < 0 or xo + r >= w:
                break  # larger disparities only move further out of the sensor
            sad = 0.0
            for j in range(-r, r + 1):
                for i in range(-r, r + 1):
                    sad += abs(ref[y + j, x + i] - oth[y + j, xo + i])
            cand_d[n_cand] = d
            cand_sad[n_cand] = sad
            n_cand += 1
            if sad < best:  # strict: ties go to the smaller disparity
                best = sad
                best_d = d
        # An ambiguous search still fills its block (the scan order stays the thesis'), with no disparity.
        value = np.float32(best_d)
        if uniqueness > 0 and ambiguous(cand_d, cand_sad, n_cand, best_d, best, 1.0 + uniqueness):
            value = np.float32(np.nan)
        for j in range(y - r, y + r + 1):
            for i in range(x - r, x + r + 1):
                disp[j, i] = value
                done[j, i] = True
    return disp


@numba.njit(cache=True, nogil=True)
def _plan_sparse(above, ref_plane, r, done, owner, searched):  # pragma: no cover - compiled
    """Which pixels Algorithm 2's scan of ``ref_plane`` searches, and which search writes each map pixel last.

    ``above`` marks the pixels whose value reaches the scan's threshold (:attr:`SparseFrames.above`): only
    they can be searched, so the scan visits only them, in its order (row by row, x ascending).
    Whether a pixel is searched depends only on the threshold and on the blocks written before it, never on
    the disparities found, so the scan order of :func:`_scan_sad_kernel` can be replayed without any SAD: the
    searched pixels go into ``searched`` (2, height * width) in scan order, and each pixel of a searched block
    gets ``done`` = True and ``owner`` = the index of the search (the later overwrites, as the scan does).
    ``done`` must be all False on entry (:func:`_unmark`). Returns the number of searches.
    """
    h, w = done.shape
    n_words = above.shape[2]
    n_searched = 0
    for y in range(r, h - r):
        for i in range(n_words):
            word = above[ref_plane, y, i]
            while word:
                x, word = bit_positions(word, i)
                if x < r or x >= w - r or done[y, x]:
                    continue
                for j in range(y - r, y + r + 1):
                    for k in range(x - r, x + r + 1):
                        owner[j, k] = n_searched
                        done[j, k] = True
                searched[0, n_searched] = y
                searched[1, n_searched] = x
                n_searched += 1
    return n_searched


@numba.njit(cache=True, nogil=True)
def _search_needed(values, support, ref_plane, oth_plane, max_disparity, r, step, searched, need,
                   gain, uniqueness):  # pragma: no cover - compiled
    """The disparity each needed search of :func:`_plan_sparse` finds (-1 for the others and for an ambiguous
    one), as :func:`_scan_sad_kernel` does (the other plane's values times ``gain``): the same float64 sums in the
    same order, but
    - a block of the other frame that holds no support pixel is all zeros, so its SAD is the same number for
      every such disparity: only the first of them is summed (ties go to the smaller disparity, so only it can
      win; the others count as rivals of the uniqueness check with its SAD);
    - a sum stops once it exceeds the largest SAD that still matters: the best so far (reaching it is enough
      without the uniqueness check), or ``1 + uniqueness`` times it (a rival,
      :mod:`cvstereo.matchers._shared.uniqueness`): its terms are >= 0 and rounding is monotonic, so it could only
      end above that.
    """
    w = values.shape[2]
    ref = values[ref_plane]
    oth = values[oth_plane]
    found = np.full(need.size, -1, np.int64)
    band = np.zeros(0, np.uint64)
    band_y = -1
    rival = 1.0 + uniqueness
    cand_d = np.empty(max_disparity + 1, np.int64)  # the candidates within the limit, for the uniqueness check
    cand_sad = np.empty(max_disparity + 1)
    for s in range(need.size):
        if not need[s]:
            continue  # no pixel with events keeps this search's disparity
        y = searched[0, s]
        x = searched[1, s]
        if y != band_y:
            band = band_of_rows(support[oth_plane], y, r, w)
            band_y = y
        best = np.inf
        best_d = 0
        limit = np.inf
        zero_sad = np.inf  # the SAD of an empty block (inf until summed, or where it ran past the limit)
        zero_block_seen = False
        n_cand = 0
        for d in range(max_disparity + 1):
            xo = x + step * d
            if xo - r < 0 or xo + r >= w:
                break  # larger disparities only move further out of the sensor
            empty = not (band[xo >> 6] >> np.uint64(xo & 63)) & np.uint64(1)
            if empty:
                if zero_block_seen:
                    if uniqueness > 0 and zero_sad <= limit:
                        cand_d[n_cand] = d
                        cand_sad[n_cand] = zero_sad
                        n_cand += 1
                    continue
                zero_block_seen = True
            sad = 0.0
            for j in range(-r, r + 1):
                for k in range(-r, r + 1):
                    a = np.float64(ref[y + j, x + k])
                    sad += abs(a - np.float64(oth[y + j, xo + k]) * gain) if not empty else abs(a - 0.0)
                if sad > limit or (uniqueness == 0 and sad >= best):
                    break
            if empty and sad <= limit:
                zero_sad = sad
            if uniqueness > 0 and sad <= limit:
                cand_d[n_cand] = d
                cand_sad[n_cand] = sad
                n_cand += 1
            if sad < best:  # strict: ties go to the smaller disparity
                best = sad
                best_d = d
                limit = best * rival
        if uniqueness > 0 and ambiguous(cand_d, cand_sad, n_cand, best_d, best, rival):
            continue
        found[s] = best_d
    return found


@numba.njit(cache=True, nogil=True)
def _unmark(done, searched, n_searched, r):  # pragma: no cover - compiled
    """``done`` = False again in the blocks of the first ``n_searched`` searched pixels (all False then)."""
    for s in range(n_searched):
        for j in range(searched[0, s] - r, searched[0, s] + r + 1):
            for k in range(searched[1, s] - r, searched[1, s] + r + 1):
                done[j, k] = False


@numba.njit(cache=True, nogil=True)
def _scan_sparse(values, support, touched, above, ref_plane, oth_plane, lr_check, max_disparity, r, step, capacity,
                 done, owner, searched, gains, uniqueness):  # pragma: no cover - compiled
    """One frame pair's matches on sparse planes: Algorithm 2's scan of ``ref_plane`` and, with ``lr_check``,
    the scan of ``oth_plane`` the other way (each plane's pixels at or above its camera's threshold marked in
    ``above``) and
    :func:`cvstereo.matchers._shared.support.lr_consistent` (tolerance 1 px) on the reference pixels with events.

    The scans are planned first (:func:`_plan_sparse`) and only the searches whose disparity some reported
    pixel keeps are computed (:func:`_search_needed`): for the reference scan those that last wrote a pixel
    with events, for the other camera's those that last wrote a pixel such a disparity names.
    ``done``, ``owner`` are (2, height, width) buffers (``done`` all False on entry and again on return),
    ``searched`` a (2, 2, height * width) one: index 0 for the reference scan, 1 for the other camera's.
    ``gains``: the factors on the compared plane of each scan (``value_units`` of :class:`FrameAreaParams`).
    Returns x, y, p (1 where the reference value is > 0) and the disparity of the reference pixels with events
    (``touched``) that got one (and passed the check), row by row, x ascending.
    """
    _, h, w = values.shape
    n_ref = _plan_sparse(above, ref_plane, r, done[0], owner[0], searched[0])
    out_x = np.empty(capacity, np.int64)
    out_y = np.empty(capacity, np.int64)
    need = np.zeros(n_ref, np.bool_)
    n = 0
    n_words = touched.shape[2]
    for y in range(h):
        for i in range(n_words):
            word = touched[ref_plane, y, i]
            while word:
                x, word = bit_positions(word, i)
                if done[0, y, x]:
                    out_x[n] = x
                    out_y[n] = y
                    need[owner[0, y, x]] = True
                    n += 1
    found = _search_needed(values, support, ref_plane, oth_plane, max_disparity, r, step, searched[0], need,
                           gains[0], uniqueness)
    n_back = 0
    found_back = found  # replaced below with lr_check
    if lr_check:
        n_back = _plan_sparse(above, oth_plane, r, done[1], owner[1], searched[1])
        need_back = np.zeros(n_back, np.bool_)
        for m in range(n):
            d = found[owner[0, out_y[m], out_x[m]]]
            xo = out_x[m] + step * d
            if d >= 0 and 0 <= xo < w and done[1, out_y[m], xo]:
                need_back[owner[1, out_y[m], xo]] = True
        found_back = _search_needed(values, support, oth_plane, ref_plane, max_disparity, r, -step, searched[1],
                                    need_back, gains[1], uniqueness)
    ref = values[ref_plane]
    out_p = np.empty(n, np.int8)
    out_d = np.empty(n, np.float32)
    kept = 0
    for m in range(n):
        x, y = out_x[m], out_y[m]
        d = found[owner[0, y, x]]
        if d < 0:
            continue  # its search was ambiguous
        if lr_check:  # the other scan at the pixel d names holds a disparity within 1 px (lr_consistent)
            xo = x + step * d
            if xo < 0 or xo >= w or not done[1, y, xo]:
                continue
            back = found_back[owner[1, y, xo]]
            if back < 0 or not abs(back - d) <= 1:
                continue
        out_x[kept] = x
        out_y[kept] = y
        out_p[kept] = ref[y, x] > 0
        out_d[kept] = d
        kept += 1
    _unmark(done[0], searched[0], n_ref, r)
    _unmark(done[1], searched[1], n_back, r)
    return out_x[:kept], out_y[:kept], out_p[:kept], out_d[:kept]


class FrameAreaMatcher(FrameMatcher):
    """Frame-area SAD matcher (thesis 3.5.1, Algorithm 2) as a streaming object.

    Results: one row per pixel of the disparity map that holds a value and saw events of the reference camera
    in the window; ``t`` = the window's end, ``camera`` = the reference camera, ``p`` = 1 (ON) where its
    (filtered) frame is > 0 at that pixel, else 0 (OFF).

    Parameters
    ----------
    params : FrameAreaParams, optional
    resolution : (width, height), keyword-only
    """

    Params = FrameAreaParams
    variants: ClassVar[dict[str, dict]] = {
        "gaussian": {"gaussian": True, "threshold": 2.0},
        "no-gaussian": {"gaussian": False, "threshold": 4.0},
    }
    method = "frame-area"

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        prm = self.params
        # The gains between the cameras (value_units): row ``reference_camera`` of its gains is the factor on the
        # compared frame of each slot in the reference camera's scan, the other row that in the left-right check's
        # scan of the other camera. Per frame, they read the level's parts.
        self._gains = FrameGains(prm, n_frames=slot_of_p(prm.polarity)[0], unit=filtered_unit(prm),
                                 units=prm.value_units)
        self._level = SignalLevel(prm, absolute=prm.threshold, unit=filtered_unit(prm), n_parts=self._gains.parts,
                                  value_name="filtered value" if prm.gaussian else "frame value")
        h, w = self.resolution[1], self.resolution[0]
        # Buffers of the sparse scan, reused, per direction (the reference camera's scan, the other camera's for
        # lr_check): searched pixels' blocks, the search that wrote each pixel last, the searched pixels.
        self._done, self._owner = np.zeros((2, h, w), np.bool_), np.zeros((2, h, w), np.int64)
        self._searched = np.empty((2, 2, h * w), np.int64)
        sparse = SparseFrames(2 * slot_of_p(prm.polarity)[0], resolution=self.resolution, gaussian=prm.gaussian,
                              kernel_sigma=prm.kernel_sigma, kernel_size=prm.kernel_size)
        self._sparse = sparse if sparse.exact else None  # None: dense frames (cv2's filter), e.g. other kernels

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.reference_camera,)

    def _frames(self, counts: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """(channel, frame) per frame of the polarity mode (one for ``shared``): :func:`polarity_frames`."""
        prm = self.params
        return [(ch, gaussian_filter(f, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size) if prm.gaussian else f)
                for ch, f in polarity_frames(counts, polarity=prm.polarity)]

    def _counts(self, window: Window) -> tuple[np.ndarray, np.ndarray]:
        """ON/OFF counts of the reference and the other camera."""
        ref_ev, oth_ev = (window.right, window.left) if self.params.reference_camera == 1 else \
            (window.left, window.right)
        return polarity_counts(ref_ev, resolution=self.resolution), polarity_counts(oth_ev, resolution=self.resolution)

    def match_window(self, window: Window) -> np.ndarray:
        prm = self.params
        k = window.t_start // prm.level_window_us
        thresholds = self._level.thresholds(k)  # from the windows before this one
        # The sparse scan searches only pixels near events: every threshold a scan uses must be > 0.
        scanned = thresholds if prm.lr_check else thresholds[prm.reference_camera]
        if self._sparse is not None and np.min(scanned) > 0:
            return self._match_sparse(k, window, thresholds)
        ref_cam = prm.reference_camera
        threshold = thresholds[ref_cam]
        ref_counts, oth_counts = self._counts(window)
        has_ref = (window.right if ref_cam == 1 else window.left).size > 0
        parts = []
        gains = self._gains.gains(k, thresholds, self._level)  # each scan in its own camera's units
        # Each frame of the polarity mode is scanned and matched on its own (``shared``: the one frame).
        for slot, ((ch, ref), (_, oth)) in enumerate(zip(self._frames(ref_counts), self._frames(oth_counts),
                                                         strict=True)):
            self._add_levels(k, ch, slot, ref if has_ref else None, oth, ref_counts, oth_counts)
            if not has_ref:
                continue  # no reference events: nothing above threshold, no pixel to report at
            gain, back_gain = gains[ref_cam, slot], gains[1 - ref_cam, slot]
            disp = scan_sad(ref, oth, threshold=threshold, max_disparity=prm.max_disparity, block=prm.block,
                            reference_camera=ref_cam, gain=gain, uniqueness=prm.uniqueness)
            keep = ~np.isnan(disp)
            if prm.lr_check:
                back = scan_sad(oth, ref, threshold=thresholds[1 - ref_cam], max_disparity=prm.max_disparity,
                                block=prm.block, reference_camera=1 - ref_cam, gain=back_gain,
                                uniqueness=prm.uniqueness)
                keep = lr_consistent(disp, back, reference_camera=ref_cam)
            y, x = np.nonzero(event_mask(ref_counts, channel=ch) & keep)
            parts.append(make_matches(window.t_end, x, y, (ref[y, x] > 0).astype(np.int8), ref_cam, disp[y, x]))
        return np.concatenate(parts) if parts else empty_matches()

    def _match_sparse(self, k: int, window: Window, thresholds: np.ndarray) -> np.ndarray:
        """:meth:`match_window` on sparse frames (:mod:`cvstereo.matchers._shared.sparse_frames`): the same matches and
        levels, fed
        in the same order (per frame of the polarity mode: the reference camera's, then the other camera's)."""
        prm = self.params
        ref_cam = prm.reference_camera
        sf = self._sparse
        n_frames, channel_of = slot_of_p(prm.polarity)
        # plane = camera * n_frames + slot; ``above``: each camera's threshold (the reference scan uses the
        # reference camera's, the left-right check's scan the other camera's)
        sf.fill((window.left, window.right), channel_of, n_frames, thresholds=thresholds)
        try:
            ref_ev, oth_ev = (window.right, window.left) if ref_cam == 1 else (window.left, window.right)
            parts = []
            gains = self._gains.gains(k, thresholds, self._level)
            for slot in range(n_frames):
                ref_plane, oth_plane = ref_cam * n_frames + slot, (1 - ref_cam) * n_frames + slot
                if ref_ev.size:
                    self._add_level(k, ref_cam, slot, sf.values_at_events(ref_plane, 1, ref_ev.size))
                self._add_level(k, 1 - ref_cam, slot, sf.values_at_events(oth_plane, 1, oth_ev.size))
                if not ref_ev.size:
                    continue  # no reference events: nothing above threshold, no pixel to report at
                x, y, p, disp = _scan_sparse(
                    sf.values, sf.support, sf.touched, sf.above, ref_plane, oth_plane, bool(prm.lr_check),
                    int(prm.max_disparity), prm.block // 2, 1 if ref_cam == 1 else -1, ref_ev.size, self._done,
                    self._owner, self._searched, (gains[ref_cam, slot], gains[1 - ref_cam, slot]),
                    float(prm.uniqueness))
                parts.append(make_matches(window.t_end, x, y, p, ref_cam, disp))
        finally:
            sf.clear()
        return np.concatenate(parts) if parts else empty_matches()

    def _add_levels(self, k: int, channel: int, slot: int, ref, oth, ref_counts: np.ndarray,
                    oth_counts: np.ndarray) -> None:
        """Feed the signal level: |frame value| at each camera's pixels with events (of the frame's polarity)."""
        ref_cam = self.params.reference_camera
        if ref is not None:
            self._add_level(k, ref_cam, slot, ref[event_mask(ref_counts, channel=channel)])
        self._add_level(k, 1 - ref_cam, slot, oth[event_mask(oth_counts, channel=channel)])

    def _add_level(self, k: int, cam: int, slot: int, values: np.ndarray) -> None:
        """One frame's values of one camera, to the signal level (to its part of the frame, for the gains)."""
        self._level.add(k, cam, values, part=self._gains.part_of(slot))
