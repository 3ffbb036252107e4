"""The streaming matcher protocol, variants and parameter parsing (independent of any real matcher)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pytest

from cvstereo.errors import EventFormatError
from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.matchers.registry import METHODS, matcher_class, parse_param_strings
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches


@dataclass(frozen=True)
class _Params:
    window_us: int = 1000
    threshold: float = 1.2
    polarity: Literal["shared", "on"] = "shared"
    gaussian: bool = True


class _WindowCounter(StreamMatcher):
    """Emits, per closed window, one match whose disparity is the number of left events in it."""

    Params = _Params
    variants = {"shared": {"polarity": "shared"}, "on": {"polarity": "on"}}  # noqa: RUF012
    anchor = "window"
    method = "test-counter"

    def __init__(self, params=None, **kw):
        super().__init__(params, **kw)
        self.pending = []

    def _feed(self, left, right):
        self.pending.extend(left["t"].tolist())
        return self._emit(closed_before=self.watermark)

    def _emit(self, closed_before):
        w = self.params.window_us
        done = sorted({t // w for t in self.pending if (t // w + 1) * w <= closed_before})
        out = [make_matches((k + 1) * w, 0, 0, 1, 0, sum(1 for t in self.pending if t // w == k)) for k in done]
        self.pending = [t for t in self.pending if t // w not in done]
        return np.concatenate(out) if out else make_matches([], [], [], [], [], [])

    def _flush(self):
        return self._emit(closed_before=2**62)


def _stream():
    t = np.array([10, 500, 999, 1000, 2500, 2600, 4100])
    return make_events(t, np.arange(t.size), np.zeros(t.size), np.ones(t.size))


@pytest.mark.parametrize("cut", [1, 2, 3, 7])
def test_result_does_not_depend_on_packet_cuts(cut):
    ev = _stream()
    m = _WindowCounter()
    parts = [m.feed(ev[i:i + cut], ev[:0]) for i in range(0, ev.size, cut)] + [m.flush()]
    got = np.concatenate(parts)
    assert got["t"].tolist() == [1000, 2000, 3000, 5000]
    assert got["disparity"].tolist() == [3, 1, 2, 1]
    assert m.input_events == ev.size


def test_until_closes_windows_while_cameras_are_silent():
    m = _WindowCounter()
    assert m.feed(_stream()[:2], _stream()[:0]).size == 0
    out = m.feed(_stream()[:0], _stream()[:0], until=1000)
    assert out["t"].tolist() == [1000] and out["disparity"].tolist() == [2]


def test_packets_going_back_in_time_are_refused():
    m = _WindowCounter()
    ev = _stream()
    m.feed(ev[3:5], ev[:0])
    with pytest.raises(EventFormatError, match=r"right packet starts at t=10, before events already fed"):
        m.feed(ev[:0], ev[:1])


def test_wrong_dtype_is_refused():
    m = _WindowCounter()
    with pytest.raises(EventFormatError, match="not EVENT_DTYPE"):
        m.feed(np.zeros(3), _stream())


def test_variants_and_overrides():
    p = _WindowCounter.make_params("on", threshold=2.0)
    assert (p.polarity, p.threshold) == ("on", 2.0)
    assert _WindowCounter.variant_of(p) == "on"
    assert _WindowCounter.make_params().polarity == "shared"
    with pytest.raises(ValueError, match="unknown variant 'both'; choose one of: shared, on"):
        _WindowCounter.make_params("both")
    with pytest.raises(ValueError, match=r"unknown parameter\(s\) treshold; _Params has: gaussian, polarity"):
        _WindowCounter.make_params(treshold=1)
    meta = _WindowCounter(p).describe()
    assert meta == {"method": "test-counter", "variant": "on", "anchor": "window", "window_us": 1000,
                    "anchor_cameras": [0, 1],
                    "params": {"window_us": 1000, "threshold": 2.0, "polarity": "on", "gaussian": True}}


def test_parse_param_strings_types_and_errors():
    got = parse_param_strings(_Params, ["window_us=40", "threshold=0.5", "polarity=on", "gaussian=false"])
    assert got == {"window_us": 40, "threshold": 0.5, "polarity": "on", "gaussian": False}
    with pytest.raises(ValueError, match="needs a int, got 'x'"):
        parse_param_strings(_Params, ["window_us=x"])
    with pytest.raises(ValueError, match="must be one of shared, on, got 'off'"):
        parse_param_strings(_Params, ["polarity=off"])
    with pytest.raises(ValueError, match="unknown parameter 'size'; allowed: gaussian, polarity, threshold"):
        parse_param_strings(_Params, ["size=3"])
    with pytest.raises(ValueError, match="is not key=value"):
        parse_param_strings(_Params, ["threshold"])


def test_unknown_method_lists_the_known_ones():
    with pytest.raises(ValueError, match="unknown method 'sift'; choose one of: " + ", ".join(METHODS)):
        matcher_class("sift")


def test_a_matcher_that_only_feeds_runs_through_match_with_the_protocols_defaults(monkeypatch):
    """A plugin that defines neither uncertainty nor diagnostics: the protocol's defaults (None, {}) apply, so
    match() stores no uncertainty array and only its own window counts as diagnostics."""
    import importlib.metadata

    from cvstereo.matchers import registry
    from cvstereo.model.recording import Recording
    from cvstereo.run import match

    monkeypatch.setitem(globals(), "_WindowCounter", _WindowCounter)
    plugin = importlib.metadata.EntryPoint("test-counter", f"{__name__}:_WindowCounter", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry.importlib.metadata, "entry_points", lambda **kw: [plugin])
    monkeypatch.setattr(registry, "resolve", lambda method, variant, param_set: (variant, {}))
    registry._methods.cache_clear()
    try:
        ev = _stream()
        result = match(Recording(ev, ev), method="test-counter", variant="shared")
    finally:
        monkeypatch.undo()
        registry._methods.cache_clear()
    assert _WindowCounter(None).take_uncertainty() is None and _WindowCounter(None).diagnostics() == {}
    assert result.arrays == {}
    # Windows of 1000 us: [0,1000) holds 3 left events, [1000,2000) 1, [2000,3000) 2, [4000,5000) 1.
    assert result.matches["disparity"].tolist() == [3, 1, 2, 1]
    assert set(result.meta["diagnostics"]) == {"window_us", "windows_with_events", "windows_with_matches"}
