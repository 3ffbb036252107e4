"""The streaming matcher protocol every matcher follows (the thesis' five and the OpenCV baselines).

A matcher is a stateful object: ``feed(left_packet, right_packet) -> matches`` any number of times, then
``flush() -> matches``. Packets may be of any size, and the result does not depend on how the stream was
cut, provided the packets are *time slices*: every event fed later has ``t >=`` every event fed earlier,
on both cameras. This base class keeps that bookkeeping (the "watermark": the time before which the
stream is complete) so that subclasses only decide what to do with complete data.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.events import DEFAULT_RESOLUTION, EVENT_DTYPE
from cvstereo.matches import empty_matches
from cvstereo.params import canonical_params


class StreamMatcher(abc.ABC):
    """Base class of all matchers.

    Subclasses set the class attributes and implement :meth:`_feed` and :meth:`_flush`.

    Attributes
    ----------
    Params : type
        The frozen dataclass of parameters, with the thesis defaults.
    variants : dict[str, dict]
        Variant name -> parameter values it sets (formats.md's variant names; the first is the default).
    anchor : {"event", "window"}
        Where matches are anchored (formats.md).
    """

    Params: ClassVar[type]
    variants: ClassVar[dict[str, dict[str, Any]]]
    anchor: ClassVar[str] = "event"

    def __init__(self, params=None, *, resolution: tuple[int, int] = DEFAULT_RESOLUTION):
        if params is None:
            params = self.Params()
        if not isinstance(params, self.Params):
            raise TypeError(f"params must be a {self.Params.__name__}, got {type(params).__name__}.")
        self.params = params
        self.resolution = (int(resolution[0]), int(resolution[1]))
        #: Every event fed from now on has t >= watermark (None before the first feed).
        self.watermark: int | None = None
        self.input_events = 0

    @classmethod
    def from_variant(cls, variant: str | None = None, *, resolution=DEFAULT_RESOLUTION, **params):
        """Build the matcher for a named variant, with parameter overrides."""
        return cls(cls.make_params(variant, **params), resolution=resolution)

    @classmethod
    def make_params(cls, variant: str | None = None, **overrides):
        """Parameters of a variant (formats.md names) with ``overrides`` applied on top.

        Raises
        ------
        ValueError
            Unknown variant or parameter name; the message lists the allowed ones.
        """
        names = list(cls.variants)
        if variant is None:
            variant = names[0]
        if variant not in cls.variants:
            raise ValueError(f"unknown variant '{variant}'; choose one of: {', '.join(names)}.")
        overrides = canonical_params(cls.Params, overrides)  # old parameter names (cvstereo.params)
        fields = {f.name for f in dataclasses.fields(cls.Params)}
        unknown = sorted(set(overrides) - fields)
        if unknown:
            raise ValueError(
                f"unknown parameter(s) {', '.join(unknown)}; {cls.Params.__name__} has: {', '.join(sorted(fields))}."
            )
        return cls.Params(**{**cls.variants[variant], **overrides})

    @classmethod
    def variant_of(cls, params) -> str:
        """The name of the first variant whose settings ``params`` has, or ``"custom"``."""
        for name, settings in cls.variants.items():
            if all(getattr(params, k) == v for k, v in settings.items()):
                return name
        return "custom"

    def feed(self, left: np.ndarray, right: np.ndarray, *, until: int | None = None) -> np.ndarray:
        """Process a time slice of both cameras; return the matches that are now final.

        Parameters
        ----------
        left, right : (N,) ndarray of EVENT_DTYPE
            Time-ordered; no event earlier than any event fed before.
        until : int, optional
            The caller vouches that no event fed later has ``t < until`` (lets a matcher close windows
            while a camera is silent).

        Returns
        -------
        (M,) ndarray of MATCH_DTYPE
            Time-ordered, and not earlier than matches returned before.
        """
        lasts = []
        for name, ev in (("left", left), ("right", right)):
            if ev.dtype != EVENT_DTYPE:
                raise EventFormatError(f"{name} packet: dtype {ev.dtype} is not EVENT_DTYPE; convert with as_events().")
            if ev.size:
                if self.watermark is not None and ev["t"][0] < self.watermark:
                    raise EventFormatError(
                        f"{name} packet starts at t={int(ev['t'][0])}, before events already fed "
                        f"(t={self.watermark}); packets must be time slices of both cameras."
                    )
                lasts.append(int(ev["t"][-1]))
        if until is not None:
            lasts.append(int(until))
        self.input_events += left.size + right.size
        if lasts:
            self.watermark = max(lasts) if self.watermark is None else max(self.watermark, *lasts)
        return self._feed(left, right)

    def flush(self) -> np.ndarray:
        """End of stream: return the matches still held back (open windows, pending candidates)."""
        return self._flush()

    @abc.abstractmethod
    def _feed(self, left: np.ndarray, right: np.ndarray) -> np.ndarray:
        """Consume a packet; ``self.watermark`` is already advanced past it."""

    def _flush(self) -> np.ndarray:
        return empty_matches()

    def describe(self) -> dict:
        """The matches-file meta of this matcher (method, variant, params, anchor, window_us)."""
        params = dataclasses.asdict(self.params)
        return {
            "method": self.method,
            "variant": self.variant_of(self.params),
            "params": params,
            "anchor": self.anchor,
            "window_us": int(params.get("window_us", 0)) if self.anchor == "window" else 0,
            "anchor_cameras": list(self.anchor_cameras()),
        }

    def anchor_cameras(self) -> tuple[int, ...]:
        """Cameras whose pixels the matches are anchored on (0 = left, 1 = right)."""
        return (0, 1)

    method: ClassVar[str] = "?"
