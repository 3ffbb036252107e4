"""The frame-based cluster matcher (thesis 3.3; docs/algorithms.md section 1).

Per 40 ms window and camera: a signed frame (sum of event signs per pixel), a 5x5 Gaussian of sigma 1,
a threshold on the magnitude. Each row then becomes a list of clusters, the maximal runs of kept pixels of one
sign (the thesis' 3xN "comparison array": sign, left edge, right edge). Row y of the two frames is matched only
if both list the same number of clusters with the same signs in the same order; cluster i pairs with cluster
i if the widths differ by at most 30 %, and the disparity is the difference of the centres.

:class:`FrameClusterMatcher` runs one numba kernel per window over all its frames: per window, numpy's per-call
overhead, not arithmetic, is the cost. On sparse frames (:mod:`cvstereo.matchers._shared.sparse_frames`: only the
pixels within
2 px of an event are filtered, with OpenCV's own arithmetic) it reads each row's clusters from the bitmap of
the pixels the threshold keeps (:func:`_match_sparse_rows`); where the sparse filter cannot reproduce OpenCV's
(another kernel size, an unknown build) or a threshold is <= 0 (the sparse path reads only pixels near events),
it filters whole stacked frames with ``cv2.GaussianBlur`` (:func:`_match_stacked_rows`). Both give the same
matches. Its readable twin, vectorised with numpy over a whole frame, is
:mod:`cvstereo.matchers.frame.reference`; the tests hold them equal.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.matchers._shared.signal_level`): the cluster
threshold
(1.2 on the filtered sum of signs) becomes ``threshold_scale`` times the signal level of each camera, the 0.9
quantile of |filtered value| at its pixels with events over the last second, because the filtered value of an
edge grows with its events per pixel. The other constants stay absolute: the 30 % width rule compares the two
clusters' widths with each other and the disparity range is geometry; the Gaussian's sigma and size are
pixels, not signal.

>>> from cvstereo.model.events import make_events
>>> ys, xs = np.mgrid[10:14, 40:46].reshape(2, -1).repeat(3, axis=1)   # 3 OFF events at each pixel of a patch
>>> left = make_events(np.zeros(xs.size, int), xs, ys, 0)
>>> right = make_events(np.zeros(xs.size, int), xs - 7, ys, 0)        # the same patch 7 px further left
>>> m = FrameClusterMatcher()
>>> out = np.concatenate([m.feed(left, right), m.flush()])
>>> sorted(set(out["disparity"].tolist())), int(out["t"][0]), int(out["camera"][0])
([7.0], 40000, 0)
"""

from __future__ import annotations

from typing import ClassVar

import numba
import numpy as np

from cvstereo.frames.accumulate import filtered_unit, gaussian_filter, stacked_frames
from cvstereo.frames.windows import FrameMatcher, Window
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers._shared.sparse_frames import SparseFrames, bit_positions
from cvstereo.matchers._shared.support import supported
from cvstereo.matchers.frame.params import WIDTH_EPS, FrameClusterParams
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import POLARITY_MODES, slot_of_p

__all__ = ["FrameClusterMatcher", "active_values"]


