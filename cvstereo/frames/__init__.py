"""Frames made of events: accumulated frames of a time window (:mod:`.accumulate`), the window clock and the
window-based matcher base (:mod:`.windows`), and the decaying dynamic frames the event matchers and the plots read
(:mod:`.dynamic`).
"""

__all__: list[str] = []  # the names live in the modules; import them from there
