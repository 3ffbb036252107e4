"""The thesis rig, defined once: :data:`THESIS_RIG` (two eDVS128 10 cm apart, its focal length and axis offset).

The simulator's default rig (:class:`cvstereo.simulate.rig.Rig`), the point cloud's default intrinsics
(:meth:`cvstereo.geometry.pointcloud.Intrinsics.from_options`) and the samples' depth model all read it.

Where the numbers come from (docs/algorithms.md): the thesis states the sensors (two eDVS128, 128 x 128) and the
baseline (10 cm, parallel axes), but no focal length. That comes from the disparities it measured, 28-30, 13-14
and 7-8 px at 50, 100 and 150 cm: a least-squares fit of ``d = f*B/Z - c`` to its means gives f*B = 16.1 px*m and
c = 2.9 px; the simulator's slight barrel distortion lowers the disparity off-centre by about 2 %, so the rig that
reproduces them through it has f = 165 px and c = 3 px. The rounder "about 160 px" (with c = 2.5) that some
samples used is that fit without the distortion; one rig, the simulator's, is now the thesis rig everywhere, so
that a depth computed from simulated matches uses the geometry that made them.

>>> THESIS_RIG.depth_model().disparity([0.5, 1.0, 1.5]).round(1).tolist()
[30.0, 13.5, 8.0]
"""

from __future__ import annotations

from dataclasses import dataclass

from cvstereo.geometry.depth import DepthModel
from cvstereo.model.events import DEFAULT_RESOLUTION

__all__ = ["THESIS_RIG", "StereoRig"]


@dataclass(frozen=True)
class StereoRig:
    """A stereo pair's nominal geometry: what depth and point clouds need when no calibration is given.

    Attributes
    ----------
    sensor : str
        The sensors' name (both cameras).
    resolution : (width, height)
        Pixels of each sensor.
    baseline_m : float
        Distance B between the optical centres, m.
    focal_px : float
        Focal length f, px (both cameras).
    axis_offset_px : float
        The offset c of ``d = f*B/Z - c``, px, from optical axes that are not exactly parallel.
    """

    sensor: str
    resolution: tuple[int, int]
    baseline_m: float
    focal_px: float
    axis_offset_px: float

    def depth_model(self) -> DepthModel:
        """The rig's disparity-to-distance model, ``d = f*B/Z - c``."""
        return DepthModel.from_rig(focal_px=self.focal_px, baseline_m=self.baseline_m, offset_px=self.axis_offset_px)


#: The thesis rig (module docstring: the sources of each number).
THESIS_RIG = StereoRig(sensor="eDVS128", resolution=DEFAULT_RESOLUTION, baseline_m=0.10, focal_px=165.0,
                       axis_offset_px=3.0)