class FrameClusterMatcher(FrameMatcher):
    """Frame-based cluster matcher (thesis 3.3) as a streaming object.

    Results: one row per pixel of each matched anchor cluster that holds events of the anchor camera in the
    window (of the cluster's frame: ON events for an ON frame), ``t`` = the window's end, ``p`` = the cluster's
    polarity, ``disparity`` = centre_left - centre_right (may be a half pixel).

    Parameters
    ----------
    params : FrameClusterParams, optional
    resolution : (width, height), keyword-only
    """

    Params = FrameClusterParams
    variants: ClassVar[dict[str, dict]] = {mode: {"polarity": mode} for mode in POLARITY_MODES}
    method = "frame"

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        prm = self.params
        self._level = SignalLevel(prm, absolute=prm.threshold, unit=filtered_unit(prm), value_name="filtered value")
        n_frames = slot_of_p(prm.polarity)[0]
        sparse = SparseFrames(2 * n_frames, resolution=self.resolution, gaussian=prm.gaussian,
                              kernel_sigma=prm.kernel_sigma, kernel_size=prm.kernel_size)
        self._sparse = sparse if sparse.exact else None  # None: dense frames (cv2's filter), e.g. other kernels

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.anchor_camera,)

    def match_window(self, window: Window) -> np.ndarray:
        prm = self.params
        k = window.t_start // prm.level_window_us
        threshold = self._level.thresholds(k)  # from the windows before this one
        if self._sparse is not None and threshold.min() > 0:  # the sparse path reads only pixels near events
            return self._match_sparse(k, window, threshold)
        if not (window.left.size and window.right.size):
            self._add_levels(k, window, *self._stack(window))
            return empty_matches()  # a frame without events has no clusters, so no row can match
        height = self.resolution[1]
        stack, seen, gap = self._stack(window)
        n_frames = seen.shape[0] // height  # 2 for separate ON/OFF, else 1
        x, y, sign, disparity = _match_stacked_rows(
            stack, seen, n_frames, height, height + gap, np.float32(threshold[0]), np.float32(threshold[1]),
            float(prm.width_tolerance), float(prm.max_disparity), int(prm.anchor_camera))
        self._add_levels(k, window, stack, seen, gap)
        matches = make_matches(window.t_end, x, y, (sign > 0).view(np.int8), prm.anchor_camera, disparity)
        # One frame: the kernel already emits (y, x) order. Two (separate ON/OFF): a pixel may be in both.
        matches = matches if n_frames == 1 else _pixel_order(matches)
        return supported(matches, prm.min_support, width=self.resolution[0])

    def _match_sparse(self, k: int, window: Window, threshold: np.ndarray) -> np.ndarray:
        """:meth:`match_window` on sparse frames (:mod:`cvstereo.matchers._shared.sparse_frames`): the same matches and
        levels."""
        prm = self.params
        sf = self._sparse
        n_frames, channel_of = slot_of_p(prm.polarity)
        frames = n_frames
        # ``above``: the pixels the clusters keep (|v| >= the float32 threshold, compared as float64: the same)
        sf.fill((window.left, window.right), channel_of, frames, thresholds=threshold.astype(np.float32))
        try:
            if window.left.size and window.right.size:
                anchor = (window.left, window.right)[prm.anchor_camera]
                x, y, sign, disparity = _match_sparse_rows(
                    sf.values, sf.above, sf.touched, frames, np.float32(threshold[0]), np.float32(threshold[1]),
                    float(prm.width_tolerance), float(prm.max_disparity), int(prm.anchor_camera), anchor.size)
                matches = make_matches(window.t_end, x, y, (sign > 0).view(np.int8), prm.anchor_camera, disparity)
            else:
                matches, n_frames = empty_matches(), 1
            for cam, ev in enumerate((window.left, window.right)):
                self._level.add(k, cam, sf.values_at_events(cam * frames, frames, ev.size))
        finally:
            sf.clear()
        matches = matches if n_frames == 1 else _pixel_order(matches)
        return supported(matches, prm.min_support, width=self.resolution[0])

    def _stack(self, window: Window):
        """The window's (filtered) frames stacked, the anchor camera's pixels with events, the gap rows."""
        prm = self.params
        # All frames of the window (cameras x frames) go through the filter as one stacked image, with zero rows
        # between them: the same as filtering each on its own with a zero border (as the reference does).
        gap = prm.kernel_size // 2 if prm.gaussian else 0
        stack, seen = stacked_frames((window.left, window.right), polarity=prm.polarity, resolution=self.resolution,
                                     gap=gap, seen_camera=prm.anchor_camera)
        if prm.gaussian:
            stack = gaussian_filter(stack, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size)
        return stack, seen, gap

    def _add_levels(self, k: int, window: Window, stack: np.ndarray, seen: np.ndarray, gap: int) -> None:
        """Feed the signal level: |filtered value| at each camera's pixels with events (of each frame)."""
        height = self.resolution[1]
        n_frames = seen.shape[0] // height
        for cam, ev in enumerate((window.left, window.right)):
            self._level.add(k, cam, active_values(stack, ev, polarity=self.params.polarity,
                                                  first_row=cam * n_frames * (height + gap), pitch=height + gap))


def active_values(stack: np.ndarray, events: np.ndarray, *, polarity: str, first_row: int, pitch: int) -> np.ndarray:
    """The values of a camera's frames (in ``stack`` from ``first_row``, one every ``pitch`` rows, in slot order,
    :mod:`cvstereo.model.polarity`) at each distinct pixel where the camera has events of that frame."""
    if events.size == 0:
        return np.empty(0, np.float32)
    slot = slot_of_p(polarity)[1][events["p"].astype(np.int64)]
    keep = slot >= 0
    rows = first_row + slot[keep] * pitch + events["y"][keep].astype(np.int64)
    flat = np.unique(rows * stack.shape[1] + events["x"][keep].astype(np.int64))
    return stack.reshape(-1)[flat]


