"""OpenCV's block matchers as baselines (methods ``stereobm`` and ``sgbm``) on a window's accumulated frames."""

from cvstereo.matchers.opencv.matcher import StereoBMMatcher, StereoBMParams, StereoSGBMMatcher, StereoSGBMParams

__all__ = ["StereoBMMatcher", "StereoBMParams", "StereoSGBMMatcher", "StereoSGBMParams"]
