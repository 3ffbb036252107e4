"""Reference implementations of every matcher: readable code that follows ``docs/algorithms.md`` step by step.

One module per matcher (:mod:`.frame_clusters`, :mod:`.frame_area`, :mod:`.event_time`, :mod:`.event_area`,
:mod:`.event_vector`), and the reference dynamic frames (:mod:`.dynamic_frames`). Each matcher's function
``<name>_reference(left, right, params, *, resolution)`` takes the whole stream at once and returns a
time-ordered matches array. They are slow (use them on short inputs) and exist so that tests can hold the fast
matchers to them: same anchors, same disparities, bit for bit. They share the parameter classes
(``cvstereo.matchers.<name>.params``) and the merge order of the two cameras
(:mod:`cvstereo.matchers._shared.merge_order`)
with the fast matchers, and import none of their kernels. In relative threshold mode they feed the same
signal-level estimator (:class:`cvstereo.matchers._shared.signal_level.SignalLevel`) with the values they compute,
window by
window (the event references one event at a time, through
:class:`~cvstereo.matchers._shared.reference_frames.LevelByWindow`).
"""

from __future__ import annotations


def sign(value: float) -> int:
    """-1, 0 or +1."""
    return 1 if value > 0 else (-1 if value < 0 else 0)
