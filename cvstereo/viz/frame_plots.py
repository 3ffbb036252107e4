"""Pictures of the cameras' input: event frames (thesis fig. 3.2), Gaussian-filtered frames (fig. 3.3), dynamic
frames (fig. 3.5).

Each function takes a :class:`~cvstereo.model.recording.Recording` and returns a :class:`matplotlib.figure.Figure` with
the left camera on the left and the right camera on the right.
"""

from __future__ import annotations

import math

import numpy as np

from cvstereo.model.events import time_slice
from cvstereo.model.recording import Recording
from cvstereo.viz._images import (
    BOTH_RGB,
    CAMERA_NAMES,
    DEFAULT_WINDOW_US,
    OFF_RGB,
    ON_RGB,
    busiest_window,
    event_frame_rgb,
    format_time,
    origin_note,
)
from cvstereo.viz.mpl import SIGNED_CMAP, cmap_with_background, new_figure, recording_name, show_sensor_image

__all__ = ["SWATCH_EDGE", "THESIS_THRESHOLD", "dynamic_frame_values", "plot_dynamic_frames", "plot_event_frames",
           "plot_filtered_frames"]

#: The thesis' threshold on filtered frames (eq. 3.7) and on dynamic frames (event-time matcher): 1.2.
THESIS_THRESHOLD = 1.2

#: Events older than this share of their initial weight are left out of a dynamic frame: below what a plot shows.
_DYNAMIC_NEGLIGIBLE = 1e-6

#: Edge colour of the legend swatches (matplotlib grey level): visible around white and the light hues alike.
SWATCH_EDGE = "0.3"

#: Size of one sensor panel, inches.
_PANEL_IN = 4.0


def _of(recording: Recording) -> str:
    """' of NAME' for titles, where the recording has a preset, scene or file name (else '')."""
    name = recording_name(recording.meta)
    return f" of {name}" if name else ""


def _check_window(window_us: int) -> int:
    if int(window_us) != window_us or window_us <= 0:
        raise ValueError(f"window_us must be a positive whole number of microseconds (the thesis uses 40000), "
                         f"got {window_us}.")
    return int(window_us)


def _window_start(recording: Recording, t_start_us: int | None, window_us: int) -> int:
    return busiest_window(recording, window_us) if t_start_us is None else int(t_start_us)


def _span(recording: Recording, t0: int, t1: int) -> str:
    """``[t0, t1)`` counted from the recording's origin."""
    return f"[{format_time(t0, recording.origin_us)}, {format_time(t1, recording.origin_us)})"


def _suptitle(fig, recording: Recording, text: str) -> None:
    """The figure's title, with the absolute time of t = 0 below it where that is not 0."""
    note = origin_note(recording)
    fig.suptitle(f"{text}\n{note}" if note else text)


def _camera_title(cam: int, n_events: int | None = None) -> str:
    base = f"{CAMERA_NAMES[cam]} camera ({cam})"
    return base if n_events is None else f"{base}: {n_events:,} events"


def plot_event_frames(recording: Recording, t_start_us: int | None = None, *,
                      window_us: int = DEFAULT_WINDOW_US, title: str | None = None):
    """Both cameras' events of one window, ON blue and OFF orange on black (thesis fig. 3.2).

    Parameters
    ----------
    recording : Recording
    t_start_us : int, optional
        Start of the window ``[t_start_us, t_start_us + window_us)``, us on the recording's (absolute) clock;
        default: the absolute window with the most events. Titles count from ``recording.origin_us``.
    window_us : int, keyword-only
        Window length, us (thesis: 40 ms; 2 ms gives its fig. 3.1).
    title : str, optional, keyword-only
        Figure title; default: the window.

    Returns
    -------
    matplotlib.figure.Figure
        Two image axes (left, right camera). A pixel that saw both polarities in the window is white.
    """
    from matplotlib.patches import Patch

    window_us = _check_window(window_us)
    t0 = _window_start(recording, t_start_us, window_us)
    fig = new_figure(2 * _PANEL_IN + 0.4, _PANEL_IN + 0.7)
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    for cam, ax in enumerate(axes):
        ev = recording.events(cam)
        ev = ev[time_slice(ev, t0, t0 + window_us)]
        show_sensor_image(ax, event_frame_rgb(ev, resolution=recording.resolution),
                          title=_camera_title(cam, ev.size))
        ax.label_outer()
    # A grey edge on every swatch: the white of "ON and OFF" is otherwise invisible on the white figure.
    handles = [Patch(facecolor=np.array(rgb) / 255, edgecolor=SWATCH_EDGE, linewidth=0.8, label=label)
               for rgb, label in ((ON_RGB, "ON"), (OFF_RGB, "OFF"), (BOTH_RGB, "ON and OFF"))]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, frameon=False)
    _suptitle(fig, recording, title or f"Events in {_span(recording, t0, t0 + window_us)}{_of(recording)}")
    return fig


