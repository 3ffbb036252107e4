"""The thesis' frame-area matcher (method ``frame-area``): block costs between a window's accumulated frames."""

from cvstereo.matchers.frame_area.matcher import FrameAreaMatcher

__all__ = ["FrameAreaMatcher"]
