"""An MP4 of a recording: both cameras' events per window and, given matches, their colour-coded disparities.

Needs the ``video`` extra (PyAV, whose wheels ship the H.264 and VP9 encoders browsers play, and matplotlib for
the colour maps).
"""

from __future__ import annotations

import math
import os

import cv2
import numpy as np

from cvstereo.geometry.depth import DepthModel
from cvstereo.model.events import time_slice
from cvstereo.model.recording import Recording
from cvstereo.viz._images import (
    CAMERA_NAMES,
    DEFAULT_WINDOW_US,
    anchor_cameras,
    anchor_of,
    colorize,
    context_rgb,
    disparity_image,
    event_frame_rgb,
    format_distance,
    match_window_slice,
    whole_range,
    window_grid,
)
from cvstereo.viz.colormaps import DISPARITY_CMAP
from cvstereo.viz.encode import CODEC_NAMES, CODECS, video_codec, video_writer

__all__ = ["CODECS", "CODEC_NAMES", "COLORBAR_LABEL_PX_PER_FONT", "COLORBAR_PX", "GAP_PX", "GAP_RGB", "HEADER_MIN_PX",
           "HEADER_PX_PER_SCALE", "MAX_AUTO_SCALE", "MAX_WIDTH_PX", "brightest_per_block", "fit_scale", "video_codec",
           "write_video"]

#: Default largest frame width, px: a laptop screen or a browser's video column shows it without scaling down.
MAX_WIDTH_PX = 1280
#: Largest video pixels per sensor pixel chosen by :func:`fit_scale` (a 128 x 128 sensor's panels then stay a
#: few hundred px: big enough to see single events, small enough for the file).
MAX_AUTO_SCALE = 4

#: Height of the text bar above the panels per unit of ``scale``, px, and its minimum: text grows with the panels.
HEADER_PX_PER_SCALE = 8
HEADER_MIN_PX = 20

#: OpenCV's simplex font at scale 1 is about 22 px tall; its scale for a text bar of height h is h / this.
_FONT_PX = 40

#: Gap between panels, px (grey, so that black panel edges stay visible).
GAP_PX = 4
GAP_RGB = (64, 64, 64)

#: Width of the colour bar beside the disparity panels, px, and of the space for its labels per unit of font scale
#: (a label such as "120px" is about 4.5 font heights wide).
COLORBAR_PX = 12
COLORBAR_LABEL_PX_PER_FONT = 110


def fit_scale(resolution: tuple[int, int], n_disparity: int, max_width: int = MAX_WIDTH_PX) -> float:
    """Video pixels per sensor pixel that make the frame at most ``max_width`` px wide.

    A whole number (crisp sensor pixels) up to :data:`MAX_AUTO_SCALE` where one fits; below 1 (the panels
    shrunk) for sensors too wide for one sensor pixel per video pixel, e.g. 640 x 480 beside itself.

    Examples
    --------
    >>> fit_scale((128, 128), 1), fit_scale((640, 480), 1) < 1
    (3, True)
    """
    for scale in range(MAX_AUTO_SCALE, 0, -1):
        if _Layout(resolution, scale, n_disparity=n_disparity).size[0] <= max_width:
            return scale
    # Below 1: the frame is linear in the scale apart from the gaps and the colour bar at the smallest header.
    fixed = _Layout(resolution, 0, n_disparity=n_disparity).size[0] + 2
    scale = (max_width - fixed) / ((2 + n_disparity) * resolution[0])
    if scale <= 0:
        raise ValueError(f"a video frame of {2 + n_disparity} panels cannot be {max_width} px wide; allow more.")
    return math.floor(scale * 1000) / 1000


