"""The fused matcher (method ``fused``): features of several matchers' windows combined per pixel."""

from cvstereo.matchers.fused.matcher import FusedMatcher

__all__ = ["FusedMatcher"]
