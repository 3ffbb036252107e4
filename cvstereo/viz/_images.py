"""The images every picture and the video are drawn from: plain numpy arrays (the colour maps' tables aside).

Keeping the data step apart from the drawing lets the plots (matplotlib) and the video (PyAV) show exactly
the same pixels, and lets tests check the data without rendering anything.
"""

from __future__ import annotations

import math

import numpy as np

from cvstereo.frames.accumulate import frame_shape
from cvstereo.geometry.depth import depth_from_meta  # noqa: F401  (re-exported by cvstereo.viz)

# The data of the disparity pictures is public in cvstereo.geometry.disparity_maps; re-exported for the plots and video.
from cvstereo.geometry.disparity_maps import disparity_image, match_window_slice, pixel_mean  # noqa: F401
from cvstereo.model.events import time_slice
from cvstereo.model.matches import MatchResult
from cvstereo.model.polarity import OFF, ON
from cvstereo.model.recording import Recording
from cvstereo.viz.colormaps import DISPARITY_CMAP, disparity_lut

#: Window length of the thesis' frames (40 ms), us.
DEFAULT_WINDOW_US = 40_000

#: Colours of ON and OFF events in every picture and the video: blue ON, orange OFF, from the Okabe-Ito palette
#: that people with any common colour-vision deficiency tell apart (the thesis' green/red is the pair that
#: red-green colour-blind readers, about 1 in 12 men, cannot). Event frames draw them on black; the signed
#: frames (filtered, dynamic) use the same hues from white (zero) to dark: ON positive, OFF negative.
ON_RGB = (86, 180, 233)
OFF_RGB = (230, 159, 0)
#: A pixel that saw ON and OFF events in one window.
BOTH_RGB = (255, 255, 255)
#: The dark ends of the signed colour scale (Okabe-Ito blue and vermillion): strong ON, strong OFF.
ON_DARK_RGB = (0, 114, 178)
OFF_DARK_RGB = (213, 94, 0)

#: Colour of pixels without a disparity in the colour-coded maps (not colour 0 of the map, which is a value).
NO_DATA_RGB = (0, 0, 0)

#: Colour of pixels that saw events but have no disparity, under the colour-coded maps: the object's silhouette,
#: so that sparse matches can be read against it. Dark enough that every colour of the map stands out.
CONTEXT_RGB = (70, 70, 70)

CAMERA_NAMES = ("left", "right")


def event_frame_rgb(events: np.ndarray, *, resolution: tuple[int, int]) -> np.ndarray:
    """Pixels that saw ON events blue, OFF events orange, both white, none black (thesis fig. 3.2).

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        One camera's events in the time span shown.
    resolution : (width, height), keyword-only

    Returns
    -------
    (height, width, 3) uint8 ndarray
        RGB.

    Examples
    --------
    >>> from cvstereo.model.events import make_events
    >>> img = event_frame_rgb(make_events([0, 1], [0, 1], [0, 0], [1, 0]), resolution=(2, 1))
    >>> img[0].tolist()
    [[86, 180, 233], [230, 159, 0]]
    """
    h, w = frame_shape(resolution)
    idx = events["y"].astype(np.intp) * w + events["x"].astype(np.intp)
    img = np.zeros((h * w, 3), dtype=np.uint8)
    on = np.zeros(h * w, dtype=bool)
    off = np.zeros(h * w, dtype=bool)
    on[idx[events["p"] == ON]] = True
    off[idx[events["p"] == OFF]] = True
    img[on] = ON_RGB
    img[off] = OFF_RGB
    img[on & off] = BOTH_RGB
    return img.reshape(h, w, 3)


def context_rgb(events: np.ndarray, *, resolution: tuple[int, int]) -> np.ndarray:
    """Pixels that saw any event in :data:`CONTEXT_RGB`, the others in :data:`NO_DATA_RGB`; (H, W, 3) uint8."""
    h, w = frame_shape(resolution)
    img = np.full((h * w, 3), NO_DATA_RGB, dtype=np.uint8)
    img[events["y"].astype(np.intp) * w + events["x"].astype(np.intp)] = CONTEXT_RGB
    return img.reshape(h, w, 3)