def _signed_grid(fig, rows: list[tuple[str, list[np.ndarray], bool]], *, threshold: float, colorbar_label: str):
    """Rows of (left, right) signed images with one diverging colour scale and the ±threshold contour.

    ``rows`` holds ``(row label, [left image, right image], thresholded)``; a thresholded row shows only the
    pixels with ``|value| >= threshold`` (thesis fig. 3.3, bottom).
    """
    from matplotlib.colors import Normalize

    # Symmetric about 0 so that white is 0, and at least 1.5x the threshold so the contour is not at the ends.
    vmax = max([threshold * 1.5] + [float(np.nanmax(np.abs(img))) for _, imgs, _ in rows for img in imgs])
    norm = Normalize(-vmax, vmax)
    cmap = cmap_with_background(SIGNED_CMAP, background=(1.0, 1.0, 1.0))
    axes = fig.subplots(len(rows), 2, sharex=True, sharey=True, squeeze=False)
    im = None
    for r, (label, images, thresholded) in enumerate(rows):
        for cam, img in enumerate(images):
            ax = axes[r, cam]
            shown = np.where(np.abs(img) >= threshold, img, np.nan) if thresholded else img
            im = show_sensor_image(ax, shown, cmap=cmap, norm=norm, title=f"{_camera_title(cam)}: {label}")
            if not thresholded:
                _threshold_contour(ax, img, threshold)
    for ax in axes.flat:
        ax.label_outer()
    cbar = fig.colorbar(im, ax=axes, shrink=0.8, label=colorbar_label)
    for level in (-threshold, threshold):
        cbar.ax.axhline(level, color="k", linewidth=0.8)
    return axes


def _threshold_contour(ax, img: np.ndarray, threshold: float) -> None:
    """Black contour where ``|img|`` crosses ``threshold`` (only levels the image reaches: no empty contours)."""
    levels = [lv for lv in (-threshold, threshold) if np.nanmin(img) < lv < np.nanmax(img)]
    if levels:
        h, w = img.shape
        ax.contour(np.arange(w), np.arange(h), img, levels=levels, colors="k", linewidths=0.7)


def plot_filtered_frames(recording: Recording, t_start_us: int | None = None, *,
                         window_us: int = DEFAULT_WINDOW_US, sigma: float = 1.0, kernel_size: int = 5,
                         threshold: float = THESIS_THRESHOLD, title: str | None = None):
    """Signed frames of one window after the thesis' 5x5 Gaussian, and the pixels above threshold (fig. 3.3).

    Parameters
    ----------
    recording : Recording
    t_start_us : int, optional
        Start of the window, us; default: the absolute window with the most events.
    window_us : int, keyword-only
    sigma, kernel_size : keyword-only
        The Gaussian (thesis: 1 px, 5x5; eq. 3.6).
    threshold : float, keyword-only
        Drawn as a contour at ``±threshold`` on the filtered frames; the bottom row keeps only the pixels with
        ``|value| >= threshold`` (thesis eq. 3.7: 1.2).
    title : str, optional, keyword-only

    Returns
    -------
    matplotlib.figure.Figure
        2 x 2 axes: filtered frames (top), thresholded (bottom); blue = ON, orange = OFF (as the event frames).
    """
    from cvstereo.frames.accumulate import gaussian_filter, signed_frame

    window_us = _check_window(window_us)
    t0 = _window_start(recording, t_start_us, window_us)
    filtered = []
    for cam in (0, 1):
        ev = recording.events(cam)
        frame = signed_frame(ev[time_slice(ev, t0, t0 + window_us)], resolution=recording.resolution)
        filtered.append(gaussian_filter(frame, sigma=sigma, kernel_size=kernel_size))
    fig = new_figure(2 * _PANEL_IN + 1.2, 2 * _PANEL_IN + 0.6)
    _signed_grid(fig, [(f"Gaussian {kernel_size}x{kernel_size}, σ={sigma:g}", filtered, False),
                       (f"|value| ≥ {threshold:g}", filtered, True)],
                 threshold=threshold, colorbar_label="filtered sum of event signs (ON +1, OFF −1)")
    _suptitle(fig, recording, title or f"Filtered frames of {_span(recording, t0, t0 + window_us)}{_of(recording)}; "
              f"contour at ±{threshold:g}")
    return fig


