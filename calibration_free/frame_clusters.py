"""The frame-based cluster matcher (thesis 3.3; algorithms.md section 1).

Per 40 ms window and camera: a signed frame (sum of event signs per pixel), a 5x5 Gaussian of sigma 1,
a threshold on the magnitude. Each row then becomes a list of clusters, the maximal runs of kept pixels of one
sign (the thesis' 3xN "comparison array": sign, left edge, right edge). Row y of the two frames is matched only
if both list the same number of clusters with the same signs in the same order; cluster i pairs with cluster
i if the widths differ by at most 30 %, and the disparity is the difference of the centres.

Two implementations of steps 3-6, which the tests hold equal. :func:`row_runs`, :func:`match_runs` and
:func:`match_frame_pair` are the readable one, vectorised with numpy over a whole frame (runs from comparing
each pixel with its row neighbours, rows compared through per-row run counts). :class:`FrameClusterMatcher`
runs one numba kernel per window over all its frames instead (:func:`_match_stacked_rows`): per window numpy's
per-call overhead, not arithmetic, was the cost, and the separate ON/OFF variant, with twice the frames, fell
short of 50x real time on a 2-core Xeon.

Relative thresholds (``threshold_mode="relative"``, :mod:`cvstereo.signal_level`): the cluster threshold
(1.2 on the filtered sum of signs) becomes ``threshold_scale`` times the signal level of each camera, the 0.9
quantile of |filtered value| at its pixels with events over the last second, because the filtered value of an
edge grows with its events per pixel. The other constants stay absolute: the 30 % width rule compares the two
clusters' widths with each other and the disparity range is geometry; the Gaussian's sigma and size are
pixels, not signal.

>>> from cvstereo.events import make_events
>>> ys, xs = np.mgrid[10:14, 40:46].reshape(2, -1).repeat(3, axis=1)   # 3 OFF events at each pixel of a patch
>>> left = make_events(np.zeros(xs.size, int), xs, ys, 0)
>>> right = make_events(np.zeros(xs.size, int), xs - 7, ys, 0)        # the same patch 7 px further left
>>> m = FrameClusterMatcher()
>>> out = np.concatenate([m.feed(left, right), m.flush()])
>>> sorted(set(out["disparity"].tolist())), int(out["t"][0]), int(out["camera"][0])
([7.0], 40000, 0)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal, NamedTuple

import numba
import numpy as np

from cvstereo.frames import (
    FrameMatcher,
    Polarity,
    Window,
    WindowFrameParams,
    _channel_of,
    gaussian_filter,
    stacked_frames,
)
from cvstereo.matches import empty_matches, make_matches
from cvstereo.signal_level import SignalLevel, SignalLevelParams

# Comparisons of integer widths against a float fraction: tolerate the rounding of 0.3 * w, so that the
# rule holds exactly at its edge (|10 - 7| <= 0.3 * 10 must pass although 0.3 * 10 may round below 3).
_EDGE_EPS = 1e-9


@dataclass(frozen=True, kw_only=True)
class FrameClusterParams(SignalLevelParams, WindowFrameParams):
    """Parameters of the frame-based cluster matcher (thesis defaults; algorithms.md section 1).

    The window and Gaussian fields (window_us, gaussian, sigma, kernel_size) are those of
    :class:`~cvstereo.frames.WindowFrameParams`, the relative-threshold fields (threshold_mode,
    threshold_scale, level_*) those of :class:`~cvstereo.signal_level.SignalLevelParams`.

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
        The camera whose cluster pixels carry the results (0 = left, 1 = right).
    """

    polarity: Polarity = "shared"
    threshold: float = 1.2
    width_tolerance: float = 0.3
    max_disparity: int = 64
    anchor_camera: Literal[0, 1] = 0

    def __post_init__(self):
        super().__post_init__()
        where = type(self).__name__
        if self.polarity not in ("shared", "separate", "on", "off"):
            raise ValueError(f"{where}: polarity must be one of shared, separate, on, off; got '{self.polarity}'.")
        if not self.threshold > 0:
            raise ValueError(f"{where}: threshold must be > 0 (the thesis uses 1.2), got {self.threshold}.")
        if not self.width_tolerance >= 0:
            raise ValueError(f"{where}: width_tolerance must be >= 0 (the thesis uses 0.3), "
                             f"got {self.width_tolerance}.")
        if not self.max_disparity >= 0:
            raise ValueError(f"{where}: max_disparity must be >= 0 (e.g. 64), got {self.max_disparity}.")
        if self.anchor_camera not in (0, 1):
            raise ValueError(f"{where}: anchor_camera must be 0 (left) or 1 (right), got {self.anchor_camera}.")


class Runs(NamedTuple):
    """Clusters of a frame: maximal runs of equal nonzero sign within one row, in row-major order.

    All fields are (K,) arrays: ``row``, ``left`` and ``right`` (inclusive edges, px), ``sign`` (+1/-1).
    """

    row: np.ndarray
    left: np.ndarray
    right: np.ndarray
    sign: np.ndarray


def row_runs(signs: np.ndarray) -> Runs:
    """List the clusters of each row of a sign image (the thesis' comparison arrays, for all rows at once).

    Parameters
    ----------
    signs : (height, width) int ndarray
        +1, -1 or 0 (pixel not kept).

    Returns
    -------
    Runs
        Sorted by row, then by left edge.

    Examples
    --------
    >>> r = row_runs(np.array([[1, 1, -1, 0, -1], [0, 0, 0, 0, 0], [0, 1, 1, 1, 0]]))
    >>> r.row.tolist(), r.left.tolist(), r.right.tolist(), r.sign.tolist()
    ([0, 0, 0, 2], [0, 2, 4, 1], [1, 2, 4, 3], [1, -1, -1, 1])
    """
    s = np.asarray(signs, dtype=np.int8)
    h, w = s.shape
    pad = np.zeros((h, w + 2), dtype=np.int8)
    pad[:, 1:-1] = s
    kept = s != 0
    # A run starts where the sign differs from the left neighbour and ends where it differs from the right one;
    # the zero padding closes runs at the sensor edges. Starts and ends come out in the same row-major order,
    # so the k-th start and the k-th end belong to the same run.
    starts = kept & (s != pad[:, :-2])
    ends = kept & (s != pad[:, 2:])
    # flatnonzero + divmod: faster than the 2-D nonzero.
    row, left = np.divmod(np.flatnonzero(starts), w)
    right = np.flatnonzero(ends) % w
    return Runs(row, left, right, s[row, left])


class Pairs(NamedTuple):
    """Matched cluster pairs: the anchor camera's cluster (row, left, right, sign) and its disparity."""

    row: np.ndarray
    left: np.ndarray
    right: np.ndarray
    sign: np.ndarray
    disparity: np.ndarray


def match_runs(left: Runs, right: Runs, *, height: int, width_tolerance: float = 0.3,
               max_disparity: int = 64, anchor_camera: int = 0) -> Pairs:
    """Pair the clusters of the left and right frame row by row (algorithms.md section 1, steps 5-6).

    Parameters
    ----------
    left, right : Runs
        Clusters of the left and right frame (from :func:`row_runs`).
    height : int, keyword-only
        Number of rows of the frames.
    width_tolerance, max_disparity : float, keyword-only
        See :class:`FrameClusterParams`.
    anchor_camera : {0, 1}, keyword-only
        Whose cluster is returned with each pair.

    Returns
    -------
    Pairs
        ``disparity = centre_left - centre_right``, within ``[0, max_disparity]``.
    """
    count_l = np.bincount(left.row, minlength=height)
    count_r = np.bincount(right.row, minlength=height)
    same_count = (count_l == count_r) & (count_l > 0)
    # In rows with equal counts the runs of both frames line up one to one, in row-major order.
    sel_l = same_count[left.row]
    sel_r = same_count[right.row]
    rl = Runs(*(a[sel_l] for a in left))
    rr = Runs(*(a[sel_r] for a in right))
    sign_differs = np.bincount(rl.row, weights=rl.sign != rr.sign, minlength=height) > 0
    ok = ~sign_differs[rl.row]
    width_l = rl.right - rl.left + 1
    width_r = rr.right - rr.left + 1
    ok &= np.abs(width_l - width_r) <= width_tolerance * np.maximum(width_l, width_r) + _EDGE_EPS
    disparity = (rl.left + rl.right - rr.left - rr.right) / 2.0
    ok &= (disparity >= 0) & (disparity <= max_disparity)
    anchor = rl if anchor_camera == 0 else rr
    return Pairs(anchor.row[ok], anchor.left[ok], anchor.right[ok], anchor.sign[ok], disparity[ok])


def cluster_signs(frame: np.ndarray, *, threshold: float) -> np.ndarray:
    """Sign of the pixels with ``|frame| >= threshold``, 0 elsewhere, as an (height, width) int8 array."""
    return (frame >= threshold).view(np.int8) - (frame <= -threshold).view(np.int8)


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
    variants: ClassVar[dict[str, dict]] = {
        "shared": {"polarity": "shared"},
        "separate": {"polarity": "separate"},
        "on": {"polarity": "on"},
        "off": {"polarity": "off"},
    }
    method = "frame"

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        p = self.params
        self._level = SignalLevel(p, absolute=p.threshold, unit=filtered_unit(p), value_name="filtered value")

    def anchor_cameras(self) -> tuple[int, ...]:
        return (self.params.anchor_camera,)

    def diagnostics(self) -> dict:
        """The signal-level diagnostics of the run so far (:meth:`cvstereo.signal_level.SignalLevel.diagnostics`)."""
        return self._level.diagnostics()

    def match_window(self, window: Window) -> np.ndarray:
        p = self.params
        k = window.t_start // p.level_window_us
        threshold = self._level.thresholds(k)  # from the windows before this one
        if not (window.left.size and window.right.size):
            self._add_levels(k, window, *self._stack(window))
            return empty_matches()  # a frame without events has no clusters, so no row can match
        height = self.resolution[1]
        stack, seen, gap = self._stack(window)
        n_frames = seen.shape[0] // height  # 2 for separate ON/OFF, else 1
        x, y, sign, disparity = _match_stacked_rows(
            stack, seen, n_frames, height, height + gap, np.float32(threshold[0]), np.float32(threshold[1]),
            float(p.width_tolerance), float(p.max_disparity), int(p.anchor_camera))
        self._add_levels(k, window, stack, seen, gap)
        matches = make_matches(window.t_end, x, y, (sign > 0).view(np.int8), p.anchor_camera, disparity)
        # One frame: the kernel already emits (y, x) order. Two (separate ON/OFF): a pixel may be in both.
        return matches if n_frames == 1 else _pixel_order(matches)

    def _stack(self, window: Window):
        """The window's (filtered) frames stacked, the anchor camera's pixels with events, the gap rows."""
        p = self.params
        # All frames of the window (cameras x frames) go through the filter as one stacked image, with zero rows
        # between them: the same as filtering each on its own with a zero border (see match_frame_pair).
        gap = p.kernel_size // 2 if p.gaussian else 0
        stack, seen = stacked_frames((window.left, window.right), polarity=p.polarity, resolution=self.resolution,
                                     gap=gap, seen_camera=p.anchor_camera)
        if p.gaussian:
            stack = gaussian_filter(stack, sigma=p.sigma, kernel_size=p.kernel_size)
        return stack, seen, gap

    def _add_levels(self, k: int, window: Window, stack: np.ndarray, seen: np.ndarray, gap: int) -> None:
        """Feed the signal level: |filtered value| at each camera's pixels with events (of each frame)."""
        height = self.resolution[1]
        n_frames = seen.shape[0] // height
        for cam, ev in enumerate((window.left, window.right)):
            self._level.add(k, cam, active_values(stack, ev, polarity=self.params.polarity,
                                                  first_row=cam * n_frames * (height + gap), pitch=height + gap))


def filtered_unit(params) -> float:
    """The filtered value of one isolated event: the Gaussian's centre weight, or 1 without the filter."""
    if not params.gaussian:
        return 1.0
    one = np.zeros((params.kernel_size, params.kernel_size), np.float32)
    one[params.kernel_size // 2, params.kernel_size // 2] = 1.0
    return float(gaussian_filter(one, sigma=params.sigma, kernel_size=params.kernel_size).max())


def active_values(stack: np.ndarray, events: np.ndarray, *, polarity: str, first_row: int, pitch: int) -> np.ndarray:
    """The values of a camera's frames (in ``stack`` from ``first_row``, one every ``pitch`` rows, in the order of
    :func:`~cvstereo.frames.polarity_frames`) at each distinct pixel where the camera has events of that frame."""
    if events.size == 0:
        return np.empty(0, np.float32)
    channel = _channel_of(polarity)[events["p"].astype(np.int64)]
    keep = channel >= 0
    rows = first_row + channel[keep] * pitch + events["y"][keep].astype(np.int64)
    flat = np.unique(rows * stack.shape[1] + events["x"][keep].astype(np.int64))
    return stack.reshape(-1)[flat]


def match_frame_pair(left: np.ndarray, right: np.ndarray, *, threshold: float = 1.2, width_tolerance: float = 0.3,
                     max_disparity: float = 64, anchor_camera: int = 0, threshold_right: float | None = None) -> Pairs:
    """Match the clusters of one pair of (filtered) frames: steps 3-5 of algorithms.md section 1.

    The readable form of what :class:`FrameClusterMatcher` does for all frames of a window at once.

    Parameters
    ----------
    left, right : (height, width) float ndarray
        Filtered frames of the left and right camera.
    threshold, width_tolerance, max_disparity, anchor_camera : keyword-only
        See :class:`FrameClusterParams`.
    threshold_right : float, optional, keyword-only
        The right frame's threshold, where it differs from the left's (relative thresholds are per camera).

    Returns
    -------
    Pairs
        The anchor camera's matched clusters and their disparities.

    Examples
    --------
    >>> row = np.array([[0, 2, 2, 2, 0, 0, -2, -2, 0, 0, 0, 0]], float)
    >>> pairs = match_frame_pair(np.roll(row, 3, axis=1), row)
    >>> pairs.disparity.tolist(), pairs.sign.tolist()
    ([3.0, 3.0], [1, -1])
    """
    right_threshold = threshold if threshold_right is None else threshold_right
    return match_runs(row_runs(cluster_signs(left, threshold=threshold)),
                      row_runs(cluster_signs(right, threshold=right_threshold)), height=left.shape[0],
                      width_tolerance=width_tolerance, max_disparity=max_disparity, anchor_camera=anchor_camera)


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


@numba.njit(cache=True, nogil=True)
def _match_stacked_rows(stack, seen, n_channels, height, pitch, threshold_left, threshold_right, width_tolerance,
                        max_disparity, anchor_camera):  # pragma: no cover - compiled
    """Steps 3-6 of algorithms.md section 1 for every frame of a window, in one pass over the rows.

    ``stack`` holds the filtered frames one above the other, every ``pitch`` rows: the left camera's channels,
    then the right camera's. ``seen`` (channel * height + y, x) marks the anchor camera's pixels with events.
    Returns x, y, sign and disparity of every reported pixel, channel by channel, row by row, x ascending.
    Same arithmetic as :func:`row_runs` + :func:`match_runs` (float32 thresholds, one per camera; float64 widths
    and centres).
    """
    width = stack.shape[1]
    capacity = n_channels * height * width
    out_x = np.empty(capacity, np.int64)
    out_y = np.empty(capacity, np.int64)
    out_sign = np.empty(capacity, np.int8)
    out_d = np.empty(capacity, np.float64)
    # Clusters of the left (0) and right (1) camera's row: sign, left and right edge; at most ``width`` a row.
    clusters = np.empty((3, 2, width), np.int64)
    sign, left, right = clusters[0], clusters[1], clusters[2]
    n = 0
    for c in range(n_channels):
        for y in range(height):
            n_l = _row_clusters(stack, c * pitch + y, threshold_left, clusters, 0)
            if n_l == 0:
                continue
            n_r = _row_clusters(stack, (n_channels + c) * pitch + y, threshold_right, clusters, 1)
            if n_r != n_l:
                continue  # unequal cluster counts: the row is not matched
            same_order = True
            for i in range(n_l):
                if sign[0, i] != sign[1, i]:
                    same_order = False
                    break
            if not same_order:
                continue
            for i in range(n_l):
                w_l = right[0, i] - left[0, i] + 1
                w_r = right[1, i] - left[1, i] + 1
                if abs(w_l - w_r) > width_tolerance * max(w_l, w_r) + _EDGE_EPS:
                    continue
                d = (left[0, i] + right[0, i] - left[1, i] - right[1, i]) / 2.0
                if d < 0 or d > max_disparity:
                    continue
                for x in range(left[anchor_camera, i], right[anchor_camera, i] + 1):
                    if seen[c * height + y, x]:
                        out_x[n] = x
                        out_y[n] = y
                        out_sign[n] = sign[0, i]
                        out_d[n] = d
                        n += 1
    return out_x[:n], out_y[:n], out_sign[:n], out_d[:n]


def _pixel_order(matches: np.ndarray) -> np.ndarray:
    """Sort one window's matches by (y, x, p), so that the output order does not depend on the variant."""
    if matches.size < 2:
        return matches
    return matches[np.lexsort((matches["p"], matches["x"], matches["y"]))]
