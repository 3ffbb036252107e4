"""Rectify events with a calibration, per event, as a stage between the packet source and any matcher.

With a :class:`~cvstereo.geometry.calibration.StereoCalibration`, :class:`Rectification` computes once, per camera,
where
every raw pixel lands in the rectified view (``cv2.undistortPoints`` with the rectifying rotation and camera
matrix, rounded to whole pixels: a lookup table), and where every rectified pixel comes from
(``cv2.initUndistortRectifyMap``, for window-anchored matches). Then:

- events keep their time and polarity and move to their rectified pixel; events that land outside the sensor
  are dropped and counted (:attr:`RectifiedStream.dropped`); packets stay time slices (no time changes);
- matches are mapped back to the recording's own pixels (:meth:`RectifiedStream.restore`): event-anchored
  matches to the very event they were anchored on (the stream remembers which raw event became which rectified
  one, until no later match can refer to it), window-anchored matches through the inverse map.

Ground truth, where a packet has it, is passed along for the kept events unchanged (it is the raw geometry's).
Without a calibration nothing of this runs: cvstereo needs none.

>>> from cvstereo.geometry.calibration import StereoCalibration
>>> K = [[100, 0, 63.5], [0, 100, 63.5], [0, 0, 1]]
>>> cal = StereoCalibration.from_opencv(K, None, K, None, np.eye(3), [-0.1, 0, 0], (128, 128))
>>> Rectification(cal).lut[0][40, 10].tolist()   # an aligned rig: every pixel stays where it is
[10, 40]
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import cv2
import numpy as np

from cvstereo.geometry.calibration import CameraCalibration, StereoCalibration
from cvstereo.model.events import StereoPacket
from cvstereo.model.matches import MATCH_DTYPE

__all__ = ["NONE", "Rectification", "RectifiedStream"]

#: Marks a pixel without a partner in the lookup tables.
NONE = -1


def _forward(cam: CameraCalibration, resolution: tuple[int, int]) -> np.ndarray:
    """(H, W, 2) int16: the rectified (x, y) of each raw pixel centre, NONE outside the rectified sensor."""
    w, h = resolution
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    if cam.model == "equidistant":
        rect = cv2.fisheye.undistortPoints(pts, cam.K, cam.D, R=cam.R_rect, P=cam.P_rect)
    else:
        # More iterations than undistortPoints' default 5: strong lenses (DSEC's) need them at the corners.
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
        rect = cv2.undistortPoints(pts, cam.K, cam.D, R=cam.R_rect, P=cam.P_rect, criteria=criteria)
    xy = np.rint(rect.reshape(h, w, 2))
    inside = np.isfinite(xy).all(axis=2) & (xy[..., 0] >= 0) & (xy[..., 0] < w) & (xy[..., 1] >= 0) & (xy[..., 1] < h)
    out = np.full((h, w, 2), NONE, np.int16)
    out[inside] = xy[inside].astype(np.int16)
    return out


def _inverse(cam: CameraCalibration, resolution: tuple[int, int]) -> np.ndarray:
    """(H, W, 2) int16: the raw (x, y) each rectified pixel samples, NONE where it falls off the raw sensor."""
    w, h = resolution
    init = cv2.fisheye.initUndistortRectifyMap if cam.model == "equidistant" else cv2.initUndistortRectifyMap
    mx, my = init(cam.K, cam.D, cam.R_rect, cam.P_rect, (w, h), cv2.CV_32FC1)
    xy = np.rint(np.stack([mx, my], axis=2).astype(np.float64))
    inside = (xy[..., 0] >= 0) & (xy[..., 0] < w) & (xy[..., 1] >= 0) & (xy[..., 1] < h)
    out = np.full((h, w, 2), NONE, np.int16)
    out[inside] = xy[inside].astype(np.int16)
    return out


class Rectification:
    """Per-pixel lookup tables of a calibrated pair, and the stage built on them.

    Parameters
    ----------
    calibration : StereoCalibration

    Attributes
    ----------
    lut : tuple of two (H, W, 2) int16 ndarrays
        Left, right: rectified ``(x, y)`` of every raw pixel, :data:`NONE` where it leaves the sensor.
    inverse : tuple of two (H, W, 2) int16 ndarrays
        Left, right: raw ``(x, y)`` of every rectified pixel, :data:`NONE` where there is none.
    """

    def __init__(self, calibration: StereoCalibration):
        self.calibration = calibration
        self.resolution = calibration.resolution
        cams = (calibration.left, calibration.right)
        self.lut = tuple(_forward(c, self.resolution) for c in cams)
        self.inverse = tuple(_inverse(c, self.resolution) for c in cams)
        self._description = None

    @classmethod
    def from_tables(cls, lut, inverse, resolution: tuple[int, int], description: dict) -> Rectification:
        """A stage from lookup tables made elsewhere (a row field: :mod:`cvstereo.rigcheck.row_field`).

        Parameters
        ----------
        lut, inverse : pairs of (H, W, 2) int16 ndarrays or None
            As the attributes below; None for a camera whose pixels stay where they are (its events pass as
            they are, and its matches need no mapping back).
        resolution : (width, height)
        description : dict
            What :meth:`describe` returns.
        """
        self = cls.__new__(cls)
        self.calibration, self.resolution, self._description = None, tuple(resolution), dict(description)
        self.lut, self.inverse = tuple(lut), tuple(inverse)
        return self

    def moves(self, camera: int) -> bool:
        """False where the camera's pixels stay where they are."""
        return self.lut[camera] is not None

    def rectify(self, events: np.ndarray, camera: int) -> tuple[np.ndarray, np.ndarray]:
        """Move one camera's events to their rectified pixels; return ``(rectified, kept)``.

        Parameters
        ----------
        events : (N,) ndarray of EVENT_DTYPE
            Raw events of camera 0 (left) or 1 (right), inside the sensor.
        camera : {0, 1}

        Returns
        -------
        rectified : (M,) ndarray of EVENT_DTYPE
            The kept events at their rectified pixels, same t and p, same order.
        kept : (N,) bool ndarray
            False for events whose pixel leaves the rectified sensor.
        """
        if not self.moves(camera):
            return events, np.ones(events.size, bool)
        xy = self.lut[camera][events["y"].astype(np.intp), events["x"].astype(np.intp)]
        kept = xy[:, 0] != NONE
        out = events[kept].copy()
        out["x"], out["y"] = xy[kept, 0], xy[kept, 1]
        return out, kept

    def stream(self, packets: Iterable[StereoPacket]) -> RectifiedStream:
        """Wrap a packet source (see :class:`RectifiedStream`)."""
        return RectifiedStream(self, packets)

    def unrectify_pixels(self, x: np.ndarray, y: np.ndarray, camera: int) -> tuple[np.ndarray, np.ndarray]:
        """Raw pixels of rectified pixels (through the inverse map; clipped to the sensor where it has none)."""
        if not self.moves(camera):
            return np.asarray(x).astype(np.int16), np.asarray(y).astype(np.int16)
        xy = self.inverse[camera][np.asarray(y, np.intp), np.asarray(x, np.intp)]
        none = xy[:, 0] == NONE
        rx, ry = xy[:, 0].astype(np.int16), xy[:, 1].astype(np.int16)
        if none.any():
            w, h = self.resolution
            rx[none] = np.clip(np.asarray(x)[none], 0, w - 1)
            ry[none] = np.clip(np.asarray(y)[none], 0, h - 1)
        return rx, ry

    def describe(self) -> dict:
        """The matches-file meta entry ``rectification`` (a row field's: its own, see :meth:`from_tables`)."""
        return self.calibration.describe() if self._description is None else dict(self._description)


