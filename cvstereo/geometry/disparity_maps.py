"""Dense disparity images from matches: one (H, W) float image per camera and window, NaN where no match.

The data behind every disparity picture and the video (:mod:`cvstereo.viz` draws these very arrays), public
so that users can take them as data:

>>> from cvstereo.model.matches import make_matches
>>> m = make_matches([100, 200, 300], [1, 1, 0], [0, 0, 0], 1, 0, [4.0, 6.0, 9.0])
>>> disparity_image(m, 0, resolution=(2, 1))
array([[9., 5.]])
>>> [(t, img.tolist()) for t, img in window_disparity_images(m, 0, resolution=(2, 1), window_us=250)]
[(0, [[nan, 5.0]]), (250, [[9.0, nan]])]
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

__all__ = ["disparity_image", "match_window_slice", "pixel_mean", "window_disparity_images"]


def pixel_mean(x: np.ndarray, y: np.ndarray, values: np.ndarray, *, resolution: tuple[int, int]) -> np.ndarray:
    """Mean of the finite ``values`` at each pixel, NaN where a pixel has none.

    Parameters
    ----------
    x, y : (N,) int ndarray
        Pixel of each value.
    values : (N,) float ndarray
    resolution : (width, height), keyword-only

    Returns
    -------
    (height, width) float64 ndarray

    Examples
    --------
    >>> pixel_mean(np.array([0, 0, 1]), np.array([0, 0, 0]), np.array([2.0, 4.0, np.nan]), resolution=(2, 1))
    array([[ 3., nan]])
    """
    w, h = int(resolution[0]), int(resolution[1])
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    idx = np.asarray(y, np.intp)[finite] * w + np.asarray(x, np.intp)[finite]
    sums = np.bincount(idx, weights=values[finite], minlength=h * w)
    counts = np.bincount(idx, minlength=h * w)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    return out.reshape(h, w)


def match_window_slice(matches: np.ndarray, t_start: int, t_stop: int, *, anchor: str) -> slice:
    """The matches that belong to the window ``[t_start, t_stop)``.

    Event-anchored matches carry their event's time, so they belong when ``t_start <= t < t_stop``. Window-anchored
    matches carry their window's *end* (docs/formats.md), so they belong when ``t_start < t <= t_stop``.

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        Time-ordered.
    t_start, t_stop : int
        The window, us.
    anchor : {"event", "window"}, keyword-only

    Returns
    -------
    slice
    """
    side = "right" if anchor == "window" else "left"
    lo, hi = np.searchsorted(matches["t"], [t_start, t_stop], side=side)
    return slice(int(lo), int(max(lo, hi)))


def disparity_image(matches: np.ndarray, camera: int, *, resolution: tuple[int, int]) -> np.ndarray:
    """Mean disparity of the matches anchored on camera ``camera`` at each pixel (NaN: no match).

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        The matches to draw (cut a window with :func:`match_window_slice`, or use
        :func:`window_disparity_images`).
    camera : {0, 1}
        0 = left, 1 = right.
    resolution : (width, height), keyword-only

    Returns
    -------
    (height, width) float64 ndarray
        Pixels, px; NaN where the camera has no match.
    """
    m = matches[matches["camera"] == camera]
    return pixel_mean(m["x"], m["y"], m["disparity"], resolution=resolution)


def window_disparity_images(matches: np.ndarray, camera: int, *, resolution: tuple[int, int], window_us: int = 40_000,
                            anchor: str = "event") -> Iterator[tuple[int, np.ndarray]]:
    """One dense disparity image per absolute window ``[k*W, (k+1)*W)`` that holds matches.

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        Time-ordered (a matches file's ``matches``).
    camera : {0, 1}
    resolution : (width, height), keyword-only
    window_us : int, keyword-only
        W; the frame matchers' window (40 ms) by default.
    anchor : {"event", "window"}, keyword-only
        The matches file's ``meta["anchor"]``: window-anchored matches carry their window's end.

    Yields
    ------
    t_start : int
        The window's start, us.
    image : (height, width) float64 ndarray
        As :func:`disparity_image`.
    """
    if window_us <= 0:
        raise ValueError(f"window_us must be positive, got {window_us}.")
    if anchor not in ("event", "window"):
        raise ValueError(f"anchor must be 'event' or 'window', got {anchor!r} (docs/formats.md).")
    m = matches[matches["camera"] == camera]
    if not m.size:
        return
    # A window anchor at t = (k+1)*W closes window k.
    t = m["t"] - (1 if anchor == "window" else 0)
    for k in np.unique(t // window_us).tolist():
        sl = match_window_slice(m, k * window_us, (k + 1) * window_us, anchor=anchor)
        yield k * window_us, disparity_image(m[sl], camera, resolution=resolution)
