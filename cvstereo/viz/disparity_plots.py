"""Pictures of a matcher's output: disparity over time (thesis figs. 4.4, 4.5), colour-coded disparity per window
(figs. 4.3, 4.6), and the error against ground truth.

Each function takes the :class:`~cvstereo.model.recording.Recording` the matches were computed on and the
:class:`~cvstereo.model.matches.MatchResult` (or a bare matches array), and returns a :class:`matplotlib.figure.Figure`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cvstereo.evaluation.metrics import evaluate, match_truth
from cvstereo.geometry.depth import DepthModel
from cvstereo.model.events import time_slice
from cvstereo.model.matches import MatchResult
from cvstereo.model.recording import Recording
from cvstereo.viz._images import (
    CAMERA_NAMES,
    DEFAULT_WINDOW_US,
    anchor_cameras,
    anchor_of,
    context_rgb,
    disparity_image,
    disparity_range,
    event_frame_rgb,
    format_time,
    match_window_slice,
    origin_note,
    truth_image,
)
from cvstereo.viz.colormaps import DISPARITY_CMAP, listed_cmap
from cvstereo.viz.mpl import add_metres_axis, figure_title, new_figure, show_sensor_image

__all__ = ["ERROR_BIN_PX", "TRUTH_BAND", "as_result", "fill_gaps", "grouped_percentiles", "picture_window",
           "plot_disparity_map", "plot_disparity_over_time", "plot_error_histogram", "window_truth"]

#: Share of the truth drawn as a band around its median per window (10th to 90th percentile): wide enough to
#: show two objects at different distances, narrow enough to ignore stray events at object borders.
TRUTH_BAND = (10, 90)

#: Percentiles of the disparities that set the over-time plot's y range: a handful of wild matches must not
#: squash the rest into a line; how many fall outside is written on the plot.
_Y_RANGE_PERCENTILES = (0.5, 99.5)

#: Error histogram: bin width and the range shown (errors beyond are counted in the outermost bins).
ERROR_BIN_PX = 0.5
_ERROR_RANGE_PX = (3.0, 40.0)


def as_result(result) -> MatchResult:
    """A :class:`MatchResult`; a bare matches array is taken as event-anchored."""
    if isinstance(result, MatchResult):
        return result
    matches = np.asarray(result)
    if matches.dtype.names is None or "disparity" not in matches.dtype.names:
        raise TypeError(f"expected a MatchResult or a matches array (MATCH_DTYPE), got {type(result).__name__}.")
    return MatchResult(matches, {"anchor": "event", "window_us": 0})


def picture_window(result: MatchResult, window_us: int | None) -> int:
    """The window of a picture: the matcher's own for window anchors, else ``window_us`` (default 40 ms)."""
    anchor, own = anchor_of(result)
    if anchor == "window" and own > 0:
        return own
    return int(window_us or DEFAULT_WINDOW_US)


def _window_keys(result: MatchResult, window_us: int) -> np.ndarray:
    """Index k of the absolute window ``[k*W, (k+1)*W)`` each match belongs to."""
    anchor, _ = anchor_of(result)
    t = result.matches["t"]
    # A window match is stamped with its window's end, which is the start of the next window.
    return (t - 1) // window_us if anchor == "window" else t // window_us