class RectifiedStream(Iterator[StereoPacket]):
    """Rectified packets over a packet source (made by :meth:`Rectification.stream`).

    Attributes
    ----------
    dropped : list of two ints
        Events of the left and right camera dropped so far because their pixel leaves the rectified sensor.
    """

    def __init__(self, rectification: Rectification, packets: Iterable[StereoPacket]):
        self.rectification = rectification
        self._source = iter(packets)
        self.dropped = [0, 0]
        w, h = rectification.resolution
        self._pixel_bits = int(w * h).bit_length()
        # Per camera, the emitted events not yet passed by the matches: rectified key -> raw pixel.
        self._keys: list[list[np.ndarray]] = [[], []]
        self._raw: list[list[np.ndarray]] = [[], []]
        self._t0: int | None = None

    def __iter__(self) -> RectifiedStream:
        return self

    def __next__(self) -> StereoPacket:
        packet = next(self._source)
        out, truth = [], []
        for cam, (events, tr) in enumerate(((packet.left, packet.left_disparity),
                                            (packet.right, packet.right_disparity))):
            rect, kept = self.rectification.rectify(events, cam)
            self.dropped[cam] += int(events.size - rect.size)
            if rect.size and self.rectification.moves(cam):
                if self._t0 is None:
                    self._t0 = int(rect["t"][0])
                self._keys[cam].append(self._key(rect["t"], rect["x"], rect["y"], rect["p"]))
                self._raw[cam].append(np.stack([events["x"][kept], events["y"][kept]], axis=1))
            out.append(rect)
            truth.append(None if tr is None else tr[kept])
        return StereoPacket(out[0], out[1], packet.until, truth[0], truth[1])

    def _key(self, t, x, y, p) -> np.ndarray:
        w = self.rectification.resolution[0]
        pix = (np.asarray(y, np.int64) * w + np.asarray(x, np.int64)) * 2 + np.asarray(p, np.int64)
        return ((np.asarray(t, np.int64) - self._t0) << (self._pixel_bits + 1)) | pix

    def restore(self, matches: np.ndarray, *, anchor: str = "event") -> np.ndarray:
        """Map matches on the rectified grid back to the recording's pixels.

        Parameters
        ----------
        matches : (N,) ndarray of MATCH_DTYPE
            A matcher's output on this stream's packets (time-ordered, not earlier than matches restored before).
        anchor : {"event", "window"}, keyword-only
            ``event``: each match goes to the raw pixel of the event it was anchored on (the inverse map where
            no such event is known); ``window``: through the inverse map.

        Returns
        -------
        (N,) ndarray of MATCH_DTYPE
            Same order, disparities unchanged (they are the rectified pair's).
        """
        if matches.dtype != MATCH_DTYPE:
            raise ValueError(f"restore: dtype {matches.dtype} is not MATCH_DTYPE; pass a matcher's output.")
        out = matches.copy()
        if not out.size:
            return out
        for cam in (0, 1):
            sel = np.flatnonzero(out["camera"] == cam)
            if not sel.size or not self.rectification.moves(cam):
                continue
            m = out[sel]
            rx, ry = self.rectification.unrectify_pixels(m["x"], m["y"], cam)
            if anchor == "event" and self._keys[cam] and self._t0 is not None:
                keys = np.concatenate(self._keys[cam])
                raw = np.concatenate(self._raw[cam])
                order = np.argsort(keys, kind="stable")
                want = self._key(m["t"], m["x"], m["y"], m["p"])
                pos = np.minimum(np.searchsorted(keys[order], want), keys.size - 1)
                found = keys[order][pos] == want
                rx[found], ry[found] = raw[order[pos[found]], 0], raw[order[pos[found]], 1]
            out["x"][sel], out["y"][sel] = rx, ry
        if anchor == "event":
            self._forget_before(int(matches["t"][-1]))
        return out

    def _forget_before(self, t: int) -> None:
        # Later matches are not earlier than t (the matcher contract), so no event before t is referred to again.
        if self._t0 is None:
            return
        cut = (t - self._t0) << (self._pixel_bits + 1)
        for cam in (0, 1):
            if not self._keys[cam]:
                continue
            keys, raw = np.concatenate(self._keys[cam]), np.concatenate(self._raw[cam])
            keep = keys >= cut
            self._keys[cam], self._raw[cam] = [keys[keep]], [raw[keep]]
