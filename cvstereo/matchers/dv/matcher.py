"""iniVation's dv-processing ``SemiDenseStereoMatcher`` on the same windows, for comparison (extra ``compare``).

dv-processing accumulates each camera's events of a window into an edge map (its ``EdgeMapAccumulator``)
and runs OpenCV's SGBM on the pair (minimum disparity 0, 48 disparities, block size 11, its defaults).
We feed it the same 40 ms windows on the absolute clock as the thesis' frame matchers, with no stereo
geometry (our rigs are uncalibrated, so nothing is rectified), and sample its disparity map at the left
camera's pixels that saw events, exactly as the OpenCV baselines report.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cvstereo.errors import require_extra
from cvstereo.frames.accumulate import polarity_counts
from cvstereo.frames.windows import FrameMatcher, Window, check_window_us
from cvstereo.matchers.opencv.matcher import DISP_SCALE, matches_at_left_events
from cvstereo.model.matches import empty_matches

__all__ = ["DvSemiDenseMatcher", "DvSemiDenseParams"]


@dataclass(frozen=True)
class DvSemiDenseParams:
    """Parameters of the dv-processing comparison.

    Attributes
    ----------
    window_us : int
        Window length, us (40 ms as the thesis' frame matchers).
    """

    window_us: int = 40_000

    def __post_init__(self):
        check_window_us(self.window_us, "DvSemiDenseParams")


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

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        self._dv = require_extra("dv_processing", "compare")
        self._matcher = self._dv.SemiDenseStereoMatcher(self.resolution, self.resolution)

    def anchor_cameras(self) -> tuple[int, ...]:
        return (0,)

    def _store(self, events: np.ndarray):
        store = self._dv.EventStore()
        # dv-processing has no bulk constructor from numpy in its Python API; one call per event.
        for t, x, y, p in zip(events["t"].tolist(), events["x"].tolist(), events["y"].tolist(),
                              events["p"].tolist(), strict=True):
            store.push_back(t, x, y, bool(p))
        return store

    def match_window(self, window: Window) -> np.ndarray:
        if not (window.left.size and window.right.size):
            return empty_matches()
        raw = self._matcher.computeDisparity(self._store(window.left), self._store(window.right))
        # Like OpenCV's SGBM it marks "no disparity" with (min_disparity - 1) * 16 = -16.
        disp = np.where(raw >= 0, raw.astype(np.float32) / DISP_SCALE, np.float32(np.nan))
        return matches_at_left_events(window.t_end, polarity_counts(window.left, resolution=self.resolution), disp)