def write_video(recording: Recording, path: str | os.PathLike, result=None, *, fps: float = 25.0,
                window_us: int = DEFAULT_WINDOW_US, scale: float | None = None, seconds: float | None = None,
                depth: DepthModel | None = None, vmin: float | None = None, vmax: float | None = None,
                max_width: int = MAX_WIDTH_PX, cmap: str = DISPARITY_CMAP) -> int:
    """Write an MP4 with one frame per window: both cameras' events and, given matches, their disparities.

    Each frame shows the window ``[k*W, (k+1)*W)`` of the absolute clock: the left and right events (ON blue,
    OFF orange, on black), then for each camera the matches are anchored on, the mean disparity at each anchor
    pixel colour-coded (``cmap``; dark grey: events without a match; black: no event) and a colour bar. A text
    bar on top gives the time counted from ``recording.origin_us``, and with matches their number, median
    disparity and, given ``depth``, the distance it means. The file is H.264 (else VP9) in MP4.

    Parameters
    ----------
    recording : Recording
    path : path-like
        Output ``.mp4`` (or a name without extension, or a device or FIFO: MP4 all the same); written to a
        temporary file first and renamed when complete.
    result : MatchResult or (N,) ndarray of MATCH_DTYPE, optional
    fps : float, keyword-only
        Playback rate; 25 fps with 40 ms windows plays in real time.
    window_us : int, keyword-only
        Window per video frame, us.
    scale : float, optional, keyword-only
        Video pixels per sensor pixel; default: :func:`fit_scale` for ``max_width``.
    seconds : float, optional, keyword-only
        Only the first ``seconds`` of the recording.
    depth : DepthModel, optional, keyword-only
    max_width : int, keyword-only
        Largest frame width, px, where ``scale`` is not given.
    cmap : str, keyword-only
        Colour map of the disparities (:func:`~cvstereo.viz.colormaps.disparity_lut`).
    vmin, vmax : float, optional, keyword-only
        Disparity colour range, px; default: 0 (or the 1st percentile if lower) to 1.5 x the 99th percentile of
        all matches and the true disparities of the anchor cameras' events (see
        :func:`~cvstereo.viz._images.disparity_range`), fixed for the whole video so that a colour means the same
        disparity in every frame.

    Returns
    -------
    int
        Number of frames written: one per window from the first event's to the last event's (or ``seconds``).

    Raises
    ------
    ValueError
        Bad fps, window or scale.
    OSError
        No encoder can be opened for the file.
    MissingExtraError
        PyAV (the ``video`` extra) is not installed.
    """
    from cvstereo.viz.disparity_plots import as_result

    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}.")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a number > 0, got {scale}.")
    if int(window_us) != window_us or window_us <= 0:
        raise ValueError(f"window_us must be a positive whole number of microseconds, got {window_us}.")
    window_us = int(window_us)
    result = None if result is None else as_result(result)
    starts = window_grid(recording, window_us)
    if seconds is not None:
        if not seconds > 0:
            raise ValueError(f"seconds must be > 0, got {seconds}.")
        starts = starts[starts < starts[0] + seconds * 1e6]
    cams = [] if result is None else anchor_cameras(result)
    if result is not None:
        vmin, vmax = whole_range(recording, result, vmin, vmax)
    if scale is None:
        scale = fit_scale(recording.resolution, len(cams), max_width)
    layout = _Layout(recording.resolution, scale, n_disparity=len(cams))
    style = _Style(vmin, vmax, depth, cmap, recording.origin_us)
    with video_writer(path, fps, layout.size) as writer:
        for t0 in starts:
            writer.write(_frame(recording, result, int(t0), window_us, cams, layout, style))
    return int(starts.size)