@numba.njit(cache=True, nogil=True, inline="always")
def _row_clusters(stack, r, threshold, clusters, camera):  # pragma: no cover - compiled
    """Write the clusters of row ``r`` of ``stack`` (as row_runs finds them) into ``clusters[:, camera]``.

    ``clusters`` is (3, 2, width): sign, left edge, right edge. Returns the number of clusters.
    """
    width = stack.shape[1]
    kept = 0
    for x in range(width):  # a loop without state, which the compiler vectorises: most rows keep no pixel
        kept += abs(stack[r, x]) >= threshold
    if kept == 0:
        return 0
    n = 0
    previous = 0
    for x in range(width):
        s = np.int8(stack[r, x] >= threshold) - np.int8(stack[r, x] <= -threshold)  # branch-free
        if s != previous:
            if previous != 0:
                clusters[2, camera, n - 1] = x - 1
            if s != 0:
                clusters[0, camera, n] = s
                clusters[1, camera, n] = x
                n += 1
            previous = s
    if previous != 0:
        clusters[2, camera, n - 1] = width - 1
    return n


@numba.njit(cache=True, nogil=True, inline="always")
def _row_match_buffers(capacity, width):  # pragma: no cover - compiled
    """Outputs x, y, sign, disparity for ``capacity`` pixels, and the clusters of the left (0) and right (1)
    camera's row: sign, left and right edge, at most ``width`` a row."""
    return (np.empty(capacity, np.int64), np.empty(capacity, np.int64), np.empty(capacity, np.int8),
            np.empty(capacity, np.float64), np.empty((3, 2, width), np.int64))


@numba.njit(cache=True, nogil=True, inline="always")
def _cluster_disparity(left, right, i, width_tolerance, max_disparity):  # pragma: no cover - compiled
    """Steps 5-6 for the ``i``-th cluster pair: its disparity (centre difference), NaN where the widths differ
    by more than the tolerance or the disparity is outside [0, max_disparity]."""
    w_l = right[0, i] - left[0, i] + 1
    w_r = right[1, i] - left[1, i] + 1
    if abs(w_l - w_r) > width_tolerance * max(w_l, w_r) + WIDTH_EPS:
        return np.nan
    d = (left[0, i] + right[0, i] - left[1, i] - right[1, i]) / 2.0
    if d < 0 or d > max_disparity:
        return np.nan
    return d


@numba.njit(cache=True, nogil=True, inline="always")
def _accepted_clusters(clusters, n_l, n_r, width_tolerance, max_disparity, accepted_i,
                       accepted_d):  # pragma: no cover - compiled
    """Steps 4-6 for one row pair (``n_l`` left and ``n_r`` right clusters in ``clusters``): the clusters whose
    disparity stands, written into ``accepted_i`` / ``accepted_d``; returns their number. None unless both rows
    have as many clusters with the same signs in the same order."""
    sign, left, right = clusters[0], clusters[1], clusters[2]
    if n_r != n_l:
        return 0
    for i in range(n_l):
        if sign[0, i] != sign[1, i]:
            return 0
    m = 0
    for i in range(n_l):
        d = _cluster_disparity(left, right, i, width_tolerance, max_disparity)
        if d == d:  # not NaN
            accepted_i[m] = i
            accepted_d[m] = d
            m += 1
    return m


@numba.njit(cache=True, nogil=True, inline="always")
def _emit_pixel(out_x, out_y, out_sign, out_d, n, x, y, sign, d):  # pragma: no cover - compiled
    """Write the ``n``-th reported pixel; the count after it."""
    out_x[n] = x
    out_y[n] = y
    out_sign[n] = sign
    out_d[n] = d
    return n + 1


