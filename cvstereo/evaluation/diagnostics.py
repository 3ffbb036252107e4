"""How much of a recording a run answered, and the one line that says why when it answered almost nothing.

:func:`cvstereo.run.match` counts the 40 ms windows that hold events and those that got matches
(:func:`coverage_of_windows`) into ``meta["diagnostics"]``, beside what the matcher reports of its thresholds;
:func:`silence_warning` turns them into a one-line explanation and a hint. They judge a run of any matcher, so
they are core, not matcher machinery.
"""

from __future__ import annotations

import numpy as np

from cvstereo.model.events import is_time_ordered, window_segments

__all__ = ["coverage_of_windows", "silence_warning", "window_index"]


def window_index(t: np.ndarray, window_us: int) -> np.ndarray:
    """Absolute window of each time, ``t // window_us``, as int64."""
    return np.asarray(t, dtype=np.int64) // int(window_us)


def coverage_of_windows(event_windows, matches: np.ndarray, meta: dict, window_us: int = 40_000) -> tuple[int, int]:
    """(windows with matches, windows with events) on the absolute clock of ``window_us``.

    ``event_windows`` are the windows ``t // window_us`` that hold events (any collection of ints, gathered
    while the recording streams past). Window-anchored matches are stamped with their window's end and count for
    the window before that stamp.
    """
    t = matches["t"].astype(np.int64)
    if meta.get("anchor") == "window" and t.size:
        t = t - 1  # the stamp is the window's end: its events lie before it
    return _windows_with(t, window_us), len(set(event_windows))


def _windows_with(t: np.ndarray, window_us: int) -> int:
    """Number of absolute windows that hold one of the times ``t``: from their runs when ``t`` is ordered (matches
    are time-ordered), which saves ``np.unique``'s hash table over every match."""
    if not is_time_ordered(t):
        return int(np.unique(window_index(t, window_us)).size)
    return len(window_segments(t, window_us))


def silence_warning(meta: dict, *, n_matches: int) -> str | None:
    """One line saying why a run yielded no or almost no matches and what to try; None when it answered.

    A run is silent when it has no matches, or matches in less than 1 % of the 40 ms windows that hold
    events (``meta["diagnostics"]``, written by :func:`cvstereo.run.match`).
    """
    d = meta.get("diagnostics") or {}
    with_events = int(d.get("windows_with_events", 0))
    with_matches = int(d.get("windows_with_matches", 0))
    if with_events == 0:
        return "no events in the recording." if n_matches == 0 else None
    if n_matches and with_matches >= 0.01 * with_events:
        return None
    hint = _hint(meta)
    if d.get("windows_with_candidates", 0) == 0 and d.get("highest_value") is not None:
        why = (f"no window reached the threshold: highest {d.get('value_name', 'value')} "
               f"{d['highest_value']:.3g} < {d['its_threshold']:.3g}")
    elif n_matches == 0:
        why = (f"values reached the threshold in {d.get('windows_with_candidates', 0)} of {with_events} windows "
               "with events, but no pair of cameras agreed")
    else:
        why = (f"matches in only {with_matches} of {with_events} windows with events "
               f"({100.0 * with_matches / with_events:.1f} %)")
    return f"{why}; {hint}"


def _hint(meta: dict) -> str:
    if meta.get("param_set") == "thesis" or (meta.get("params") or {}).get("threshold_mode") == "absolute":
        return ("try --param-set adaptive (thresholds that follow the recording's signal level) or a lower "
                "--param threshold=...")
    return ("try a lower --param threshold_scale=..., another --variant, or `cvstereo rigcheck` (cameras swapped, "
            "rows or clocks offset)")