def anchor_of(result: MatchResult) -> tuple[str, int]:
    """(anchor, window_us) from a matches file's meta; event anchors when the meta does not say."""
    anchor = str(result.meta.get("anchor", "event"))
    if anchor not in ("event", "window"):
        raise ValueError(f"matches meta: anchor must be 'event' or 'window', got {anchor!r} (docs/formats.md).")
    return anchor, int(result.meta.get("window_us", 0) or 0)


def anchor_cameras(result: MatchResult) -> list[int]:
    """The cameras the matches are anchored on (0 = left, 1 = right), from the meta or the matches."""
    cams = result.meta.get("anchor_cameras")
    if cams is None:
        cams = np.unique(result.matches["camera"]).tolist() or [0]
    return sorted(int(c) for c in cams)


def window_grid(recording: Recording, window_us: int) -> np.ndarray:
    """Start times of the windows ``[k*W, (k+1)*W)`` on the absolute clock from the first to the last event."""
    first, last = recording.t_start // window_us, recording.t_end // window_us
    return np.arange(first, last + 1, dtype=np.int64) * window_us


def busiest_window(recording: Recording, window_us: int = DEFAULT_WINDOW_US) -> int:
    """Start (us) of the absolute window holding the most events of both cameras (a good default to show)."""
    starts = window_grid(recording, window_us)
    counts = np.zeros(starts.size, dtype=np.int64)
    for ev in (recording.left, recording.right):
        k = (ev["t"] // window_us - starts[0] // window_us).astype(np.intp)
        counts += np.bincount(k, minlength=starts.size)
    return int(starts[int(np.argmax(counts))])


def truth_image(recording: Recording, camera: int, t_start: int, t_stop: int) -> np.ndarray:
    """Mean true disparity of camera ``camera``'s events in ``[t_start, t_stop)`` at each pixel (NaN: none).

    Raises
    ------
    ValueError
        The recording has no ground truth.
    """
    truth = recording.truth(camera)
    if truth is None:
        raise ValueError("the recording has no ground truth (left_disparity/right_disparity).")
    ev = recording.events(camera)
    sl = time_slice(ev, t_start, t_stop)
    return pixel_mean(ev["x"][sl], ev["y"][sl], truth[sl], resolution=recording.resolution)


#: Percentiles of the values that set the colour range of disparity maps: the scene's own spread, not its outliers.
RANGE_PERCENTILES = (2.0, 98.0)
#: Margin added on both sides of that range: this share of its width, and at least :data:`RANGE_MIN_MARGIN_PX`, so
#: that a scene at one depth (29-30 px) still spans the colours instead of being one flat colour.
RANGE_MARGIN = 0.15
RANGE_MIN_MARGIN_PX = 1.0


def disparity_range(*arrays: np.ndarray, reference=None) -> tuple[float, float]:
    """A colour range for disparities, scaled to the data: their 2nd-98th percentile plus a margin.

    Parameters
    ----------
    *arrays : ndarray
        Disparity values (images or lists; NaN ignored).
    reference : ndarray or sequence of ndarrays, optional, keyword-only
        Values that define the scene, e.g. the true disparities where known: the range follows them, so that a
        matcher's wrong matches show at the ends of the colour scale (clipped) instead of stretching it.

    Returns
    -------
    (float, float)
        ``(vmin, vmax)``; never below 0 when no value is; ``(0, 1)`` without any value.

    Examples
    --------
    >>> disparity_range(np.array([29.0] * 50 + [30.0] * 50))
    (28.0, 31.0)
    >>> disparity_range(np.array([3.0, 29.5, 45.0]), reference=[np.array([29.0] * 50 + [30.0] * 50)])
    (28.0, 31.0)
    """
    values = _finite(reference) if reference is not None else np.empty(0)
    if values.size == 0:
        values = _finite(arrays)
    if values.size == 0:
        return 0.0, 1.0
    lo, hi = (float(v) for v in np.percentile(values, RANGE_PERCENTILES))
    margin = max(RANGE_MIN_MARGIN_PX, RANGE_MARGIN * (hi - lo))
    lo, hi = lo - margin, hi + margin
    if values.min() >= 0:
        lo = max(lo, 0.0)
    return round(lo, 6), round(hi, 6)


def whole_range(recording: Recording, result: MatchResult, vmin: float | None = None,
                vmax: float | None = None) -> tuple[float, float]:
    """The colour range of a whole run (video, rerun): fixed for every window, so that a colour means the same
    disparity throughout; set by the anchor cameras' true disparities where known (a matcher's wild matches then
    show as outliers instead of stretching the scale), else by the matches. ``vmin``/``vmax`` given win."""
    truths = [t for t in (recording.truth(c) for c in anchor_cameras(result)) if t is not None]
    lo, hi = disparity_range(result.disparity, reference=truths or None)
    return (lo if vmin is None else vmin), (hi if vmax is None else vmax)


def _finite(arrays) -> np.ndarray:
    if isinstance(arrays, np.ndarray):
        arrays = [arrays]
    values = np.concatenate([np.asarray(a, np.float64).ravel() for a in arrays] or [np.empty(0)])
    return values[np.isfinite(values)]


def colorize(image: np.ndarray, vmin: float, vmax: float, *, background: np.ndarray | None = None,
             cmap: str = DISPARITY_CMAP) -> np.ndarray:
    """Colour-code a disparity image with a colour map (:func:`~cvstereo.viz.colormaps.disparity_lut`); NaN shows
    the background.

    Parameters
    ----------
    image : (H, W) float ndarray
    vmin, vmax : float
        Values mapped to the ends of the map (clipped beyond).
    background : (H, W, 3) uint8 ndarray, optional, keyword-only
        Shown where ``image`` is NaN (e.g. :func:`context_rgb`); default black.
    cmap : str, keyword-only
        A matplotlib colour map name; default viridis (colour-blind safe), its too-dark low end cut.

    Returns
    -------
    (H, W, 3) uint8 ndarray
        RGB.
    """
    finite = np.isfinite(image)
    scaled = np.clip((np.where(finite, image, vmin) - vmin) / (vmax - vmin), 0.0, 1.0)
    lut = disparity_lut(cmap)
    rgb = lut[np.round(scaled * (lut.shape[0] - 1)).astype(np.intp)]
    rgb[~finite] = NO_DATA_RGB if background is None else background[~finite]
    return rgb


#: Times shown below this (relative to the origin) are in ms to 0.1 ms, beyond it in s to 1 ms: a panel title
#: keeps at most 6 digits, so that titles side by side do not run into each other.
_MS_UNTIL_US = 10_000_000


def format_time(t_us: int | float, origin_us: int = 0) -> str:
    """A time for titles and labels, counted from the recording's origin: ``"2040 ms"``, ``"49.600 s"``.

    Examples
    --------
    >>> format_time(1_700_000_002_040_000, 1_700_000_000_000_000), format_time(49_600_000), format_time(-100)
    ('2040 ms', '49.600 s', '-0.1 ms')
    """
    t = t_us - origin_us
    return f"{round(t / 1000, 1):g} ms" if abs(t) < _MS_UNTIL_US else f"{t / 1e6:.3f} s"


def origin_note(recording: Recording) -> str:
    """"t = 0 at ... us" where the recording's origin is not 0 (where it is, the times shown are the clock's own)."""
    origin = recording.origin_us
    return f"t = 0 at {origin} µs on the recording's clock" if origin else ""


def format_distance(metres: float) -> str:
    """A distance for labels: ``"0.98 m"``, ``"inf"`` beyond the model's range."""
    return f"{metres:.2f} m" if math.isfinite(metres) else "inf"
