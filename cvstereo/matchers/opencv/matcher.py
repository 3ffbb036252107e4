"""OpenCV's StereoBM and StereoSGBM on the same 40 ms frames as the thesis' frame matchers.

So that a user can compare the calibration-free matchers with OpenCV on equal terms, the baselines see the same
windows (``[k*W, (k+1)*W)`` on the absolute clock), the same signed, Gaussian-filtered frames, and report in the
same matches format: at the left camera's pixels that saw events in the window and got a valid disparity,
stamped with the window's end.

Image mapping. OpenCV's block matchers take 8-bit images, so each filtered frame ``F`` (sum of event signs,
Gaussian, as in thesis 3.3) becomes ``clip(128 + gain * F, 0, 255)``: mid-grey where nothing happened, brighter for
ON activity, darker for OFF activity (gain 32: a filtered value of +-4, about 8 events of one sign on a spot,
saturates). With ``image="count"`` it is ``clip(gain * (ON + OFF count), 0, 255)`` instead, blind to polarity.

OpenCV computes disparities on the left image (its convention: ``x_right = x_left - d``), which is also ours
(``d = x_left - x_right``). It searches ``min_disparity .. max_disparity`` (OpenCV's numDisparities is the count
of them, a multiple of 16: the default 0 .. 63 is 64). Its left strip of that many columns has no result, because
the search would leave the right image; with ``pad=True`` (default) both images get that many mid-grey columns on
the left, so the whole sensor gets results. OpenCV returns fixed-point disparities (``int16``, 4 fractional bits);
the ``/16`` is applied here and nowhere else.
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar

import cv2
import numpy as np

from cvstereo.frames.accumulate import event_mask, gaussian_filter, polarity_counts, polarity_frames
from cvstereo.frames.windows import FrameMatcher, Window
from cvstereo.matchers.opencv.params import StereoBMParams, StereoSGBMParams
from cvstereo.model.matches import empty_matches, make_matches
from cvstereo.model.polarity import OFF, ON

__all__ = ["DISP_SCALE", "MID_GREY", "StereoBMMatcher", "StereoBMParams", "StereoSGBMMatcher", "StereoSGBMParams",
           "matches_at_left_events", "opencv_range"]

#: OpenCV's fixed-point disparity scale (4 fractional bits).
DISP_SCALE = 16
#: Grey value of "no events" in the ``filtered`` image mapping.
MID_GREY = 128


def opencv_range(default: int, width: int, low: int = 0) -> int:
    """The largest disparity an OpenCV block matcher searches on a sensor ``width`` px wide, given its range
    ``low .. default`` on a 128 px wide one: the count ``default - low + 1`` scaled by ``width / 128`` and rounded up
    to a multiple of 16 (OpenCV's rule for numDisparities). The one range rule of every matcher built on OpenCV's
    block matchers (the baselines here and dv-processing's, :mod:`cvstereo.matchers.dv.matcher`), so that they search
    the same disparities on every sensor.

    Examples
    --------
    >>> opencv_range(63, 128), opencv_range(63, 346), opencv_range(47, 128), opencv_range(47, 640)
    (63, 175, 47, 239)
    """
    count = 16 * math.ceil((default - low + 1) * width / 128 / 16)
    return low + count - 1


class _OpenCVMatcher(FrameMatcher):
    """Common part of the baselines: frames -> 8-bit images -> OpenCV -> matches at left event pixels.

    Parameters
    ----------
    params : the subclass's ``Params`` (StereoBMParams, StereoSGBMParams), optional
    resolution : (width, height), keyword-only
    """

    variants: ClassVar[dict[str, dict]] = {"default": {}}

    @classmethod
    def max_disparity_for(cls, default: int, width: int, given: dict) -> int:
        """The scaled range, rounded up so that OpenCV's disparity count stays a multiple of 16
        (:func:`opencv_range`)."""
        low = int(given.get("min_disparity", cls.Params.__dataclass_fields__["min_disparity"].default))
        return opencv_range(default, width, low)

    def __init__(self, params=None, *, resolution=(128, 128)):
        super().__init__(params, resolution=resolution)
        # OpenCV refuses (with a C++ traceback) a block that does not fit in the image.
        if self.params.block_size >= min(self.resolution):
            raise ValueError(f"{type(self.params).__name__}: block_size {self.params.block_size} does not fit a "
                             f"{self.resolution[0]}x{self.resolution[1]} sensor; give an odd number below "
                             f"{min(self.resolution)} (e.g. 9).")
        self._stereo = self._create()

    def anchor_cameras(self) -> tuple[int, ...]:
        return (0,)

    @abc.abstractmethod
    def _create(self):
        """The configured OpenCV matcher object."""

    def image(self, counts: np.ndarray) -> np.ndarray:
        """The 8-bit image OpenCV sees for one camera's window (see the module docstring).

        Parameters
        ----------
        counts : (2, height, width) int ndarray
            OFF and ON counts (:func:`cvstereo.frames.accumulate.polarity_counts`).

        Returns
        -------
        (height, width) uint8 ndarray
        """
        prm = self.params
        if prm.image == "count":
            frame, offset = (counts[ON] + counts[OFF]).astype(np.float32), 0.0
        else:
            ((_, frame),) = polarity_frames(counts, polarity="shared")
            offset = MID_GREY
        if prm.gaussian:
            frame = gaussian_filter(frame, sigma=prm.kernel_sigma, kernel_size=prm.kernel_size)
        return np.clip(np.rint(offset + prm.gain * frame), 0, 255).astype(np.uint8)

    def disparity_map(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """Run OpenCV on a pair of 8-bit images.

        Parameters
        ----------
        left, right : (height, width) uint8 ndarray

        Returns
        -------
        (height, width) float32 ndarray
            Disparity ``x_left - x_right`` at the left image's pixels, px; NaN where OpenCV found none.
        """
        prm = self.params
        pad = prm.num_disparities if prm.pad else 0
        fill = MID_GREY if prm.image == "filtered" else 0
        if pad:
            left, right = (cv2.copyMakeBorder(im, 0, 0, pad, 0, cv2.BORDER_CONSTANT, value=fill)
                           for im in (left, right))
        raw = self._stereo.compute(left, right)[:, pad:]
        # OpenCV marks "no disparity" with (min_disparity - 1) * 16; everything at or above min_disparity is valid.
        valid = raw >= prm.min_disparity * DISP_SCALE
        return np.where(valid, raw.astype(np.float32) / DISP_SCALE, np.float32(np.nan))

    def match_window(self, window: Window) -> np.ndarray:
        if not (window.left.size and window.right.size):
            return empty_matches()
        counts = [polarity_counts(ev, resolution=self.resolution) for ev in (window.left, window.right)]
        disp = self.disparity_map(self.image(counts[0]), self.image(counts[1]))
        return matches_at_left_events(window.t_end, counts[0], disp)


def matches_at_left_events(t_end: int, left_counts: np.ndarray, disparity: np.ndarray) -> np.ndarray:
    """Sample a dense disparity map at the left camera's pixels that saw events (docs/formats.md's window anchors).

    Parameters
    ----------
    t_end : int
        The window's end time, us: the stamp of every match.
    left_counts : (2, height, width) int ndarray
        OFF and ON counts of the left camera in the window (:func:`cvstereo.frames.accumulate.polarity_counts`).
    disparity : (height, width) float ndarray
        Disparity at the left image's pixels; NaN where there is none.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
    """
    y, x = np.nonzero(event_mask(left_counts) & ~np.isnan(disparity))
    # Polarity of a pixel: the sign of its sum of event signs (ties count as ON).
    pol = (left_counts[ON, y, x] >= left_counts[OFF, y, x]).astype(np.int8)
    return make_matches(t_end, x, y, pol, 0, disparity[y, x])


class StereoBMMatcher(_OpenCVMatcher):
    """OpenCV ``StereoBM`` on the thesis' 40 ms frames (method ``stereobm``): its arguments are
    those of the common base, ``_OpenCVMatcher``."""

    Params = StereoBMParams
    method = "stereobm"

    def _create(self):
        prm = self.params
        bm = cv2.StereoBM_create(numDisparities=prm.num_disparities, blockSize=prm.block_size)
        bm.setMinDisparity(prm.min_disparity)
        bm.setUniquenessRatio(prm.uniqueness_ratio)
        bm.setTextureThreshold(prm.texture_threshold)
        bm.setPreFilterCap(prm.prefilter_cap)
        bm.setSpeckleWindowSize(prm.speckle_window_size)
        bm.setSpeckleRange(prm.speckle_range)
        return bm


#: OpenCV's usual smoothness penalties as multiples of the block's area: what ``p1 = 0`` and ``p2 = 0`` choose.
SGBM_PENALTY_FACTORS = {"p1": 8, "p2": 32}

_SGBM_MODES = {"sgbm": cv2.STEREO_SGBM_MODE_SGBM, "hh": cv2.STEREO_SGBM_MODE_HH,
               "3way": cv2.STEREO_SGBM_MODE_SGBM_3WAY}


class StereoSGBMMatcher(_OpenCVMatcher):
    """OpenCV ``StereoSGBM`` on the thesis' 40 ms frames (method ``sgbm``): its arguments are
    those of the common base, ``_OpenCVMatcher``."""

    Params = StereoSGBMParams
    method = "sgbm"

    @staticmethod
    def automatic_values(params: StereoSGBMParams) -> dict[str, str]:
        """What the parameters whose 0 means "automatic" take for ``params`` (``p1``, ``p2``), as
        `cvstereo match --list-methods` names them: OpenCV's usual penalties for the block size."""
        area = params.block_size * params.block_size
        return {k: f"{f} * block_size**2 = {f * area} at block_size {params.block_size}"
                for k, f in SGBM_PENALTY_FACTORS.items()}

    def _create(self):
        prm = self.params
        area = prm.block_size * prm.block_size
        penalty = {k: getattr(prm, k) or f * area for k, f in SGBM_PENALTY_FACTORS.items()}
        return cv2.StereoSGBM_create(
            minDisparity=prm.min_disparity, numDisparities=prm.num_disparities, blockSize=prm.block_size,
            P1=penalty["p1"], P2=penalty["p2"], disp12MaxDiff=prm.disp12_max_diff,
            uniquenessRatio=prm.uniqueness_ratio, speckleWindowSize=prm.speckle_window_size,
            speckleRange=prm.speckle_range, mode=_SGBM_MODES[prm.mode],
        )
