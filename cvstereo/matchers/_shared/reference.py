"""Reference implementations of every matcher: readable code that follows ``docs/algorithms.md`` step by step.

One module per matcher (``cvstereo.matchers.<name>.reference``), and the reference dynamic frames
(:mod:`.reference_frames`). Each matcher's function ``<name>_reference(left, right, params, *, resolution)``
takes the whole stream at once and returns a time-ordered matches array; its own docstring says what its rows
are. The arguments, the same for every one:

Parameters
----------
left, right : (N,) ndarray of EVENT_DTYPE
    Each camera's events, time-ordered.
params : the matcher's parameter class (``cvstereo.matchers.<name>.params``), optional
    None: the class's defaults.
resolution : (width, height), keyword-only
    The sensor size (default: the DVS128's).

They are slow (use them on short inputs) and exist so that tests can hold the fast
matchers to them: same anchors, same disparities, bit for bit. They share with the fast matchers only what is
not code of a kernel: the parameter classes
(``cvstereo.matchers.<name>.params``), named constants (:mod:`cvstereo.matchers._shared.consistency`,
:mod:`cvstereo.frames.dynamic_limits`) and, in relative threshold mode, the signal-level estimator
(:class:`cvstereo.matchers._shared.signal_level.SignalLevel`), which they feed with the values they compute,
window by window (the event references one event at a time, through
:class:`~cvstereo.matchers._shared.reference_frames.LevelByWindow`). The merge order of the two cameras, the
frames and their Gaussian, the dynamic frames' kernel, neighbour support and the left-right check are computed
here again from their definitions (:mod:`.reference_frames`, :mod:`.reference_windows`, :mod:`.reference_checks`),
and no reference module imports a module holding a numba kernel (test_reference_independence).
"""

from __future__ import annotations


def sign(value: float) -> int:
    """-1, 0 or +1."""
    return 1 if value > 0 else (-1 if value < 0 else 0)
