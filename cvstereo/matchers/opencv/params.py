"""The parameters of OpenCV's baselines (methods ``stereobm`` and ``sgbm``): fields, declared constraints and sets.

The image mapping and the disparity range they configure are described in :mod:`cvstereo.matchers.opencv.matcher`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from cvstereo.frames.windows import WindowFrameParams
from cvstereo.matchers._shared.border import BorderParams
from cvstereo.matchers.constraints import param
from cvstereo.matchers.params import Alias
from cvstereo.matchers.sets import ADAPTIVE_BORDER, AdaptiveDefaults

__all__ = ["StereoBMParams", "StereoSGBMParams"]


@dataclass(frozen=True, kw_only=True)
class _OpenCVParams(BorderParams, WindowFrameParams):
    """Parameters common to both baselines (see the module docstring for the image mapping).

    The window and Gaussian fields (window_us, gaussian, kernel_sigma, kernel_size) are those of
    :class:`~cvstereo.frames.windows.WindowFrameParams`, the border rule's (border_horizon_us, border_rows) those of
    :class:`~cvstereo.matchers._shared.border.BorderParams`.

    Attributes
    ----------
    image : {"filtered", "count"}
        Image mapping: signed Gaussian-filtered frame around mid-grey, or event count.
    gain : float
        Grey levels per unit of frame value.
    min_disparity : int
        Smallest disparity searched, px.
    max_disparity : int
        Largest disparity searched, px; ``max_disparity - min_disparity + 1`` must be a positive multiple of 16
        (OpenCV's rule). Old name: ``num_disparities``, the count (``max_disparity = min_disparity + count - 1``).
    block_size : int
        Odd matching block side, px.
    uniqueness_ratio : int
        OpenCV's uniquenessRatio, percent (0 disables the check).
    speckle_window_size, speckle_range : int
        OpenCV's speckle filter (0: off).
    pad : bool
        Pad both images on the left with :attr:`num_disparities` mid-grey columns, so that the left strip gets
        results.
    """

    aliases: ClassVar[dict] = {"num_disparities": Alias("max_disparity",
                                                        lambda n, given: given.get("min_disparity", 0) + int(n) - 1)}

    image: Literal["filtered", "count"] = "filtered"
    gain: float = param(32.0, gt=0, note="e.g. 32")
    min_disparity: int = 0
    max_disparity: int = 63
    block_size: int = param(9, side=True, note="e.g. 9")
    uniqueness_ratio: int = param(10, ge=0, note="0: off")
    speckle_window_size: int = 0
    speckle_range: int = 0
    pad: bool = True

    def check_rules(self):
        """The rule between fields: OpenCV searches a multiple of 16 disparities."""
        if self.num_disparities <= 0 or self.num_disparities % 16:
            raise ValueError(f"{type(self).__name__}: max_disparity - min_disparity + 1 (the number of disparities "
                             f"OpenCV searches) must be a positive multiple of 16 (OpenCV's rule), e.g. max_disparity "
                             f"47 or 63; got {self.num_disparities} (max_disparity {self.max_disparity}, "
                             f"min_disparity {self.min_disparity}).")

    @property
    def num_disparities(self) -> int:
        """OpenCV's numDisparities: how many disparities are searched."""
        return self.max_disparity - self.min_disparity + 1


@dataclass(frozen=True, kw_only=True)
class StereoBMParams(_OpenCVParams):
    """Parameters of :class:`~cvstereo.matchers.opencv.matcher.StereoBMMatcher`: the common ones (see
    ``_OpenCVParams``) and BM's own.

    Attributes
    ----------
    texture_threshold : int
        OpenCV's textureThreshold: blocks with less texture get no result.
    prefilter_cap : int
        OpenCV's preFilterCap (1..63).
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="default",
        why="OpenCV's block matcher as it is, with the border rule: no answer where the nearest answers inward "
            "say the partner lies outside the other image",
        params=ADAPTIVE_BORDER,
    )

    block_size: int = param(9, side=True, ge=5, le=255, note="StereoBM's range")
    texture_threshold: int = 10
    prefilter_cap: int = param(31, ge=1, le=63)


@dataclass(frozen=True, kw_only=True)
class StereoSGBMParams(_OpenCVParams):
    """Parameters of :class:`~cvstereo.matchers.opencv.matcher.StereoSGBMMatcher`: the common ones (see
    ``_OpenCVParams``) and SGBM's own.

    Attributes
    ----------
    block_size : int
        Odd block side (SGBM works with small blocks; default 5).
    p1, p2 : int
        Smoothness penalties; 0 = automatic: OpenCV's usual ``8 * block_size**2`` and ``32 * block_size**2``.
    disp12_max_diff : int
        Left-right consistency tolerance, px (-1: off).
    mode : {"sgbm", "hh", "3way"}
        OpenCV's mode (5-direction SGBM, full 8-direction, 3-way).
    """

    adaptive: ClassVar[AdaptiveDefaults] = AdaptiveDefaults(
        variant="default",
        why="OpenCV's SGBM as it is, with the border rule: no answer where the nearest answers inward say the "
            "partner lies outside the other image",
        params=ADAPTIVE_BORDER,
    )

    block_size: int = param(5, side=True, note="e.g. 5")
    p1: int = 0
    p2: int = 0
    disp12_max_diff: int = 1
    mode: Literal["sgbm", "hh", "3way"] = "sgbm"

    def check_rules(self):
        """The rules between fields: the common one, and SGBM's penalties (OpenCV's rule: p2 > p1)."""
        super().check_rules()
        if self.p1 and self.p2 and self.p2 <= self.p1:
            raise ValueError(f"StereoSGBMParams: p2 must exceed p1 (OpenCV's rule), got p1={self.p1}, p2={self.p2}.")