def grouped_percentiles(keys: np.ndarray, values: np.ndarray, q: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Percentiles ``q`` of the finite ``values`` in each group of equal ``keys``.

    Returns
    -------
    groups : (G,) ndarray
        The distinct keys that have finite values, ascending.
    percentiles : (G, len(q)) float64 ndarray
    """
    values = np.asarray(values, np.float64)
    finite = np.isfinite(values)
    keys, values = np.asarray(keys)[finite], values[finite]
    order = np.lexsort((values, keys))
    keys, values = keys[order], values[order]
    groups, starts = np.unique(keys, return_index=True)
    parts = np.split(values, starts[1:])
    out = np.array([np.percentile(p, q) for p in parts]).reshape(len(parts), len(q))
    return groups, out


def fill_gaps(groups: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Spread per-window rows over every window from the first to the last, NaN rows where a window is missing.

    Lines drawn through the result break over windows without data instead of bridging them.

    Examples
    --------
    >>> k, v = fill_gaps(np.array([2, 3, 5]), np.array([[1.0], [2.0], [3.0]]))
    >>> k.tolist(), v[:, 0].tolist()
    ([2, 3, 4, 5], [1.0, 2.0, nan, 3.0])
    """
    if groups.size == 0:
        return groups, values
    keys = np.arange(groups[0], groups[-1] + 1)
    out = np.full((keys.size, *values.shape[1:]), np.nan)
    out[groups - groups[0]] = values
    return keys, out


def window_truth(recording: Recording, cameras: Sequence[int], window_us: int,
                 q: Sequence[float] = (50, *TRUTH_BAND)) -> tuple[np.ndarray, np.ndarray]:
    """Percentiles of the true disparity of the events of ``cameras`` per absolute window.

    Returns
    -------
    starts : (G,) int64 ndarray
        Window starts (us) from the first to the last window holding events with finite truth.
    percentiles : (G, len(q)) float64 ndarray
        NaN for windows without such events.
    """
    keys = np.concatenate([recording.events(c)["t"] // window_us for c in cameras])
    values = np.concatenate([recording.truth(c) for c in cameras])
    groups, pct = grouped_percentiles(keys, values, q)
    groups, pct = fill_gaps(groups, pct)
    return groups * window_us, pct


def plot_disparity_over_time(recording: Recording, result, *, window_us: int | None = None,
                             depth: DepthModel | None = None, title: str | None = None):
    """Every match's disparity against time, its median per window, and the ground truth (thesis figs. 4.4, 4.5).

    Parameters
    ----------
    recording : Recording
        The recording the matches came from; its ground truth, if any, is drawn as the median true disparity of
        the anchor cameras' events per window with a 10-90 % band.
    result : MatchResult or (N,) ndarray of MATCH_DTYPE
    window_us : int, optional, keyword-only
        Window of the medians; default: the matcher's window for frame matchers, else 40 ms.
    depth : DepthModel, optional, keyword-only
        Adds a distance axis (m) on the right.
    title : str, optional, keyword-only

    Returns
    -------
    matplotlib.figure.Figure
        One axes: time (s, from ``recording.origin_us``) against disparity (px). Its first line holds the matches
        themselves.
    """
    result = as_result(result)
    matches = result.matches
    window_us = picture_window(result, window_us)
    fig = new_figure(10.0, 4.8)
    ax = fig.subplots()
    disp = matches["disparity"].astype(np.float64)
    origin = recording.origin_us
    ax.plot((matches["t"] - origin) / 1e6, disp, linestyle="none", marker=".", markersize=2.0, markeredgewidth=0,
            color="tab:blue", alpha=_point_alpha(disp.size), rasterized=True, label=f"matches ({disp.size:,})")
    lows, highs = [], []
    if disp.size:
        groups, med = fill_gaps(*grouped_percentiles(_window_keys(result, window_us), disp, [50]))
        centre = (groups * window_us + window_us / 2 - origin) / 1e6
        ax.plot(centre, med[:, 0], color="tab:orange", linewidth=1.5,
                label=f"median of matches per {window_us / 1000:g} ms")
        lows.append(np.percentile(disp, _Y_RANGE_PERCENTILES[0]))
        highs.append(np.percentile(disp, _Y_RANGE_PERCENTILES[1]))
    if recording.has_truth:
        starts, pct = window_truth(recording, anchor_cameras(result), window_us)
        if starts.size:
            centre = (starts + window_us / 2 - origin) / 1e6
            ax.fill_between(centre, pct[:, 1], pct[:, 2], color="k", alpha=0.15, linewidth=0,
                            label=f"truth, {TRUTH_BAND[0]}-{TRUTH_BAND[1]} % of events")
            ax.plot(centre, pct[:, 0], color="k", linestyle="--", linewidth=1.2,
                    label=f"truth, median per {window_us / 1000:g} ms")
            lows.append(float(np.nanmin(pct[:, 1])))
            highs.append(float(np.nanmax(pct[:, 2])))
    if lows:
        lo, hi = min(0.0, min(lows)), max(highs)
        pad = 0.05 * max(hi - lo, 1.0)
        ax.set_ylim(lo - (pad if lo < 0 else 0), hi + pad)
        outside = int(np.count_nonzero((disp < ax.get_ylim()[0]) | (disp > ax.get_ylim()[1])))
        if outside:
            share = outside / disp.size
            ax.text(0.01, 0.98, f"{outside:,} matches ({'<0.1%' if share < 0.001 else f'{share:.1%}'}) outside "
                    "the plotted range",
                    transform=ax.transAxes, va="top", fontsize="small", color="0.3")
    note = origin_note(recording)
    ax.set_xlabel(f"time (s; {note})" if note else "time (s)")
    ax.set_ylabel("disparity (px)")
    ax.grid(True, alpha=0.3)
    # Below the axes: inside, any corner may hide matches.
    fig.legend(loc="outside lower center", ncols=4, fontsize="small", markerscale=4, frameon=False)
    if depth is not None:
        add_metres_axis(ax, depth)
    ax.set_title(title or ("Disparity over time: " + (figure_title(result.meta, recording.meta) or "matches")))
    return fig


def _point_alpha(n: int) -> float:
    # Dense clouds need translucent points to show where most matches lie; a few points stay opaque.
    return float(np.clip(300.0 / math.sqrt(max(n, 1)), 0.08, 1.0))


def _pick_windows(result: MatchResult, window_us: int, n_windows: int) -> list[int]:
    """Ends (us) of ``n_windows`` windows holding matches, evenly spread over the matches' time span."""
    keys = np.unique(_window_keys(result, window_us))
    if keys.size == 0:
        raise ValueError("there are no matches to show; run a matcher on the recording first.")
    n = min(int(n_windows), keys.size)
    # Interior points of an even spread: the first and last windows are often half empty.
    pos = np.round(np.linspace(0, keys.size - 1, n + 2)[1:-1]).astype(int) if keys.size > n else np.arange(n)
    return [int((keys[i] + 1) * window_us) for i in pos]


def plot_disparity_map(recording: Recording, result, t_end_us: int | Sequence[int] | None = None, *,
                       n_windows: int = 3, window_us: int | None = None, depth: DepthModel | None = None,
                       vmin: float | None = None, vmax: float | None = None, title: str | None = None,
                       cmap: str = DISPARITY_CMAP):
    """Colour-coded disparities at their anchor pixels, one row per window (thesis figs. 4.3, 4.6).

    Each row shows a window ``[t_end - W, t_end)``: both cameras' events (ON blue, OFF orange), then for each
    camera the matches are anchored on, the mean disparity of its matches at each pixel, and the true disparity
    of its events there when the recording has ground truth. Pixels that saw events of that camera but have no
    value are dark grey (the object's silhouette), the others black.

    Parameters
    ----------
    recording : Recording
    result : MatchResult or (N,) ndarray of MATCH_DTYPE
    t_end_us : int or sequence of int, optional
        End(s) of the window(s), us on the recording's (absolute) clock; default: ``n_windows`` windows spread over
        the matches. Titles count from ``recording.origin_us``.
    n_windows : int, keyword-only
    window_us : int, optional, keyword-only
        Window length W; default: the matcher's for frame matchers, else 40 ms.
    depth : DepthModel, optional, keyword-only
        Adds distances (m) beside the colour bar.
    vmin, vmax : float, optional, keyword-only
        Colour range, px; default: from the disparities and truths shown (0 to 1.5 x their 99th percentile, see
        :func:`~cvstereo.viz._images.disparity_range`).
    title : str, optional, keyword-only
    cmap : str, keyword-only
        Colour map of the disparities (:func:`~cvstereo.viz.colormaps.disparity_lut`); default colour-blind safe.

    Returns
    -------
    matplotlib.figure.Figure
        The disparity panels are titled with the number of matches they hold.
    """
    result = as_result(result)
    window_us = picture_window(result, window_us)
    if t_end_us is None:
        ends = _pick_windows(result, window_us, n_windows)
    else:
        ends = [int(t_end_us)] if np.ndim(t_end_us) == 0 else [int(t) for t in t_end_us]
    if not ends:
        raise ValueError("give at least one window end (t_end_us).")
    anchor, _ = anchor_of(result)
    cams = anchor_cameras(result)
    res = recording.resolution
    rows = []
    for t_end in ends:
        t0 = t_end - window_us
        frames = [event_frame_rgb(recording.events(c)[time_slice(recording.events(c), t0, t_end)], resolution=res)
                  for c in (0, 1)]
        m = result.matches[match_window_slice(result.matches, t0, t_end, anchor=anchor)]
        maps = []
        for c in cams:
            ev = recording.events(c)
            context = context_rgb(ev[time_slice(ev, t0, t_end)], resolution=res)
            maps.append((f"disparity ({CAMERA_NAMES[c]})", disparity_image(m, c, resolution=res),
                         int(np.count_nonzero(m["camera"] == c)), context))
            if recording.has_truth:
                maps.append((f"truth ({CAMERA_NAMES[c]})", truth_image(recording, c, t0, t_end), None, context))
        rows.append((t0, t_end, frames, maps))
    estimates = [img for *_, maps in rows for label, img, count, _ in maps if count is not None]
    truths = [img for *_, maps in rows for label, img, count, _ in maps if count is None]
    lo, hi = disparity_range(*estimates, reference=truths or None)
    norm_lo, norm_hi = lo if vmin is None else vmin, hi if vmax is None else vmax
    title = title or ("Disparity per window: " + (figure_title(result.meta, recording.meta) or "matches"))
    note = origin_note(recording)
    return _draw_map_grid(rows, norm_lo, norm_hi, depth=depth, title=f"{title}\n{note}" if note else title,
                          cmap=cmap, origin_us=recording.origin_us)


def _draw_map_grid(rows, vmin: float, vmax: float, *, depth: DepthModel | None, title: str, cmap: str,
                   origin_us: int):
    from matplotlib.colors import Normalize

    n_cols = 2 + len(rows[0][3])
    panel = 2.6
    # 0.9 in beyond the panels for the title, the x labels and the colour bar's ends (one row clipped them at 0.5).
    fig = new_figure(n_cols * panel + 1.0, len(rows) * panel + 0.9)
    axes = fig.subplots(len(rows), n_cols, sharex=True, sharey=True, squeeze=False)
    # NaN transparent: the anchor camera's events show through in grey where they got no disparity.
    colours = listed_cmap(cmap)
    norm = Normalize(vmin, vmax)
    im = None
    for r, (t0, t_end, frames, maps) in enumerate(rows):
        span = f"{format_time(t0, origin_us)} + {format_time(t_end - t0)}"
        for c, frame in enumerate(frames):
            show_sensor_image(axes[r, c], frame, title=f"{CAMERA_NAMES[c]} events, {span}")
        for j, (label, img, count, context) in enumerate(maps):
            suffix = "" if count is None else f", {count:,} match{'es' if count != 1 else ''}"
            show_sensor_image(axes[r, 2 + j], context)
            im = show_sensor_image(axes[r, 2 + j], img, cmap=colours, norm=norm, title=label + suffix)
    for ax in axes.flat:
        ax.label_outer()
        ax.title.set_fontsize("small")
    # Arrows at both ends: values beyond the range (a matcher's outliers) take the end colours.
    cbar = fig.colorbar(im, ax=axes, shrink=0.9 if len(rows) > 1 else 1.0, label="disparity (px)", extend="both")
    if depth is not None:
        add_metres_axis(cbar.ax, depth, location="left")
    fig.suptitle(title)
    return fig


def plot_error_histogram(recording: Recording, result, *, bin_px: float = ERROR_BIN_PX,
                         limit_px: float | None = None, log: bool = False, title: str | None = None):
    """Histogram of the signed error (estimate - truth) of the matches that have ground truth.

    Parameters
    ----------
    recording : Recording
        With ground truth.
    result : MatchResult or (N,) ndarray of MATCH_DTYPE
    bin_px : float, keyword-only
        Bin width, px.
    limit_px : float, optional, keyword-only
        Errors shown in ``[-limit_px, limit_px]``, larger ones counted in the outermost bins; default: the 99th
        percentile of ``|error|``, between 3 and 40 px.
    log : bool, keyword-only
        Logarithmic count axis, so that the tails of rare large errors show beside the peak.
    title : str, optional, keyword-only
        Default: method, MAE, bad1 (share of |error| > 1 px), false-match rate.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        The recording has no ground truth, or no match has any.
    """
    result = as_result(result)
    if not recording.has_truth:
        raise ValueError("the error histogram needs a recording with ground truth (left_disparity/right_disparity).")
    if not bin_px > 0:
        raise ValueError(f"bin_px must be > 0, got {bin_px}.")
    anchor, window = anchor_of(result)
    truth = match_truth(recording, result.matches, anchor=anchor, window_us=window)
    has = np.isfinite(truth)
    if not has.any():
        raise ValueError(f"none of the {result.matches.size:,} matches has ground truth (all are anchored on noise "
                         "or background); is it the right recording?")
    err = result.matches["disparity"][has].astype(np.float64) - truth[has]
    if limit_px is None:
        # One px beyond the 99th percentile, so that the tail shows before the outer bins collect the rest.
        limit_px = float(np.clip(np.ceil(np.percentile(np.abs(err), 99)) + 1, *_ERROR_RANGE_PX))
    n_bins = max(1, math.ceil(limit_px / bin_px))
    edges = np.arange(-n_bins, n_bins + 1) * bin_px
    fig = new_figure(8.0, 4.5)
    ax = fig.subplots()
    ax.axvspan(-1, 1, color="tab:green", alpha=0.12, linewidth=0, label="|error| ≤ 1 px")
    ax.hist(np.clip(err, edges[0], edges[-1]), bins=edges, color="tab:blue", edgecolor="white", linewidth=0.3,
            label=f"matches with truth ({err.size:,})")
    beyond = int(np.count_nonzero(np.abs(err) > edges[-1]))
    if beyond:
        ax.text(0.01, 0.98, f"{beyond:,} errors beyond ±{edges[-1]:g} px counted in the outer bins",
                transform=ax.transAxes, va="top", fontsize="small", color="0.3")
    ax.axvline(0, color="k", linewidth=0.8)
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel("disparity error: estimate − truth (px)")
    ax.set_ylabel("matches (log scale)" if log else "matches")
    if log:
        ax.set_yscale("log")
    ax.legend(loc="upper right", fontsize="small")
    f = evaluate(recording, result)
    name = figure_title(result.meta, recording.meta) or "matches"
    ax.set_title(title or f"Disparity error: {name}\nMAE {f['mae']:.2f} px, bad1 (|error| > 1 px) {f['bad1']:.1%}, "
                 f"median error {np.median(err):+.2f} px, false matches {f['false_rate']:.1%}")
    return fig
