"""The thesis' event-area matcher (method ``event-area``): block costs on the dynamic frames, event by event."""

from cvstereo.matchers.event_area.matcher import EventAreaMatcher

__all__ = ["EventAreaMatcher"]
