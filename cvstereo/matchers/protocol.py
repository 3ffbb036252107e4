"""The streaming matcher protocol every matcher follows (the thesis' five and the OpenCV baselines).

A matcher is a stateful object: ``feed(left_packet, right_packet) -> matches`` any number of times, then
``flush() -> matches``. Packets may be of any size, and the result does not depend on how the stream was
cut, provided the packets are *time slices*: every event fed later has ``t >=`` every event fed earlier,
on both cameras. This base class keeps that bookkeeping (the "watermark": the time before which the
stream is complete) so that subclasses only decide what to do with complete data. ``flush`` ends the stream:
a packet fed after it is refused (:class:`~cvstereo.errors.StreamEndedError`), since the state it would
need has been emptied.
"""

from __future__ import annotations

import abc
import dataclasses
import math
import numbers
from typing import Any, ClassVar

import numpy as np
from numba import njit

from cvstereo._threads import NOT_A_PARAMETER, check_threads, using_threads
from cvstereo.errors import EventFormatError, StreamEndedError
from cvstereo.matchers._shared.border import border_rule_for
from cvstereo.matchers.constraints import (
    MAX_EXTENT,
    MAX_PARAM_INT,
    DeclaredParams,
    check_value,
    finite_number,
    validate,
    whole_number,
)
from cvstereo.matchers.params import canonical_params
from cvstereo.model.events import DEFAULT_RESOLUTION, EVENT_DTYPE, check_resolution, validate_events
from cvstereo.model.matches import empty_matches

# MAX_EXTENT and MAX_PARAM_INT: defined in cvstereo.matchers.constraints, named here as in 0.2.
__all__ = ["MAX_EXTENT", "MAX_PARAM_INT", "StreamMatcher", "check_param_value", "check_params", "check_until"]

#: The range of ``until``: event times are int64 microseconds.
_INT64 = np.iinfo(np.int64)


def check_param_value(name: str, value, kind: type, *, where: str = "parameter") -> Any:
    """0.2's type rule of one value, kept for code that calls it: a finite number for ``float``, a whole number a
    C int holds for ``int`` (returned as the int), anything else unchecked. The rule of a field is
    :func:`cvstereo.matchers.constraints.check_value` (its type and its declaration)."""
    label = f"{where} '{name}'"
    return finite_number(label, value) if kind is float else whole_number(label, value) if kind is int else value


def check_params(params_cls: type, values: dict) -> dict:
    """``values`` checked against the fields of ``params_cls`` (:func:`cvstereo.matchers.constraints.check_value`;
    names it does not have are returned unchecked, as in 0.2)."""
    fields = {f.name for f in dataclasses.fields(params_cls)}
    return {k: check_value(params_cls, k, v) if k in fields else v for k, v in values.items()}


def check_until(until) -> int:
    """Return ``until`` (:meth:`StreamMatcher.feed`) as an int; raise a ValueError naming it otherwise.

    ``until`` is a time on the events' clock, int64 microseconds: a whole number that int64 holds (a numpy
    integer, or a float without a fraction such as ``80000.0``). NaN, infinities, fractions, bools and strings
    are refused rather than converted, as ``int(inf)`` raises an OverflowError and ``int(1.5)`` would move
    the watermark silently.
    """
    if isinstance(until, bool) or not isinstance(until, numbers.Real):
        raise ValueError(f"until={_shown(until)}: must be a time in whole microseconds (an int), "
                         f"not a {type(until).__name__}.")
    if not isinstance(until, numbers.Integral):
        try:
            whole = math.isfinite(until) and until == int(until)
        except OverflowError:
            whole = False
        if not whole:
            raise ValueError(f"until={_shown(until)}: must be a finite whole number of microseconds.")
    value = int(until)
    if not _INT64.min <= value <= _INT64.max:
        raise ValueError(f"until={_shown(until)}: beyond the int64 microseconds of event times.")
    return value


def _shown(value, limit: int = 40) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


@njit(cache=True, nogil=True)
def _first_bad_event(t, x, y, width, height):
    """Index of the first event off the sensor or earlier than its predecessor, or -1 (one pass, no copies).

    Three vectorised numpy passes over the strided fields were a visible share of the fastest matchers' time;
    this single pass reads each event once.
    """
    for i in range(t.size):
        if x[i] < 0 or x[i] >= width or y[i] < 0 or y[i] >= height or (i > 0 and t[i] < t[i - 1]):
            return i
    return -1


