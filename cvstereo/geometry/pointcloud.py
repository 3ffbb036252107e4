"""Depth as data: per-match distance in metres, and point clouds written as PLY.

The calibration-free model gives the distance (d = a/Z - c, :class:`~cvstereo.geometry.depth.DepthModel`); the other two
coordinates need the focal length and principal point: ``X = (x_left - cx) * Z / f``, ``Y = (y - cy) * Z / f``
in the left camera's frame (X right, Y down, Z forward, metres). Those come from a calibration when there is one
(the rectified view's, :class:`~cvstereo.geometry.calibration.StereoCalibration`), else from the rig options
(``focal_px``, default the thesis rig's 165 px, and the sensor centre). :class:`Intrinsics` records which, and
the PLY header says it.

>>> from cvstereo.model.matches import make_matches
>>> m = make_matches([0, 5], [70, 60], [64, 60], 1, [0, 1], [10.0, 10.0])
>>> [round(float(z), 3) for z in depth_per_match(m, DepthModel(a=16.5))]
[1.65, 1.65]
>>> pts = point_cloud(m, DepthModel(a=16.5), Intrinsics(165.0, 63.5, 63.5, "test"))
>>> [round(float(v), 3) for v in pts[1][["x", "y", "z"]]]   # right-anchored: x_left = 60 + 10
[0.065, -0.035, 1.65]
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from cvstereo.geometry.depth import DepthModel
from cvstereo.geometry.rig import THESIS_RIG

__all__ = ["POINT_DTYPE", "THESIS_FOCAL_PX", "Intrinsics", "depth_per_match", "point_cloud", "window_point_clouds",
           "write_ply"]

#: The thesis rig's focal length, px: :data:`cvstereo.geometry.rig.THESIS_RIG`'s, under the name 0.3 exported.
THESIS_FOCAL_PX = THESIS_RIG.focal_px

#: The PLY vertex: position (m), the match's disparity (px), time (us) and anchoring camera.
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("disparity", "<f4"), ("t", "<i8"),
                        ("camera", "u1")])


@dataclass(frozen=True)
class Intrinsics:
    """Focal length and principal point of the (rectified) left view, and where they came from.

    Attributes
    ----------
    focal_px, cx, cy : float
    source : str
        E.g. ``"calibration cam_to_cam.yaml"`` or ``"rig options (--focal-px 165, sensor centre)"``.
    """

    focal_px: float
    cx: float
    cy: float
    source: str

    @classmethod
    def from_options(cls, resolution: tuple[int, int], *, focal_px: float | None = None, calibration=None,
                     rig: Mapping | None = None) -> Intrinsics:
        """From a calibration when given, else ``focal_px``, else the recording's rig, else the thesis rig's.

        The order is :mod:`cvstereo.geometry.source`'s: what the user calibrated or said before what the
        recording carries.

        Parameters
        ----------
        resolution : (width, height)
            The principal point defaults to the sensor centre ``((w-1)/2, (h-1)/2)``.
        focal_px : float, optional, keyword-only
            A finite focal length > 0; not together with a calibration (it has its own).
        calibration : StereoCalibration, optional, keyword-only
        rig : mapping, optional, keyword-only
            A recording's ``meta["rig"]`` (the simulator's :meth:`~cvstereo.simulate.rig.Rig.describe`):
            ``focal_px`` and the left camera's principal point, shifted from the centre by half of
            ``axis_offset_px`` and ``vertical_offset_px``; used only when it is for this sensor size.

        Raises
        ------
        ValueError
            ``focal_px`` with a calibration, or not a finite number > 0.
        """
        if calibration is not None:
            if focal_px is not None:
                raise ValueError("give a calibration or --focal-px, not both: the calibration has the focal length.")
            (cx, cy), f = calibration.principal_point, calibration.focal_px
            return cls(f, cx, cy, f"calibration {calibration.source} (rectified left view)")
        w, h = resolution
        if focal_px is not None:
            f = float(focal_px)
            if not (math.isfinite(f) and f > 0):
                raise ValueError(f"--focal-px must be a finite number > 0, got {f:g}.")
            return cls(f, (w - 1) / 2, (h - 1) / 2, f"--focal-px (focal {f:g} px; principal point: sensor centre)")
        if _rig_fits(rig, resolution):
            f = float(rig["focal_px"])
            cx = (w - 1) / 2 - float(rig.get("axis_offset_px", 0.0)) / 2
            cy = (h - 1) / 2 - float(rig.get("vertical_offset_px", 0.0)) / 2
            return cls(f, cx, cy, f"the recording's rig (focal {f:g} px, its left camera's principal point)")
        return cls(THESIS_FOCAL_PX, (w - 1) / 2, (h - 1) / 2,
                   f"rig options (focal {THESIS_FOCAL_PX:g} px: default, the thesis rig's; principal point: sensor "
                   "centre)")


def _rig_fits(rig, resolution) -> bool:
    """Whether a recording's rig description gives a usable focal length for a sensor of ``resolution``."""
    if not isinstance(rig, Mapping):
        return False
    try:
        f = float(rig["focal_px"])
        size = tuple(int(v) for v in rig.get("resolution", resolution))
    except (KeyError, TypeError, ValueError):
        return False
    return math.isfinite(f) and f > 0 and size == tuple(resolution)


