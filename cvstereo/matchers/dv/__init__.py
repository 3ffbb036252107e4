"""dv-processing's semi-dense stereo matcher as a baseline (method ``dv-semidense``; extra ``compare``)."""

from cvstereo.matchers.dv.matcher import DvSemiDenseMatcher, DvSemiDenseParams

__all__ = ["DvSemiDenseMatcher", "DvSemiDenseParams"]
