"""The parameters of the dv-processing comparison (method ``dv-semidense``): fields and declared constraints.

Why these values is said in :mod:`cvstereo.matchers.dv.matcher`. The comparison runs the same under both
parameter sets (no ``adaptive`` attribute).
"""

from __future__ import annotations

from dataclasses import dataclass

from cvstereo.matchers.constraints import DeclaredParams, param

__all__ = ["DV_MAX_DISPARITY", "DV_SGBM", "DvSemiDenseParams"]

#: dv-processing's own range: 48 disparities (0 .. 47), minimum 0.
DV_MAX_DISPARITY = 47
#: OpenCV SGBM settings that reproduce dv-processing's matcher (block 11, P1 = 8 * 11^2, P2 = 32 * 11^2, uniqueness
#: 15, speckle window 200 and range 1, three-way mode), found by comparing disparity maps
#: (:mod:`cvstereo.matchers.dv.matcher`).
DV_SGBM = {"blockSize": 11, "P1": 8 * 11 * 11, "P2": 32 * 11 * 11, "uniquenessRatio": 15,
           "speckleWindowSize": 200, "speckleRange": 1, "mode": 2}


@dataclass(frozen=True)
class DvSemiDenseParams(metaclass=DeclaredParams):
    """Parameters of the dv-processing comparison.

    Attributes
    ----------
    window_us : int
        Window length, us (40 ms as the thesis' frame matchers).
    max_disparity : int
        Largest disparity searched, px (0 .. max_disparity): dv-processing's 47 on a 128 px wide sensor, scaled
        with the width by the OpenCV baselines' rule (:mod:`cvstereo.matchers.dv.matcher`); ``max_disparity + 1``
        must be a multiple of 16 (OpenCV's rule).
    """

    window_us: int = param(40_000, gt=0, note="the thesis uses 40000")
    max_disparity: int = param(DV_MAX_DISPARITY, ge=15, note="max_disparity + 1 a multiple of 16, e.g. 47")

    def check_rules(self):
        """OpenCV's rule, which a bound cannot say: ``max_disparity + 1`` disparities, a multiple of 16."""
        if (self.max_disparity + 1) % 16:
            raise ValueError(f"DvSemiDenseParams: max_disparity + 1 must be a positive multiple of 16 (OpenCV's "
                             f"rule; e.g. 47, dv-processing's own range), got max_disparity {self.max_disparity}.")
