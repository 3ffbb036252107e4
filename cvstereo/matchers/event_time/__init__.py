"""The thesis' event-time matcher (method ``event-time``): each event against the other camera's dynamic frames."""

from cvstereo.matchers.event_time.matcher import EventTimeMatcher

__all__ = ["EventTimeMatcher"]
