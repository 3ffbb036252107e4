"""The geometry steps around a match: what a match result gets from the geometry it was matched with.

A recording is matched with a geometry (:mod:`cvstereo.geometry.source`) in steps that are each one library
call; ``cvstereo match`` only wires them together, so that the recording is streamed from its file:

1. resolve the geometry: ``geometry = GeometryOptions(...).resolve(stream.meta, stream.resolution,
   recording=stream.read)`` (the precedence rule; ``stream.read`` is called only for a rig check, which looks
   at the whole recording);
2. match: ``result = match(geometry.prepare(stream), rig_check=geometry.rig_check_wanted,
   **geometry.match_kwargs())`` (the cameras exchanged, rows and times corrected or rectified, packet by packet:
   :func:`cvstereo.run.match`; its own rig check on the stream's prefix only where no source gave side, rows
   or time);
3. :func:`record_geometry`: the geometry and its sources in the meta, the distance of every match beside it;
4. :func:`point_cloud_of`: the matches as 3D points.

>>> from cvstereo.geometry.depth import DepthModel
>>> from cvstereo.geometry.source import GeometryOptions
>>> from cvstereo.model.matches import MatchResult, make_matches
>>> geometry = GeometryOptions(depth=DepthModel(a=20.0)).resolve({}, (128, 128))
>>> result = MatchResult(make_matches([1000, 2000], [40, 41], [5, 5], [1, 1], [0, 0], [5.0, 4.0]))
>>> record_geometry(result, geometry).meta["geometry"]["depth"]
{'source': 'options', 'a': 20.0, 'c': 0.0}
>>> result.arrays["depth_m"].tolist()  # Z = a / d
[4.0, 5.0]
"""

from __future__ import annotations

import numpy as np

from cvstereo.geometry.pointcloud import depth_per_match, point_cloud
from cvstereo.geometry.source import Geometry
from cvstereo.model.matches import MatchResult

__all__ = ["depth_of", "point_cloud_of", "record_geometry"]


def depth_of(result: MatchResult, geometry: Geometry) -> np.ndarray | None:
    """The distance of every match, metres, by the geometry's depth model (None without one).

    Returns
    -------
    (N,) float32 ndarray or None
        In the order of ``result.matches``; inf where the disparity is at or beyond infinity
        (:func:`~cvstereo.geometry.pointcloud.depth_per_match`).
    """
    return None if geometry.depth is None else depth_per_match(result.matches, geometry.depth)


def record_geometry(result: MatchResult, geometry: Geometry) -> MatchResult:
    """Store in ``result`` what its matches were computed with; return it.

    ``result`` is what :func:`cvstereo.run.match` returned for ``geometry.prepare(recording)``. The meta gets
    ``geometry`` (:meth:`Geometry.describe <cvstereo.geometry.source.Geometry.describe>`: each part and its
    source; with what the match's own prefix check applied, :meth:`Geometry.matched
    <cvstereo.geometry.source.Geometry.matched>`), ``rigcheck`` (the report and what of it was applied) when a
    rig check ran, and ``depth`` (the
    model) with the per-match array ``depth_m`` when there is a depth model: the match dtype is a contract of
    docs/formats.md, so distances go beside it. Where the cameras were exchanged, ``meta["fingerprint"]`` is
    turned back into that of the files as read, so that the matches are recognised against the recording as
    it is read again (:func:`cvstereo.evaluation.metrics.check_same_recording`).
    """
    from cvstereo.model.fingerprint import swap_cameras

    meta = result.meta
    geometry = geometry.matched(meta)  # with what the match's own rig check applied, where it ran
    meta["geometry"] = geometry.describe()
    if geometry.rigcheck is not None:
        meta["rigcheck"] = geometry.rigcheck
    if geometry.swap and not geometry.in_match:  # the match saw the swapped stream; its own swap came after the count
        meta["fingerprint"] = swap_cameras(meta["fingerprint"])
    if geometry.depth is not None:
        meta["depth"] = geometry.depth.to_dict()
        result.arrays["depth_m"] = depth_of(result, geometry)
    return result


def point_cloud_of(result: MatchResult, geometry: Geometry) -> np.ndarray:
    """The matches with a finite distance as 3D points in the left camera's frame
    (:func:`~cvstereo.geometry.pointcloud.point_cloud`), by the geometry's depth model and intrinsics.

    Raises
    ------
    ValueError
        The geometry has no depth model, or no intrinsics (it was resolved without ``point_cloud=True``).
    """
    if geometry.depth is None:
        raise ValueError("a point cloud needs a depth model: give a calibration, a depth model (--depth A C) or a "
                         "recording whose meta describes its rig.")
    if geometry.intrinsics is None:
        raise ValueError("a point cloud needs the intrinsics: resolve the geometry with "
                         "GeometryOptions(point_cloud=True).")
    return point_cloud(result.matches, geometry.depth, geometry.intrinsics)
