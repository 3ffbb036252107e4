"""iniVation's dv-processing ``SemiDenseStereoMatcher`` on the same windows, for comparison (extra ``compare``).

dv-processing accumulates each camera's events of a window into an edge map (its ``EdgeMapAccumulator``)
and runs OpenCV's SGBM on the pair (minimum disparity 0, 48 disparities, block size 11, its defaults).
We feed it the same 40 ms windows on the absolute clock as the thesis' frame matchers, with no stereo
geometry (our rigs are uncalibrated, so nothing is rectified), and sample its disparity map at the left
camera's pixels that saw events, exactly as the OpenCV baselines report.

Disparity range. dv-processing's 48 disparities are the range of a 128 px wide sensor; a wider one sees the same
scene at disparities larger by ``width / 128`` (up to a quarter of the width in the generalization suite), so the
comparison gets the OpenCV baselines' range rule (:func:`cvstereo.matchers.opencv.matcher.opencv_range`: 0 .. 47 at
128 px, 0 .. 95 at 240, 0 .. 143 at 346, 0 .. 239 at 640). dv-processing's Python API cannot set its matcher's range, so
beyond its own 48 the same edge maps (dv-processing's ``EdgeMapAccumulator``, as its matcher builds them) go to
OpenCV's SGBM configured as dv-processing's (:data:`~cvstereo.matchers.dv.params.DV_SGBM`, with the wider range);
at 48 disparities that configuration gives dv-processing's own disparity on 99.4 % of the pixels (six windows of two
generalization recordings), and the 128 px sensor keeps dv-processing's own matcher (bit for bit the published figures).

Edge maps. dv-processing's Python API takes events one call per event (``EventStore.push_back``), which at large
sensors cost more than the matching itself. :func:`edge_map` builds the same 8-bit image as its
``EdgeMapAccumulator`` with the matcher's defaults (each event adds 64, polarity ignored, saturating at 255, from 0
in every frame) from the window's polarity counts (the OpenCV baselines' own), and the pair goes to dv-processing's
own ``compute`` of images (or to the wider SGBM): the same disparity maps, bit for bit (tests compare them with
dv-processing's event path).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from cvstereo.errors import require_extra
from cvstereo.frames.accumulate import polarity_counts
from cvstereo.frames.windows import FrameMatcher, Window
from cvstereo.matchers.dv.params import DV_MAX_DISPARITY, DV_SGBM, DvSemiDenseParams
from cvstereo.matchers.opencv.matcher import DISP_SCALE, matches_at_left_events, opencv_range
from cvstereo.model.matches import empty_matches

__all__ = ["EDGE_STEP", "DvSemiDenseMatcher", "DvSemiDenseParams", "edge_map"]

#: What one event adds to its pixel in dv-processing's ``EdgeMapAccumulator`` with the defaults its stereo matcher
#: uses (contribution 0.25 of 255, rounded); the 8-bit pixel saturates at 255.
EDGE_STEP = 64


def edge_map(counts: np.ndarray) -> np.ndarray:
    """dv-processing's edge map of a window (its ``EdgeMapAccumulator`` with its stereo matcher's defaults).

    Parameters
    ----------
    counts : (2, height, width) int ndarray
        One camera's OFF and ON counts of the window (:func:`cvstereo.frames.accumulate.polarity_counts`; polarity
        is ignored).

    Returns
    -------
    (height, width) uint8 ndarray
        ``min(255, 64 * n)`` at a pixel that saw ``n`` events.
    """
    return np.minimum(counts.sum(axis=0) * EDGE_STEP, 255).astype(np.uint8)


class DvSemiDenseMatcher(FrameMatcher):
    """dv-processing's ``SemiDenseStereoMatcher`` per 40 ms window (method ``dv-semidense``).

    Raises
    ------
    MissingExtraError
        dv-processing is not installed (``pip install 'cvstereo[compare]'``).
    """

    Params = DvSemiDenseParams
    variants: ClassVar[dict[str, dict]] = {"default": {}}
    method = "dv-semidense"
    #: Modules the matcher needs beyond the core (the registry lists it only where they are installed).
    requires: ClassVar[tuple[str, ...]] = ("dv_processing",)

    @classmethod
    def max_disparity_for(cls, default: int, width: int, given: dict) -> int:
        """The OpenCV baselines' range rule (:func:`cvstereo.matchers.opencv.matcher.opencv_range`)."""
        return opencv_range(default, width)

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._dv = require_extra("dv_processing", "compare")
        self._matcher = None
        if self.params.max_disparity == DV_MAX_DISPARITY:
            self._matcher = self._dv.SemiDenseStereoMatcher(self.resolution, self.resolution)
        else:
            import cv2

            self._sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=self.params.max_disparity + 1,
                                               **DV_SGBM)

    def anchor_cameras(self) -> tuple[int, ...]:
        return (0,)

    def match_window(self, window: Window) -> np.ndarray:
        if not (window.left.size and window.right.size):
            return empty_matches()
        # The counts the OpenCV baselines take too: the left camera's also give the anchors.
        counts = [polarity_counts(ev, resolution=self.resolution) for ev in (window.left, window.right)]
        raw = (self._matcher if self._matcher is not None else self._sgbm).compute(*map(edge_map, counts))
        # Like OpenCV's SGBM it marks "no disparity" with (min_disparity - 1) * 16 = -16.
        disp = np.where(raw >= 0, raw.astype(np.float32) / DISP_SCALE, np.float32(np.nan))
        return matches_at_left_events(window.t_end, counts[0], disp)
