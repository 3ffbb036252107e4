"""The thesis' event-vector matcher (method ``event-vector``): runs of a row of the dynamic frames, event by event."""

from cvstereo.matchers.event_vector.matcher import EventVectorMatcher

__all__ = ["EventVectorMatcher"]
