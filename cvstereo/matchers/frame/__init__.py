"""The thesis' frame matcher (method ``frame``): clusters of a window's accumulated frames matched row by row."""

from cvstereo.matchers.frame.matcher import FrameClusterMatcher

__all__ = ["FrameClusterMatcher"]