def brightest_per_block(rgb: np.ndarray, k: int) -> np.ndarray:
    """Shrink an image by ``k`` in each direction, keeping the brightest pixel of each ``k x k`` block.

    Shrinking a sparse event image by averaging would dim single events and, for the disparity panels, turn a
    colour into a darker one that means another disparity; the brightest pixel keeps every event's own colour.

    Examples
    --------
    >>> img = np.zeros((2, 4, 3), np.uint8); img[1, 3] = (10, 200, 30)
    >>> brightest_per_block(img, 2)[0].tolist()
    [[0, 0, 0], [10, 200, 30]]
    """
    h, w = rgb.shape[:2]
    hp, wp = -(-h // k) * k, -(-w // k) * k
    padded = np.zeros((hp, wp, 3), np.uint8)
    padded[:h, :w] = rgb
    blocks = padded.reshape(hp // k, k, wp // k, k, 3).transpose(0, 2, 1, 3, 4).reshape(hp // k, wp // k, k * k, 3)
    pick = blocks.astype(np.int32).sum(axis=3).argmax(axis=2)
    return np.take_along_axis(blocks, pick[..., None, None], axis=2)[:, :, 0]


class _Style:
    """What every frame is drawn with besides its data: colour range and map, depth model, time origin."""

    def __init__(self, vmin, vmax, depth: DepthModel | None, cmap: str, origin_us: int):
        self.vmin, self.vmax, self.depth, self.cmap, self.origin_us = vmin, vmax, depth, cmap, origin_us


class _Layout:
    """Where the panels go in a video frame: a header bar, then the panels side by side with gaps."""

    def __init__(self, resolution: tuple[int, int], scale: float, *, n_disparity: int):
        self.pw, self.ph = round(resolution[0] * scale), round(resolution[1] * scale)
        n_panels = 2 + n_disparity
        self.header = max(HEADER_MIN_PX, round(HEADER_PX_PER_SCALE * scale))
        self.font = self.header / _FONT_PX
        bar = COLORBAR_PX + round(COLORBAR_LABEL_PX_PER_FONT * self.font * 0.7) if n_disparity else 0
        width = n_panels * self.pw + (n_panels + 1) * GAP_PX + bar
        height = self.header + self.ph + GAP_PX
        # Even sides: 4:2:0 video subsamples colour by 2 in each direction.
        self.size = (width + width % 2, height + height % 2)
        self.n_panels = n_panels
        self.scale = scale

    def panel_origin(self, i: int) -> tuple[int, int]:
        """(x, y) of the top-left corner of panel ``i``."""
        return GAP_PX + i * (self.pw + GAP_PX), self.header

    @property
    def colorbar_x(self) -> int:
        return self.panel_origin(self.n_panels)[0]


def _frame(recording: Recording, result, t0: int, window_us: int, cams: list[int], layout: _Layout,
           style: _Style) -> np.ndarray:
    """One video frame, RGB."""
    w, h = layout.size
    img = np.full((h, w, 3), GAP_RGB, dtype=np.uint8)
    img[:layout.header] = 0
    t1 = t0 + window_us
    panels = [(event_frame_rgb(ev[time_slice(ev, t0, t1)], resolution=recording.resolution), f"{name} events")
              for ev, name in ((recording.left, "left"), (recording.right, "right"))]
    header = f"t = {(t0 - style.origin_us) / 1e6:7.3f} s"
    if result is not None:
        anchor, _ = anchor_of(result)
        m = result.matches[match_window_slice(result.matches, t0, t1, anchor=anchor)]
        for c in cams:
            ev = recording.events(c)
            context = context_rgb(ev[time_slice(ev, t0, t1)], resolution=recording.resolution)
            panels.append((colorize(disparity_image(m, c, resolution=recording.resolution), style.vmin, style.vmax,
                                    background=context, cmap=style.cmap), f"disparity ({CAMERA_NAMES[c]})"))
        header += f"   {m.size:5d} matches"
        if m.size:
            med = float(np.median(m["disparity"]))
            header += f"   median {med:5.1f} px"
            if style.depth is not None:
                header += f" = {format_distance(float(style.depth.distance(med)))}"
        _draw_colorbar(img, layout, style)
    for i, (rgb, label) in enumerate(panels):
        x, y = layout.panel_origin(i)
        if layout.pw < rgb.shape[1]:
            rgb = brightest_per_block(rgb, math.ceil(rgb.shape[1] / layout.pw))
        big = cv2.resize(rgb, (layout.pw, layout.ph), interpolation=cv2.INTER_NEAREST)
        img[y:y + layout.ph, x:x + layout.pw] = big
        cv2.putText(img, label, (x + 3, y + int(layout.header * 0.5)), cv2.FONT_HERSHEY_SIMPLEX, layout.font * 0.7,
                    (200, 200, 200), 1, cv2.LINE_AA)
    cv2.putText(img, header, (GAP_PX, int(layout.header * 0.72)), cv2.FONT_HERSHEY_SIMPLEX, layout.font,
                (255, 255, 255), 1, cv2.LINE_AA)
    return img


def _draw_colorbar(img: np.ndarray, layout: _Layout, style: _Style) -> None:
    """A vertical colour bar from vmin (bottom) to vmax (top) beside the last panel, labelled in px."""
    x, y = layout.colorbar_x, layout.header
    vmin, vmax = style.vmin, style.vmax
    values = np.linspace(vmax, vmin, layout.ph)[:, None].repeat(COLORBAR_PX, axis=1)
    img[y:y + layout.ph, x:x + COLORBAR_PX] = colorize(values, vmin, vmax, cmap=style.cmap)
    font = layout.font * 0.7
    for value, ty in ((vmax, y + round(_FONT_PX * font * 0.6)), (vmin, y + layout.ph - 2)):
        cv2.putText(img, f"{value:.0f}px", (x + COLORBAR_PX + 2, ty), cv2.FONT_HERSHEY_SIMPLEX, font,
                    (255, 255, 255), 1, cv2.LINE_AA)
