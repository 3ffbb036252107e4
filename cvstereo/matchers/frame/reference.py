"""Reference frame-based cluster matcher (docs/algorithms.md section 1, thesis 3.3): numpy over whole frames.

Frame by frame, as the thesis describes it: per window and camera a signed frame per polarity frame
(:func:`cvstereo.matchers._shared.reference_windows.signed_frame`), the Gaussian, the threshold, the clusters of
each row (the thesis' 3xN "comparison array": sign, left edge, right edge), then rows with the same number of
clusters in the same sign order are paired cluster by cluster. Vectorised with numpy (runs from comparing each
pixel with its row neighbours, rows compared through per-row run counts) but with no shortcut of the fast
matcher, which stacks all frames of a window into one image and runs one numba kernel over it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cvstereo.matchers._shared.reference_border import border_rule_of
from cvstereo.matchers._shared.reference_checks import supported
from cvstereo.matchers._shared.reference_windows import (
    filtered_unit,
    gaussian_filter,
    signed_frame,
    values_at_events,
    window_events,
)
from cvstereo.matchers._shared.signal_level import SignalLevel
from cvstereo.matchers.frame.params import WIDTH_EPS, FrameClusterParams
from cvstereo.model.events import DEFAULT_RESOLUTION
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import frame_signs

__all__ = ["Pairs", "Runs", "cluster_signs", "frame_clusters_reference", "match_frame_pair", "match_runs", "row_runs"]


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
    """Pair the clusters of the left and right frame row by row (docs/algorithms.md section 1, steps 5-6).

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
    ok &= np.abs(width_l - width_r) <= width_tolerance * np.maximum(width_l, width_r) + WIDTH_EPS
    disparity = (rl.left + rl.right - rr.left - rr.right) / 2.0
    ok &= (disparity >= 0) & (disparity <= max_disparity)
    anchor = rl if anchor_camera == 0 else rr
    return Pairs(anchor.row[ok], anchor.left[ok], anchor.right[ok], anchor.sign[ok], disparity[ok])


def cluster_signs(frame: np.ndarray, *, threshold: float) -> np.ndarray:
    """Sign of the pixels with ``|frame| >= threshold``, 0 elsewhere, as an (height, width) int8 array."""
    return (frame >= threshold).view(np.int8) - (frame <= -threshold).view(np.int8)


def match_frame_pair(left: np.ndarray, right: np.ndarray, *, threshold: float = 1.2, width_tolerance: float = 0.3,
                     max_disparity: float = 64, anchor_camera: int = 0, threshold_right: float | None = None) -> Pairs:
    """Match the clusters of one pair of (filtered) frames: steps 3-5 of docs/algorithms.md section 1.

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


def frame_clusters_reference(left: np.ndarray, right: np.ndarray, params: FrameClusterParams | None = None, *,
                             resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the frame-based cluster matcher, window by window, frame by frame.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        Per window (stamped with its end), the anchor camera's pixels of matched clusters that saw events of
        the cluster's frame, in (y, x, p) order.

    See Also
    --------
    cvstereo.matchers._shared.reference : the arguments, the same for every reference function.
    """
    prm = params if params is not None else FrameClusterParams()
    width, height = resolution
    level = SignalLevel(prm, absolute=prm.threshold, unit=filtered_unit(prm), value_name="filtered value")
    parts = []
    for t_end, ev_l, ev_r in window_events(left, right, prm.window_us, every=True):
        k = (t_end - prm.window_us) // prm.level_window_us
        # The fast kernel compares float32 values with float32 thresholds: the same numbers here.
        thr_l, thr_r = (float(np.float32(v)) for v in level.thresholds(k))
        anchor = (ev_l, ev_r)[prm.anchor_camera]
        rows = []
        for signs in frame_signs(prm.polarity):
            fl, fr = (signed_frame(ev, resolution=resolution, signs=signs) for ev in (ev_l, ev_r))
            if prm.gaussian:
                fl, fr = (gaussian_filter(f, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size) for f in (fl, fr))
            # The signal level sees each camera's values at its pixels with events of this frame.
            for cam, (f, ev) in enumerate(((fl, ev_l), (fr, ev_r))):
                level.add(k, cam, values_at_events(f, ev[np.isin(ev["p"].astype(int) * 2 - 1, signs)]))
            if not (ev_l.size and ev_r.size):
                continue  # a frame without events has no clusters, so no row can match
            pairs = match_frame_pair(fl, fr, threshold=thr_l, threshold_right=thr_r,
                                     width_tolerance=prm.width_tolerance, max_disparity=prm.max_disparity,
                                     anchor_camera=prm.anchor_camera)
            # Pixels with events of this frame's polarities (ON and OFF events at one pixel may cancel).
            seen = np.zeros((height, width), bool)
            ev = anchor[np.isin(anchor["p"].astype(int) * 2 - 1, signs)]
            seen[ev["y"], ev["x"]] = True
            for y, a, b, sign, d in zip(*pairs, strict=True):
                rows += [(int(y), x, int(sign > 0), float(d)) for x in range(int(a), int(b) + 1) if seen[y, x]]
        rows.sort()
        if rows:
            y, x, p, d = zip(*rows, strict=True)
            parts.append(supported(make_matches(t_end, x, y, p, prm.anchor_camera, d), prm.min_support))
    # The border rule (adaptive set) decides on the whole output, in its order.
    return border_rule_of(np.concatenate(parts) if parts else empty_matches(), prm, resolution)
