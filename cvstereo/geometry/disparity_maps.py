"""Dense disparity images from matches: one (H, W) float image per camera and window, NaN where no match.

The data behind every disparity picture and the video (:mod:`cvstereo.viz` draws these very arrays), public
so that users can take them as data:

>>> from cvstereo.model.matches import make_matches
>>> m = make_matches([100, 200, 300], [1, 1, 0], [0, 0, 0], 1, 0, [4.0, 6.0, 9.0])
>>> disparity_image(m, 0, resolution=(2, 1))
array([[9., 5.]])
>>> [(t, img.tolist()) for t, img in window_disparity_images(m, 0, resolution=(2, 1), window_us=250)]
[(0, [[nan, 5.0]]), (250, [[9.0, nan]])]

:func:`disparity_images` (``cvs.disparity_images``) takes a whole :class:`~cvstereo.model.matches.MatchResult`
and reads the anchor, window and sensor size from its meta, so that no window comes out shifted.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

__all__ = ["DEFAULT_WINDOW_US", "disparity_image", "disparity_images", "match_window_slice", "pixel_mean",
           "window_disparity_images"]

#: The frame matchers' window, us: the windows of the images of event-anchored matches, whose meta has none.
DEFAULT_WINDOW_US = 40_000


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


def window_disparity_images(matches: np.ndarray, camera: int, *, resolution: tuple[int, int],
                            window_us: int = DEFAULT_WINDOW_US,
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


def disparity_images(result, *, camera: int | None = None, window_us: int | None = None,
                     resolution: tuple[int, int] | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """OpenCV-style disparity images of a match result: per window a dense float32 (H, W) image, NaN where no answer.

    The window, the anchor and the sensor size come from the result's meta (docs/formats.md), so that
    window-anchored matches (stamped with their window's *end*) land in their own window, not the next one.

    Parameters
    ----------
    result : MatchResult
        What :func:`cvstereo.match` returns or :func:`cvstereo.read_matches` reads.
    camera : {0, 1}, optional, keyword-only
        Whose pixels; default: the camera the matches are anchored on (``meta["anchor_cameras"]``, else left).
    window_us : int, optional, keyword-only
        Default: ``meta["window_us"]`` for window anchors, :data:`DEFAULT_WINDOW_US` for event anchors.
    resolution : (width, height), optional, keyword-only
        Default: ``meta["resolution"]``.

    Yields
    ------
    t_start : int
        The window ``[t_start, t_start + window_us)``, us; only windows that hold matches.
    image : (height, width) float32 ndarray
        The mean disparity x_left - x_right (px) of the pixel's matches, as ``cv2.StereoSGBM``'s output divided by
        16 holds it; NaN where the pixel has none.

    Raises
    ------
    TypeError
        ``result`` is not a MatchResult (a bare matches array: :func:`window_disparity_images`).
    ValueError
        No sensor size given or in the meta; an anchor other than ``event``/``window``.

    Examples
    --------
    >>> from cvstereo.model.matches import MatchResult, make_matches
    >>> m = make_matches([40_000, 80_000], [1, 0], [0, 0], 0, 0, [5.0, 9.0])
    >>> r = MatchResult(m, {"anchor": "window", "window_us": 40_000, "resolution": [2, 1]})
    >>> [(t, img.tolist()) for t, img in disparity_images(r)]
    [(0, [[nan, 5.0]]), (40000, [[9.0, nan]])]
    """
    from cvstereo.model.matches import MatchResult

    if not isinstance(result, MatchResult):
        raise TypeError(f"disparity_images takes a MatchResult (cvs.match, cvs.read_matches), got "
                        f"{type(result).__name__}; for a bare matches array use "
                        "cvstereo.geometry.disparity_maps.window_disparity_images(matches, camera, ...).")
    meta = result.meta
    anchor = meta.get("anchor", "event")
    if resolution is None:
        if meta.get("resolution") is None:
            raise ValueError("disparity_images: the matches' meta has no resolution; give resolution=(width, height).")
        resolution = tuple(int(v) for v in meta["resolution"])
    if window_us is None:
        window_us = int(meta.get("window_us") or DEFAULT_WINDOW_US) if anchor == "window" else DEFAULT_WINDOW_US
    if camera is None:
        camera = int((meta.get("anchor_cameras") or [0])[0])
    for t_start, image in window_disparity_images(result.matches, camera, resolution=resolution,
                                                  window_us=window_us, anchor=anchor):
        yield t_start, image.astype(np.float32)
