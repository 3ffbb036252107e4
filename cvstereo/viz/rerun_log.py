"""``--rerun``: a recording and its matches in the rerun viewer, live or as an ``.rrd`` file (the ``rerun`` extra).

One timeline, ``time``: for a recording (``match``, ``video``) counted from its origin, one step per window; for
``live``, the rig's clock, one step per packet (:class:`LiveLog`). The entities:

=====================================  =========================================================================
entity                                 what
=====================================  =========================================================================
``cameras/{left,right}/events``        the window's events as 2D points, ON blue, OFF orange
``cameras/{cam}/disparity``            the colour-coded disparity image of the anchor camera ``cam``
``cameras/{cam}/depth``                its distance in metres (a depth image), where a depth model is known
``world/points``                       the window's matches as 3D points (metres, left camera frame), likewise
=====================================  =========================================================================
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import require_extra
from cvstereo.model.events import time_slice
from cvstereo.model.recording import Recording
from cvstereo.viz._images import (
    CAMERA_NAMES,
    DEFAULT_WINDOW_US,
    OFF_RGB,
    ON_RGB,
    anchor_cameras,
    anchor_of,
    colorize,
    disparity_image,
    match_window_slice,
    whole_range,
    window_grid,
)
from cvstereo.viz.colormaps import DISPARITY_CMAP, disparity_lut

__all__ = ["APPLICATION_ID", "TIMELINE", "LiveLog", "entity_paths", "log_step", "log_windows", "rerun_stream"]

#: The application the recordings belong to in the viewer, and the name of their timeline.
APPLICATION_ID, TIMELINE = "cvstereo", "time"


@contextlib.contextmanager
def rerun_stream(target) -> Iterator[object]:
    """A ``rerun.RecordingStream`` to log into: written atomically to ``target.path``
    (:class:`cvstereo.cli._rerun.RerunTarget`), else to a spawned viewer; None where ``--rerun`` was not given.

    Opened before the work it shows, so that a viewer that cannot start is said at once.

    Raises
    ------
    OSError
        No viewer can be started (the file form still works).
    """
    if not target.wanted:
        yield None
        return
    import rerun as rr

    from cvstereo.io.atomic import atomic_path

    stream = rr.RecordingStream(APPLICATION_ID)
    if target.path is None:
        try:
            stream.spawn()
        except Exception as exc:  # the SDK raises its own types: the viewer binary missing or not starting
            reason = str(exc).split(".")[0].strip()  # the SDK's first sentence; the rest is installation advice
            raise OSError(f"--rerun: cannot start a rerun viewer ({reason}); give --rerun FILE.rrd to write a "
                          "file instead.") from exc
        yield stream
        stream.flush()
        return
    with atomic_path(target.path) as tmp:
        stream.save(os.fspath(tmp))
        try:
            yield stream
            stream.flush()
        finally:
            stream.disconnect()


def log_windows(stream, recording: Recording, result=None, *, window_us: int | None = None, depth=None,
                intrinsics=None,
                cmap: str = DISPARITY_CMAP, vmin: float | None = None, vmax: float | None = None,
                seconds: float | None = None) -> int:
    """Log every window ``[k*W, (k+1)*W)`` of the absolute clock (the video's frames) into ``stream``.

    Parameters
    ----------
    stream : rerun.RecordingStream
    recording : Recording
    result : MatchResult, optional
        Without it only the events are logged.
    window_us : int, optional, keyword-only
        Default: the matcher's own window for frame matchers, else 40 ms (as the pictures).
    depth : DepthModel, optional, keyword-only
        Adds the depth images and, with ``intrinsics``, the 3D points.
    intrinsics : cvstereo.geometry.pointcloud.Intrinsics, optional, keyword-only
        Default: :meth:`~cvstereo.geometry.pointcloud.Intrinsics.from_options` of the recording's rig.
    cmap, vmin, vmax : keyword-only
        The disparity colours, as the video's (default range: :func:`~cvstereo.viz._images.whole_range`).
    seconds : float, optional, keyword-only
        Only the first ``seconds`` (the windows the video shows).

    Returns
    -------
    int
        Windows logged.
    """
    from cvstereo.viz.disparity_plots import as_result, picture_window

    result = None if result is None else as_result(result)
    window_us = picture_window(result, window_us) if result is not None else int(window_us or DEFAULT_WINDOW_US)
    starts = window_grid(recording, window_us)
    if seconds is not None:
        starts = starts[starts < starts[0] + seconds * 1e6]
    cams = [] if result is None else anchor_cameras(result)
    anchor = None if result is None else anchor_of(result)[0]
    if result is not None:
        vmin, vmax = whole_range(recording, result, vmin, vmax)
    if depth is not None and intrinsics is None:
        from cvstereo.geometry.pointcloud import Intrinsics

        intrinsics = Intrinsics.from_options(recording.resolution, rig=recording.meta.get("rig"))
    for t0 in starts.tolist():
        events = tuple(recording.events(c)[time_slice(recording.events(c), t0, t0 + window_us)] for c in (0, 1))
        m = None if result is None else result.matches[match_window_slice(result.matches, t0, t0 + window_us,
                                                                          anchor=anchor)]
        log_step(stream, (t0 - recording.origin_us) / 1e6, events, m, cameras=cams, resolution=recording.resolution,
                 depth=depth, intrinsics=intrinsics, cmap=cmap, vmin=vmin, vmax=vmax)
    return int(starts.size)


def log_step(stream, t_s: float, events: tuple[np.ndarray, np.ndarray], matches: np.ndarray | None = None, *,
             cameras=(), resolution: tuple[int, int], depth=None, intrinsics=None, cmap: str = DISPARITY_CMAP,
             vmin: float = 0.0, vmax: float = 1.0) -> None:
    """Log one step of the timeline, at ``t_s`` s: the one logging of a window (:func:`log_windows`) and of a
    live packet (:class:`LiveLog`), so that both show the same entities the same way.

    Parameters
    ----------
    stream : rerun.RecordingStream
    t_s : float
        The step's time on the :data:`TIMELINE`, s.
    events : (left, right) event arrays
    matches : matches array, optional
        Without it only the events are logged.
    cameras : iterable of int, keyword-only
        The anchor cameras whose disparity (and depth) images are logged.
    resolution : (width, height), keyword-only
    depth, intrinsics : keyword-only
        The depth images need ``depth``, the 3D points ``depth`` and ``intrinsics``.
    cmap, vmin, vmax : keyword-only
        The disparity colours, fixed for the whole run.
    """
    import rerun as rr

    stream.set_time(TIMELINE, duration=t_s)
    for c, ev in enumerate(events):
        colours = np.where((ev["p"] == 1)[:, None], np.array(ON_RGB, np.uint8), np.array(OFF_RGB, np.uint8))
        stream.log(f"cameras/{CAMERA_NAMES[c]}/events",
                   rr.Points2D(np.column_stack([ev["x"], ev["y"]]).astype(np.float32), colors=colours))
    if matches is None:
        return
    for c in cameras:
        img = disparity_image(matches, c, resolution=resolution)
        stream.log(f"cameras/{CAMERA_NAMES[c]}/disparity", rr.Image(colorize(img, vmin, vmax, cmap=cmap)))
        if depth is not None:
            metres = np.asarray(depth.distance(img), np.float64)
            # 0 is rerun's "no depth": pixels without a disparity, and disparities at or beyond infinity.
            stream.log(f"cameras/{CAMERA_NAMES[c]}/depth",
                       rr.DepthImage(np.where(np.isfinite(metres), metres, 0.0).astype(np.float32), meter=1.0))
    if depth is not None and intrinsics is not None:
        _log_points(stream, matches, depth, intrinsics, cmap, vmin, vmax)


class LiveLog:
    """``cvstereo live --rerun``: each packet of the live loop logged as it is matched (:func:`log_step`), at the
    packet's end on the rig's clock (every event of it happened before), in s.

    The colour range is the matcher's disparity range (``min_disparity`` or 0 to ``max_disparity``, else the
    sensor's width): a live run has no whole run to take it from, and a colour must mean the same disparity
    throughout. Call it with each packet and its matches (:func:`cvstereo.sensors.live.run_live`'s
    ``on_packet``); :attr:`packets` counts the steps logged. A packet that ends where the last one did holds no
    event (the rig's clock did not move); without matches it is not logged, since at the same time it would
    replace the last packet's pictures with empty ones.
    """

    def __init__(self, stream, matcher, *, depth=None, intrinsics=None, cmap: str = DISPARITY_CMAP):
        self.stream, self.depth, self.intrinsics, self.cmap = stream, depth, intrinsics, cmap
        self.cameras = tuple(matcher.anchor_cameras())
        self.resolution = tuple(matcher.resolution)
        prm = matcher.params
        self.vmin = float(getattr(prm, "min_disparity", 0))
        self.vmax = float(getattr(prm, "max_disparity", self.resolution[0] - 1))
        self.packets = 0
        self._last_until: int | None = None

    def __call__(self, packet, matches: np.ndarray) -> None:
        if packet.until == self._last_until and not matches.size:
            return
        self._last_until = packet.until
        log_step(self.stream, packet.until / 1e6, (packet.left, packet.right), matches, cameras=self.cameras,
                 resolution=self.resolution, depth=self.depth, intrinsics=self.intrinsics, cmap=self.cmap,
                 vmin=self.vmin, vmax=self.vmax)
        self.packets += 1


def _log_points(stream, matches: np.ndarray, depth, intrinsics, cmap: str, vmin: float, vmax: float) -> None:
    import rerun as rr

    from cvstereo.geometry.pointcloud import point_cloud

    points = point_cloud(matches, depth, intrinsics)
    lut = disparity_lut(cmap)
    level = np.clip((points["disparity"] - vmin) / (vmax - vmin), 0.0, 1.0)
    colours = lut[np.round(level * (lut.shape[0] - 1)).astype(np.intp)]
    xyz = np.column_stack([points["x"], points["y"], points["z"]]).astype(np.float32)
    stream.log("world/points", rr.Points3D(xyz, colors=colours))


def entity_paths(path: str | os.PathLike) -> set[str]:
    """The entity paths an ``.rrd`` file holds, read by rerun's own loader (its ``rerun.chunk.RrdReader``)."""
    require_extra("rerun", "rerun")
    from rerun.chunk import RrdReader

    schema = RrdReader(os.fspath(path)).store().schema()
    return {c.entity_path for c in schema.component_columns()}
