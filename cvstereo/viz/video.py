"""An MP4 of a recording: both cameras' events per window and, given matches, their colour-coded disparities.

Needs only OpenCV (a core dependency), not the ``viz`` extra.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from cvstereo.geometry.depth import DepthModel
from cvstereo.io.atomic import atomic_path, inspect_target
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
    disparity_range,
    event_frame_rgb,
    format_distance,
    match_window_slice,
    window_grid,
)

__all__ = ["CODECS", "CODEC_NAMES", "COLORBAR_LABEL_PX_PER_FONT", "COLORBAR_PX", "GAP_PX", "GAP_RGB", "HEADER_MIN_PX",
           "HEADER_PX_PER_SCALE", "video_codec", "write_video"]

#: Codecs tried in order: H.264 (``avc1``: about half the size at the same quality, where the OpenCV build has an
#: encoder for it; the opencv-python wheels have none), then MPEG-4 part 2 (``mp4v``: every OpenCV build with
#: FFmpeg writes it, and every player reads it).
CODECS = ("avc1", "mp4v")
#: What each codec is, for messages.
CODEC_NAMES = {"avc1": "H.264", "mp4v": "MPEG-4 part 2"}

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


def write_video(recording: Recording, path: str | os.PathLike, result=None, *, fps: float = 25.0,
                window_us: int = DEFAULT_WINDOW_US, scale: int = 4, seconds: float | None = None,
                depth: DepthModel | None = None, vmin: float | None = None, vmax: float | None = None) -> int:
    """Write an MP4 with one frame per window: both cameras' events and, given matches, their disparities.

    Each frame shows the window ``[k*W, (k+1)*W)`` of the absolute clock: the left and right events (ON blue,
    OFF orange, on black), then for each camera the matches are anchored on, the mean disparity at each anchor
    pixel colour-coded with the turbo map (dark grey: events without a match; black: no event) and a colour
    bar. A text bar on top gives the time, and with matches their number, median disparity and, given
    ``depth``, the distance it means.

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
    scale : int, keyword-only
        Each sensor pixel becomes ``scale`` x ``scale`` video pixels.
    seconds : float, optional, keyword-only
        Only the first ``seconds`` of the recording.
    depth : DepthModel, optional, keyword-only
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
        OpenCV cannot open a writer for the file.
    """
    from cvstereo.viz.disparity_plots import as_result

    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}.")
    if int(scale) != scale or scale < 1:
        raise ValueError(f"scale must be a whole number >= 1, got {scale}.")
    if int(window_us) != window_us or window_us <= 0:
        raise ValueError(f"window_us must be a positive whole number of microseconds, got {window_us}.")
    scale, window_us = int(scale), int(window_us)
    result = None if result is None else as_result(result)
    starts = window_grid(recording, window_us)
    if seconds is not None:
        if not seconds > 0:
            raise ValueError(f"seconds must be > 0, got {seconds}.")
        starts = starts[starts < starts[0] + seconds * 1e6]
    cams = [] if result is None else anchor_cameras(result)
    if result is not None:
        # The scene's true disparities, where known, set the colours as in plot_disparity_map: a matcher's wild
        # matches then show as outliers instead of stretching the scale.
        truths = [t for t in (recording.truth(c) for c in cams) if t is not None]
        lo, hi = disparity_range(result.disparity, reference=truths or None)
        vmin, vmax = (lo if vmin is None else vmin), (hi if vmax is None else vmax)
    layout = _Layout(recording.resolution, scale, n_disparity=len(cams))
    with _video_writer(path, fps, layout.size) as writer:
        for t0 in starts:
            writer.write(_frame(recording, result, int(t0), window_us, cams, layout, vmin, vmax, depth))
    return int(starts.size)


class _Layout:
    """Where the panels go in a video frame: a header bar, then the panels side by side with gaps."""

    def __init__(self, resolution: tuple[int, int], scale: int, *, n_disparity: int):
        self.pw, self.ph = resolution[0] * scale, resolution[1] * scale
        n_panels = 2 + n_disparity
        self.header = max(HEADER_MIN_PX, HEADER_PX_PER_SCALE * scale)
        self.font = self.header / _FONT_PX
        bar = COLORBAR_PX + round(COLORBAR_LABEL_PX_PER_FONT * self.font * 0.7) if n_disparity else 0
        width = n_panels * self.pw + (n_panels + 1) * GAP_PX + bar
        height = self.header + self.ph + GAP_PX
        # Even sides: MPEG-4 encoders subsample colour by 2 in each direction.
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
           vmin, vmax, depth: DepthModel | None) -> np.ndarray:
    """One video frame, BGR (as OpenCV writes)."""
    w, h = layout.size
    img = np.full((h, w, 3), GAP_RGB, dtype=np.uint8)
    img[:layout.header] = 0
    t1 = t0 + window_us
    panels = [(event_frame_rgb(ev[time_slice(ev, t0, t1)], resolution=recording.resolution), f"{name} events")
              for ev, name in ((recording.left, "left"), (recording.right, "right"))]
    header = f"t = {t0 / 1e6:7.3f} s"
    if result is not None:
        anchor, _ = anchor_of(result)
        m = result.matches[match_window_slice(result.matches, t0, t1, anchor=anchor)]
        for c in cams:
            ev = recording.events(c)
            context = context_rgb(ev[time_slice(ev, t0, t1)], resolution=recording.resolution)
            panels.append((colorize(disparity_image(m, c, resolution=recording.resolution), vmin, vmax,
                                    background=context), f"disparity ({CAMERA_NAMES[c]})"))
        header += f"   {m.size:5d} matches"
        if m.size:
            med = float(np.median(m["disparity"]))
            header += f"   median {med:5.1f} px"
            if depth is not None:
                header += f" = {format_distance(float(depth.distance(med)))}"
        _draw_colorbar(img, layout, vmin, vmax)
    for i, (rgb, label) in enumerate(panels):
        x, y = layout.panel_origin(i)
        big = cv2.resize(rgb, (layout.pw, layout.ph), interpolation=cv2.INTER_NEAREST)
        img[y:y + layout.ph, x:x + layout.pw] = big
        cv2.putText(img, label, (x + 3, y + int(layout.header * 0.5)), cv2.FONT_HERSHEY_SIMPLEX, layout.font * 0.7,
                    (200, 200, 200), 1, cv2.LINE_AA)
    cv2.putText(img, header, (GAP_PX, int(layout.header * 0.72)), cv2.FONT_HERSHEY_SIMPLEX, layout.font,
                (255, 255, 255), 1, cv2.LINE_AA)
    return np.ascontiguousarray(img[..., ::-1])


def _draw_colorbar(img: np.ndarray, layout: _Layout, vmin: float, vmax: float) -> None:
    """A vertical turbo bar from vmin (bottom) to vmax (top) beside the last panel, labelled in px."""
    x, y = layout.colorbar_x, layout.header
    values = np.linspace(vmax, vmin, layout.ph)[:, None].repeat(COLORBAR_PX, axis=1)
    img[y:y + layout.ph, x:x + COLORBAR_PX] = colorize(values, vmin, vmax)
    font = layout.font * 0.7
    for value, ty in ((vmax, y + round(_FONT_PX * font * 0.6)), (vmin, y + layout.ph - 2)):
        cv2.putText(img, f"{value:.0f}px", (x + COLORBAR_PX + 2, ty), cv2.FONT_HERSHEY_SIMPLEX, font,
                    (255, 255, 255), 1, cv2.LINE_AA)


@functools.cache
def video_codec() -> str:
    """The first of :data:`CODECS` that this OpenCV build can encode to MP4 (probed once, on a tiny file).

    Raises
    ------
    OSError
        No codec works: the OpenCV build lacks FFmpeg.
    """
    with tempfile.TemporaryDirectory() as folder, _quiet_stderr():
        for fourcc in CODECS:
            writer = cv2.VideoWriter(os.path.join(folder, f"probe-{fourcc}.mp4"), cv2.VideoWriter_fourcc(*fourcc),
                                     25.0, (16, 16))
            ok = writer.isOpened()
            writer.release()
            if ok:
                return fourcc
    raise OSError(f"OpenCV cannot write MP4 video with any of {', '.join(CODECS)}; this opencv build may lack "
                  "FFmpeg: try `pip install opencv-python-headless`.")


@contextlib.contextmanager
def _quiet_stderr():
    """Silence file descriptor 2 (FFmpeg prints its failed encoder probes there, not through Python)."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@contextlib.contextmanager
def _video_writer(path: str | os.PathLike, fps: float, size: tuple[int, int]):
    """A cv2.VideoWriter on a temporary file that becomes ``path`` when the block completes."""
    target = Path(path)
    if target.suffix and target.suffix.lower() != ".mp4" and not inspect_target(target)[2]:
        raise ValueError(f"{target}: the video is written as MP4; give a file name ending in .mp4 (or none).")
    fourcc = video_codec()
    with atomic_path(target) as tmp:
        # OpenCV picks the container from the extension, so the temporary file must end in .mp4 itself.
        video_tmp = tmp.with_name(tmp.name + ".mp4")
        writer = cv2.VideoWriter(str(video_tmp), cv2.VideoWriter_fourcc(*fourcc), float(fps), size)
        try:
            if not writer.isOpened():
                raise OSError(f"{target}: OpenCV cannot open a video writer ({fourcc}, {size[0]}x{size[1]}); "
                              "this opencv build may lack FFmpeg: try `pip install opencv-python-headless`.")
            yield writer
            writer.release()
            os.replace(video_tmp, tmp)
        finally:
            writer.release()
            with contextlib.suppress(FileNotFoundError):
                video_tmp.unlink()