def dynamic_frame_values(recording: Recording, t_us: int, *, params=None) -> list[np.ndarray]:
    """Both cameras' dynamic frames at time ``t_us`` (events at ``t <= t_us`` included).

    Parameters
    ----------
    recording : Recording
    t_us : int
    params : cvstereo.frames.dynamic.DynamicFrameParams, optional, keyword-only
        Default: the thesis' (3x3 Gaussian of gain 2, x0.99 every 250 us, ON and OFF shared).

    Returns
    -------
    list of two (n_frames, H, W) float64 ndarrays
        Left and right camera; ``n_frames`` is 2 (OFF, ON) for ``polarity="separate"``, else 1.
    """
    from cvstereo.frames.dynamic import DynamicFrameParams, FrameBank

    params = params if params is not None else DynamicFrameParams()
    # Older events have decayed below what a picture can show; leave them out rather than replay the recording.
    if params.decay < 1:
        ticks = math.ceil(math.log(_DYNAMIC_NEGLIGIBLE) / math.log(params.decay))
        since = int(t_us) - (ticks + 1) * params.decay_period_us
    else:
        since = None
    bank = FrameBank(2, params, resolution=recording.resolution)
    out = []
    for cam in (0, 1):
        ev = recording.events(cam)
        bank.process(cam, ev[time_slice(ev, since, int(t_us) + 1)])
        out.append(bank.values(cam, int(t_us)))
    return out


def plot_dynamic_frames(recording: Recording, t_us: int | None = None, *, params=None,
                        threshold: float = THESIS_THRESHOLD, title: str | None = None):
    """Both cameras' dynamic frames (rolling, decaying event memories) at one instant (thesis fig. 3.5).

    Parameters
    ----------
    recording : Recording
    t_us : int, optional
        The instant, us; default: the end of the 40 ms window with the most events.
    params : cvstereo.frames.dynamic.DynamicFrameParams, optional, keyword-only
        Default: the thesis'. With ``polarity="separate"`` the ON and OFF frames are shown in two rows.
    threshold : float, keyword-only
        Contour at ``±threshold``: the event-time matcher only matches where the frame exceeds it (thesis: 1.2).
    title : str, optional, keyword-only

    Returns
    -------
    matplotlib.figure.Figure
    """
    from cvstereo.frames.dynamic import DynamicFrameParams

    params = params if params is not None else DynamicFrameParams()
    t = busiest_window(recording, DEFAULT_WINDOW_US) + DEFAULT_WINDOW_US if t_us is None else int(t_us)
    values = dynamic_frame_values(recording, t, params=params)
    n_frames = values[0].shape[0]
    labels = ["OFF frame", "ON frame"] if n_frames == 2 else [f"{params.polarity} dynamic frame"]
    rows = [(labels[i], [values[0][i], values[1][i]], False) for i in range(n_frames)]
    fig = new_figure(2 * _PANEL_IN + 1.2, n_frames * _PANEL_IN + 0.6)
    _signed_grid(fig, rows, threshold=threshold, colorbar_label="dynamic frame value (ON +, OFF −)")
    _suptitle(fig, recording, title or f"Dynamic frames{_of(recording)} at t = {format_time(t, recording.origin_us)} "
              f"(×{params.decay:g} every {params.decay_period_us} µs); contour at ±{threshold:g}")
    return fig
