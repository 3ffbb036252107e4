"""Scoring matches against dense ground-truth disparity maps, as DSEC's benchmark scores (docs/evaluation.md).

DSEC (and MVSEC, whose depth maps become disparities through the calibration) give the true disparity as images
in the *rectified left* camera's frame at their own timestamps ``ts``. Matches are events or windows, not images,
so each map is compared with the matches of the time before it:

1. every match is moved to its rectified left pixel: a left-anchored match through the calibration's
   rectification of its raw pixel, a right-anchored one to the rectified right pixel and then ``d`` px to the
   right (``x_left = x_right + d``); without a calibration the pixels are taken as they are;
2. the matches with ``ts - 50 ms < t <= ts`` (:data:`TRUTH_WINDOW_US`) belong to the map at ``ts``; a pixel's
   answer is the mean of its matches (:func:`cvstereo.geometry.disparity_maps.pixel_mean`);
3. over the pixels that have both a true disparity and an answer, pooled over all maps: ``1PE`` and ``2PE``
   (the fraction with an absolute error above 1 px and 2 px; DSEC prints them as percentages, as the command
   does), ``MAE`` and ``RMSE`` (px), DSEC's metrics; beside them ``coverage``, the fraction of ground-truth
   pixels answered (DSEC scores dense predictions on every ground-truth pixel; a sparse event matcher answers
   few, so its errors mean little without it).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from cvstereo.geometry.disparity_maps import pixel_mean

__all__ = ["DENSE_METRICS", "TRUTH_WINDOW_US", "predicted_maps", "rectified_left_matches", "score_maps"]

#: The time before a ground-truth map whose matches it scores, us (DSEC's event window for disparity).
TRUTH_WINDOW_US = 50_000
#: The figures of :func:`score_maps`, in the order they are printed.
DENSE_METRICS = ("1PE", "2PE", "MAE", "RMSE", "coverage", "maps", "pixels_scored", "truth_pixels")
#: The error thresholds of 1PE and 2PE, px.
_PE_THRESHOLDS = {"1PE": 1.0, "2PE": 2.0}


def rectified_left_matches(matches: np.ndarray, rectification=None) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                             np.ndarray]:
    """Each match's rectified left pixel: ``(t, x, y, disparity)``, those that leave the sensor dropped.

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        At the recording's raw pixels (as `cvstereo match --calibration` writes them).
    rectification : cvstereo.geometry.rectify.Rectification, optional
        None: the pixels are already rectified ones.

    Returns
    -------
    t : (M,) int64, x, y : (M,) intp, disparity : (M,) float64
    """
    keep = np.isfinite(matches["disparity"])
    m = matches[keep]
    x, y = m["x"].astype(np.intp), m["y"].astype(np.intp)
    camera = m["camera"].astype(np.intp)
    if rectification is not None:
        w, h = rectification.resolution
        inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        m, x, y, camera = m[inside], x[inside], y[inside], camera[inside]
        xy = np.stack([rectification.lut[c][y, x] for c in (0, 1)])[camera, np.arange(camera.size)]
        x, y = xy[:, 0].astype(np.intp), xy[:, 1].astype(np.intp)
        kept = x >= 0  # NONE (-1): the pixel leaves the rectified sensor
        m, x, y, camera = m[kept], x[kept], y[kept], camera[kept]
    d = m["disparity"].astype(np.float64)
    # A right-anchored match names the right pixel: its left partner lies d px to the right on the same row.
    x = np.where(camera == 1, np.rint(x + d).astype(np.intp), x)
    return m["t"].astype(np.int64), x, y, d


def _map_maker(matches: np.ndarray, resolution: tuple[int, int], rectification):
    """``map_at(ts, window_us)``: the mean disparity per rectified left pixel of the matches in ``(ts - W, ts]``."""
    t, x, y, d = rectified_left_matches(matches, rectification)
    w, h = resolution
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    t, x, y, d = t[inside], x[inside], y[inside], d[inside]

    def map_at(ts: int, window_us: int) -> np.ndarray:
        lo, hi = np.searchsorted(t, [ts - window_us, ts], side="right")
        return pixel_mean(x[lo:hi], y[lo:hi], d[lo:hi], resolution=resolution).astype(np.float32)

    return map_at


def predicted_maps(matches: np.ndarray, times: Iterable[int], *, resolution: tuple[int, int], rectification=None,
                   window_us: int = TRUTH_WINDOW_US) -> Iterator[tuple[int, np.ndarray]]:
    """The matches' disparity map at each time ``ts``: per rectified left pixel the mean disparity of its matches
    with ``ts - window_us < t <= ts``, NaN where none (float32 (height, width)).

    ``matches`` are time-ordered (docs/formats.md); pixels that fall outside the sensor are dropped.
    """
    map_at = _map_maker(matches, resolution, rectification)
    for ts in times:
        yield int(ts), map_at(int(ts), window_us)


def score_maps(matches: np.ndarray, truth: Iterable[tuple[int, np.ndarray]], *, resolution: tuple[int, int],
               rectification=None) -> dict:
    """DSEC's metrics of ``matches`` against ground-truth disparity maps (see the module doc).

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        Time-ordered.
    truth : iterable of (int, (height, width) float ndarray)
        Each map's time (us, the events' clock) and true disparities, NaN where there is none; read one at a
        time, so that a long sequence's maps are never all in memory.
    resolution : (width, height), keyword-only
    rectification : Rectification, optional, keyword-only

    Returns
    -------
    dict
        ``1PE``, ``2PE`` (fractions), ``MAE``, ``RMSE`` (px) over the answered ground-truth pixels (None when
        none is answered), ``coverage`` (the fraction of ground-truth pixels answered), ``maps``,
        ``pixels_scored``, ``truth_pixels``.
    """
    map_at = _map_maker(matches, resolution, rectification)
    totals = dict.fromkeys(("maps", "truth_pixels", "pixels_scored", "abs", "sq", *_PE_THRESHOLDS), 0)
    for ts, true in truth:
        true = np.asarray(true, dtype=np.float64)
        if true.shape != (resolution[1], resolution[0]):
            raise ValueError(f"the ground-truth map at {ts} us is {true.shape[-1]}x{true.shape[0]}; the matches' "
                             f"sensor is {resolution[0]}x{resolution[1]}.")
        predicted = map_at(int(ts), TRUTH_WINDOW_US)
        valid = np.isfinite(true)
        answered = valid & np.isfinite(predicted)
        err = np.abs(predicted[answered].astype(np.float64) - true[answered])
        totals["maps"] += 1
        totals["truth_pixels"] += int(valid.sum())
        totals["pixels_scored"] += int(err.size)
        totals["abs"] += float(err.sum())
        totals["sq"] += float(np.square(err).sum())
        for name, limit in _PE_THRESHOLDS.items():
            totals[name] += int(np.count_nonzero(err > limit))
    n = totals["pixels_scored"]
    out = {name: (totals[name] / n if n else None) for name in _PE_THRESHOLDS}
    out["MAE"] = totals["abs"] / n if n else None
    out["RMSE"] = float(np.sqrt(totals["sq"] / n)) if n else None
    out["coverage"] = n / totals["truth_pixels"] if totals["truth_pixels"] else 0.0
    out.update({k: totals[k] for k in ("maps", "pixels_scored", "truth_pixels")})
    return {k: out[k] for k in DENSE_METRICS}
