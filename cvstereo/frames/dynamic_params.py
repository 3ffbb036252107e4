"""The parameters of the dynamic frames (:mod:`cvstereo.frames.dynamic`), in a module without compiled code, so
that the readable references (:mod:`cvstereo.matchers._shared.reference_frames`) take them without importing the
fast path's kernels."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from cvstereo.matchers.constraints import DeclaredParams, param
from cvstereo.model.polarity import Polarity

__all__ = ["DynamicFrameParams"]


@dataclass(frozen=True, kw_only=True)
class DynamicFrameParams(metaclass=DeclaredParams):
    """Parameters of the dynamic frames, shared by the parameter classes of all event matchers.

    Attributes
    ----------
    polarity : {"shared", "separate", "on", "off"}
        ON and OFF in one frame (thesis default), one frame each, ON events only, OFF events only.
    gaussian : bool
        Add ``gaussian_gain * s * G`` (eq. 3.9); False adds s at the event's pixel only (eq. 4.1).
    kernel_size : int
        Odd side of the Gaussian G (thesis: 3).
    kernel_sigma : float
        Its standard deviation in pixels (thesis: 1).
    gaussian_gain : float
        The factor 2 of eq. 3.9.
    decay : float
        Factor applied to all values at every tick (thesis: 0.99).
    decay_period_us : int
        Tick period on the absolute clock (thesis: 250 us).
    """

    polarity: Polarity = "shared"
    gaussian: bool = True
    kernel_size: int = param(3, side=True, note="the thesis uses 3")
    kernel_sigma: float = param(1.0, gt=0, note="the thesis uses 1.0")
    gaussian_gain: float = 2.0
    decay: float = param(0.99, gt=0, le=1, note="the thesis uses 0.99")
    decay_period_us: int = param(250, gt=0, note="the thesis uses 250")

    def frame_params(self) -> DynamicFrameParams:
        """The dynamic-frame part of a (derived) parameter object."""
        return DynamicFrameParams(**{f.name: getattr(self, f.name) for f in dataclasses.fields(DynamicFrameParams)})