def depth_per_match(matches: np.ndarray, model: DepthModel) -> np.ndarray:
    """The distance of every match, metres: the optional per-match array ``depth_m`` of a matches file.

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
    model : DepthModel

    Returns
    -------
    (N,) float32 ndarray
        inf where the disparity is at or beyond infinity (``d + c <= 0``).
    """
    return model.distance(matches["disparity"]).astype(np.float32)


def point_cloud(matches: np.ndarray, model: DepthModel, intrinsics: Intrinsics) -> np.ndarray:
    """3D points of the matches with a finite distance, in the left camera's frame.

    Right-anchored matches are placed at their left-camera column ``x + disparity``.

    Returns
    -------
    (M,) ndarray of POINT_DTYPE
    """
    z = depth_per_match(matches, model).astype(np.float64)
    ok = np.isfinite(z)
    m, z = matches[ok], z[ok]
    x_left = m["x"].astype(np.float64) + np.where(m["camera"] == 1, m["disparity"], 0.0)
    out = np.empty(m.size, POINT_DTYPE)
    out["x"] = (x_left - intrinsics.cx) * z / intrinsics.focal_px
    out["y"] = (m["y"].astype(np.float64) - intrinsics.cy) * z / intrinsics.focal_px
    out["z"] = z
    out["disparity"], out["t"], out["camera"] = m["disparity"], m["t"], m["camera"]
    return out


def window_point_clouds(matches: np.ndarray, model: DepthModel, intrinsics: Intrinsics, *, window_us: int = 40_000,
                        anchor: str = "event") -> Iterator[tuple[int, np.ndarray]]:
    """One point cloud per absolute window ``[k*W, (k+1)*W)`` that holds matches.

    Parameters
    ----------
    matches : (N,) ndarray of MATCH_DTYPE
        Time-ordered.
    model, intrinsics
        As for :func:`point_cloud`.
    window_us : int, keyword-only
    anchor : {"event", "window"}, keyword-only
        The matches file's ``meta["anchor"]`` (window anchors carry their window's end).

    Yields
    ------
    t_start : int
        The window's start, us.
    points : (M,) ndarray of POINT_DTYPE
    """
    from cvstereo.geometry.disparity_maps import match_window_slice

    if window_us <= 0:
        raise ValueError(f"window_us must be positive, got {window_us}.")
    if not matches.size:
        return
    t = matches["t"] - (1 if anchor == "window" else 0)
    for k in np.unique(t // window_us).tolist():
        sl = match_window_slice(matches, k * window_us, (k + 1) * window_us, anchor=anchor)
        yield k * window_us, point_cloud(matches[sl], model, intrinsics)


def write_ply(path: str | os.PathLike, points: np.ndarray, *, model: DepthModel, intrinsics: Intrinsics,
              comments: tuple[str, ...] = ()) -> None:
    """Write points as a binary PLY (plyfile: the ``pointcloud`` extra), atomically.

    The header's comments say the frame and units, the depth model and where the intrinsics came from.

    Parameters
    ----------
    path : path-like
    points : (M,) ndarray of POINT_DTYPE
    model : DepthModel, keyword-only
    intrinsics : Intrinsics, keyword-only
    comments : tuple of str, keyword-only
        More header comments (one line each), e.g. the input file and the window.
    """
    try:
        from plyfile import PlyData, PlyElement
    except ImportError as exc:
        raise ImportError("writing PLY needs plyfile: pip install 'cvstereo[pointcloud]'") from exc
    from cvstereo.io.atomic import atomic_path

    header = ("cvstereo point cloud: left camera frame, X right, Y down, Z forward, metres",
              f"depth model: d = a/Z - c with a = {model.a:.6g} px*m, c = {model.c:.6g} px",
              f"intrinsics: f = {intrinsics.focal_px:.6g} px, principal point ({intrinsics.cx:.6g}, "
              f"{intrinsics.cy:.6g}) from {intrinsics.source}", *comments)
    for line in header:
        if "\n" in line or "\r" in line:
            raise ValueError(f"PLY comments are single lines; got {line!r}.")
    element = PlyElement.describe(np.ascontiguousarray(points, POINT_DTYPE).astype(
        [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("disparity", "<f4"), ("t", "<f8"), ("camera", "u1")]), "vertex")
    with atomic_path(path) as tmp:
        PlyData([element], text=False, byte_order="<", comments=list(header)).write(str(tmp))
