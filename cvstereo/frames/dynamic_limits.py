"""The limits of the dynamic frames' lazy decay, shared by the compiled frames and their reference.

:mod:`cvstereo.frames.dynamic` (the numba frames) and
:class:`cvstereo.matchers._shared.reference_frames.DynamicFrames` (plain Python) both renormalise and forget at
these points; they are kept in a module without compiled code so that the reference reads them without
importing a kernel.
"""

from __future__ import annotations

__all__ = ["FORGET_TICKS", "RENORM"]

#: Renormalise the stored frames when the lazy decay factor falls below this (0.99^22900, about 5.7 s).
RENORM = 1e-100

#: A gap of more than this many decay ticks clears the frames (0.99^1e6 underflows to zero).
FORGET_TICKS = 1_000_000