class StreamMatcher(abc.ABC):
    """Base class of all matchers.

    Subclasses set the class attributes and implement :meth:`_feed` and :meth:`_flush`.

    Attributes
    ----------
    Params : type
        The frozen dataclass of parameters, with the thesis defaults.
    variants : dict[str, dict]
        Variant name -> parameter values it sets (docs/formats.md's variant names; the first is the default).
    anchor : {"event", "window"}
        Where matches are anchored (docs/formats.md).
    threads : int
        Threads the matcher may run on (numba's and OpenCV's, :mod:`cvstereo._threads`): a whole number >= 1,
        1 unless set (:func:`~cvstereo.matchers.registry.create_matcher` sets the cores here). Not a parameter:
        the matches do not depend on it, so it is in neither ``params`` nor the matches' meta.
    """

    Params: ClassVar[type]
    variants: ClassVar[dict[str, dict[str, Any]]]
    anchor: ClassVar[str] = "event"
    #: Backs :attr:`threads`: one thread unless set, the serial kernels.
    _threads: int = 1

    @property
    def threads(self) -> int:
        """Threads of numba's and OpenCV's pools while this matcher runs (:func:`cvstereo._threads.using_threads`)."""
        return self._threads

    @threads.setter
    def threads(self, value) -> None:
        self._threads = check_threads(value)

    def __init__(self, params=None, *, resolution: tuple[int, int] = DEFAULT_RESOLUTION):
        if params is None:
            params = self.Params()
        if not isinstance(params, self.Params):
            raise TypeError(f"params must be a {self.Params.__name__}, got {type(params).__name__}.")
        if not isinstance(type(params), DeclaredParams):
            validate(params)  # a plugin's class without the metaclass, built directly: the same rules
        self.params = params
        self.resolution = check_resolution(resolution, source=f"{type(self).__name__} resolution")
        #: Every event fed from now on has t >= watermark (None before the first feed).
        self.watermark: int | None = None
        self.input_events = 0
        #: Set by :meth:`flush`: the stream has ended, further packets are refused.
        self.ended = False
        #: The border rule (:mod:`cvstereo.matchers._shared.border`) every returned match passes, where the
        #: parameters switch it on.
        self._border = border_rule_for(params, self.resolution)

    @classmethod
    def from_variant(cls, variant: str | None = None, *, resolution=DEFAULT_RESOLUTION, **params):
        """Build the matcher for a named variant, with parameter overrides.

        Defaults that are sizes in pixels follow the sensor (:meth:`sensor_defaults`): on a 346x260 sensor the
        disparity range is ``round(64 * 346 / 128) = 173`` px unless ``max_disparity`` is given.
        """
        return cls(cls.params_for(variant, resolution=resolution, **params), resolution=resolution)

    @classmethod
    def params_for(cls, variant: str | None = None, *, resolution=DEFAULT_RESOLUTION, **params):
        """The parameters :meth:`from_variant` builds the matcher with (every check of the values run)."""
        return cls.make_params(variant, **cls.sensor_defaults(resolution, variant, params))

    @classmethod
    def sensor_defaults(cls, resolution, variant: str | None, given: dict) -> dict:
        """``given`` plus the defaults that scale with the sensor width: ``max_disparity`` (the one rule of the
        disparity range: the default on a 128 px wide sensor, times ``width / 128``, see
        :meth:`max_disparity_for`), where the parameters have it and neither ``given`` nor the variant sets it.

        The same optics on a wider sensor give disparities larger by the same factor, so a range fixed in
        pixels would cut off every near object (at 640x480 the thesis' 64 px reach only to ~2 m).
        """
        from cvstereo.matchers.params import canonical_params

        fields = cls.Params.__dataclass_fields__
        width = int(resolution[0])
        if ("max_disparity" not in fields or width == DEFAULT_RESOLUTION[0]
                or "max_disparity" in canonical_params(cls.Params, given)
                or "max_disparity" in cls.variants.get(variant or next(iter(cls.variants)), {})):
            return given
        return {**given, "max_disparity": cls.max_disparity_for(fields["max_disparity"].default, width, given)}

    @classmethod
    def max_disparity_for(cls, default: int, width: int, given: dict) -> int:
        """The default disparity range on a sensor ``width`` px wide: ``round(default * width / 128)``."""
        return round(default * width / DEFAULT_RESOLUTION[0])

    @classmethod
    def make_params(cls, variant: str | None = None, **overrides):
        """Parameters of a variant (docs/formats.md names) with ``overrides`` applied on top.

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
        overrides = canonical_params(cls.Params, overrides)  # old parameter names (cvstereo.matchers.params)
        fields = {f.name for f in dataclasses.fields(cls.Params)}
        unknown = sorted(set(overrides) - fields)
        if unknown:
            raise ValueError(
                f"unknown parameter(s) {', '.join(unknown)}; {cls.Params.__name__} has: {', '.join(sorted(fields))}"
                + (f" ({NOT_A_PARAMETER})." if "threads" in unknown else ".")
            )
        params = cls.Params(**{**cls.variants[variant], **overrides})
        if not isinstance(cls.Params, DeclaredParams):
            validate(params)  # a plugin's class without the metaclass: the same rules (the sweep's grid check)
        return params

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
            while a camera is silent); a whole number of microseconds (:func:`check_until`).

        Returns
        -------
        (M,) ndarray of MATCH_DTYPE
            Time-ordered, and not earlier than matches returned before.

        Raises
        ------
        StreamEndedError
            After :meth:`flush`.
        EventFormatError, ValueError
            A packet or ``until`` the matcher cannot take; the matcher is left as it was.
        """
        if self.ended:
            raise StreamEndedError(f"{type(self).__name__}.feed after flush(): the stream has ended and the state "
                                   "it needs is gone; make a new matcher for another stream.")
        lasts = []
        for name, ev in (("left", left), ("right", right)):
            lasts.extend(self._check_packet(name, ev))
        if until is not None:
            lasts.append(check_until(until))
        self.input_events += left.size + right.size
        if lasts:
            self.watermark = max(lasts) if self.watermark is None else max(self.watermark, *lasts)
        with using_threads(self._threads):
            return self._bordered(self._feed(left, right))

    def _bordered(self, matches: np.ndarray) -> np.ndarray:
        return matches if self._border is None else self._border(matches)

    def _check_packet(self, name: str, ev) -> list[int]:
        """Refuse a packet the kernels cannot take; return its last timestamp (as a list, empty if none).

        Compiled kernels index frames by x and y without bounds checks (an event off the sensor wrote
        outside the buffers: SIGSEGV, heap corruption) and assume time order, so every packet is checked
        whole, vectorised: a few passes over the packet, a small share of any matcher's time.
        """
        source = f"{name} packet"
        if not isinstance(ev, np.ndarray):
            raise EventFormatError(f"{source}: expected an event array of EVENT_DTYPE, got {type(ev).__name__}; "
                                   "build one with cvstereo.model.events.make_events or as_events().")
        if ev.dtype != EVENT_DTYPE:
            raise EventFormatError(f"{source}: dtype {ev.dtype} is not EVENT_DTYPE; convert with as_events().")
        if ev.size and ev.ndim == 1 and self.watermark is not None and ev["t"][0] < self.watermark:
            raise EventFormatError(
                f"{source} starts at t={int(ev['t'][0])}, before events already fed "
                f"(t={self.watermark}); packets must be time slices of both cameras."
            )
        if ev.ndim != 1:
            raise EventFormatError(f"{source}: expected a 1-D event array, got shape {ev.shape}.")
        bad = _first_bad_event(ev["t"], ev["x"], ev["y"], *self.resolution) if ev.size else -1
        if bad >= 0:
            # The prefix before `bad` is valid, so the contract's checker names exactly that event and field.
            validate_events(ev[: bad + 1], resolution=self.resolution, source=source)
        return [int(ev["t"][-1])] if ev.size else []

    def flush(self) -> np.ndarray:
        """End of stream: return the matches still held back (open windows, pending candidates).

        The stream ends here: a later :meth:`feed` raises :class:`~cvstereo.errors.StreamEndedError`, and a
        second ``flush`` returns no matches (everything was returned by the first).
        """
        if self.ended:
            return empty_matches()
        self.ended = True
        with using_threads(self._threads):
            return self._bordered(self._flush())

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

    def take_uncertainty(self) -> np.ndarray | None:
        """The uncertainty (0..1, lower is more certain) of every match returned since the last call, in order,
        or None: this matcher does not rate its matches (the default).

        Part of the protocol so that the run loop asks every matcher the same way; a matcher that rates its
        matches (docs/formats.md's optional per-match array ``uncertainty``) overrides it.
        """
        return None

    #: The matcher's signal level (:class:`~cvstereo.matchers._shared.signal_level.SignalLevel`), where it keeps
    #: one (set in ``__init__``): :meth:`diagnostics` reports it.
    _level = None

    def diagnostics(self) -> dict:
        """What the matcher observed of its own thresholds so far, for ``meta["diagnostics"]``
        (:func:`cvstereo.evaluation.diagnostics.silence_warning` reads it): its signal level's diagnostics
        (:meth:`cvstereo.matchers._shared.signal_level.SignalLevel.diagnostics`) where it keeps one, else empty."""
        return {} if self._level is None else self._level.diagnostics()

    method: ClassVar[str] = "?"