@numba.njit(cache=True, nogil=True)
def _match_stacked_rows(stack, seen, n_channels, height, pitch, threshold_left, threshold_right, width_tolerance,
                        max_disparity, anchor_camera):  # pragma: no cover - compiled
    """Steps 3-6 of docs/algorithms.md section 1 for every frame of a window, in one pass over the rows.

    ``stack`` holds the filtered frames one above the other, every ``pitch`` rows: the left camera's channels,
    then the right camera's. ``seen`` (channel * height + y, x) marks the anchor camera's pixels with events.
    Returns x, y, sign and disparity of every reported pixel, channel by channel, row by row, x ascending.
    Same arithmetic as the reference ``row_runs`` + ``match_runs`` (float32 thresholds, one per camera; float64
    widths and centres).
    """
    width = stack.shape[1]
    capacity = n_channels * height * width
    out_x, out_y, out_sign, out_d, clusters = _row_match_buffers(capacity, width)
    sign, left, right = clusters[0], clusters[1], clusters[2]
    acc_i, acc_d = np.empty(width, np.int64), np.empty(width, np.float64)  # a row's accepted clusters
    n = 0
    for c in range(n_channels):
        for y in range(height):
            n_l = _row_clusters(stack, c * pitch + y, threshold_left, clusters, 0)
            if n_l == 0:
                continue
            n_r = _row_clusters(stack, (n_channels + c) * pitch + y, threshold_right, clusters, 1)
            for a in range(_accepted_clusters(clusters, n_l, n_r, width_tolerance, max_disparity, acc_i, acc_d)):
                i = acc_i[a]
                for x in range(left[anchor_camera, i], right[anchor_camera, i] + 1):
                    if seen[c * height + y, x]:
                        n = _emit_pixel(out_x, out_y, out_sign, out_d, n, x, y, sign[0, i], acc_d[a])
    return out_x[:n], out_y[:n], out_sign[:n], out_d[:n]


@numba.njit(cache=True, nogil=True, inline="always")
def _bit_row_clusters(values, above, plane, y, threshold, clusters, camera):  # pragma: no cover - compiled
    """:func:`_row_clusters` of row ``y`` of a sparse plane: runs of consecutive kept pixels of one sign.

    Only the kept pixels are visited (``above``: |value| >= threshold, :attr:`SparseFrames.above`); pixels off
    the support hold 0, which no threshold > 0 keeps.
    """
    n = 0
    previous_sign = 0
    previous_x = -2
    row = above[plane, y]
    for i in range(row.size):
        word = row[i]
        while word:
            x, word = bit_positions(word, i)
            v = values[plane, y, x]
            s = np.int8(v >= threshold) - np.int8(v <= -threshold)
            if s == 0:
                continue
            if s == previous_sign and x == previous_x + 1:
                clusters[2, camera, n - 1] = x  # the run goes on
            else:
                clusters[0, camera, n] = s
                clusters[1, camera, n] = x
                clusters[2, camera, n] = x
                n += 1
            previous_sign = s
            previous_x = x
    return n


@numba.njit(cache=True, nogil=True)
def _match_sparse_rows(values, above, touched, n_channels, threshold_left, threshold_right, width_tolerance,
                       max_disparity, anchor_camera, capacity):  # pragma: no cover - compiled
    """:func:`_match_stacked_rows` on sparse planes (:class:`cvstereo.matchers._shared.sparse_frames.SparseFrames`: the
    left
    camera's channels, then the right camera's); ``capacity``: the anchor camera's events, at least the number
    of pixels reported."""
    height, width = values.shape[1], values.shape[2]
    out_x, out_y, out_sign, out_d, clusters = _row_match_buffers(capacity, width)
    sign, left, right = clusters[0], clusters[1], clusters[2]
    acc_i, acc_d = np.empty(width, np.int64), np.empty(width, np.float64)  # a row's accepted clusters
    n = 0
    for c in range(n_channels):
        seen = anchor_camera * n_channels + c
        for y in range(height):
            n_l = _bit_row_clusters(values, above, c, y, threshold_left, clusters, 0)
            if n_l == 0:
                continue
            n_r = _bit_row_clusters(values, above, n_channels + c, y, threshold_right, clusters, 1)
            for a in range(_accepted_clusters(clusters, n_l, n_r, width_tolerance, max_disparity, acc_i, acc_d)):
                i = acc_i[a]
                for x in range(left[anchor_camera, i], right[anchor_camera, i] + 1):
                    if touched[seen, y, x >> 6] & (np.uint64(1) << np.uint64(x & 63)):
                        n = _emit_pixel(out_x, out_y, out_sign, out_d, n, x, y, sign[0, i], acc_d[a])
    return out_x[:n], out_y[:n], out_sign[:n], out_d[:n]

def _pixel_order(matches: np.ndarray) -> np.ndarray:
    """Sort one window's matches by (y, x, p), so that the output order does not depend on the variant.

    One stable sort of a key that orders as (y, x, p) does (x, y < 2048 = MAX_RESOLUTION, p in {0, 1}): the
    kernels emit each frame's matches in pixel order, and the sort merges those runs in one pass, where
    ``np.lexsort`` sorted three times.
    """
    if matches.size < 2:
        return matches
    key = (matches["y"].astype(np.int64) * 2048 + matches["x"]) * 2 + matches["p"]
    return matches[np.argsort(key, kind="stable")]
