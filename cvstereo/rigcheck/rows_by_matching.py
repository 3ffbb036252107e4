"""Row offset by matching: :func:`rows_by_matching`, for when the overlay of frames cannot tell the rows.

The row stage (:func:`~cvstereo.rigcheck.rows.row_offsets`) correlates accumulated frames over row and column
shifts. On a scene with little vertical structure its profile over rows is broad and its peak may sit a row or
more from the truth: NSTlogo.dat (a logo sliding sideways, 2,600 events) with the right camera moved two rows down
was found one row down, at confidence 0.26; a rig turning or translating past texture at 640x480 gave
confidences below 0.2, some of them rows off. A stereo matcher reads the same events more sharply: where the
rows line up, block SADs are low and the left-right check passes, so the matcher answers at more pixels; rows
apart, its answers thin out. This module runs one (``frame-area`` under ``adaptive``: fast, sparse and left-right
checked) on a span of the events with the right camera's rows moved by each candidate offset, and takes the
offset with the most answers (sub-row by a parabola through its neighbours, rounded).

How far the answers' profile over the offsets rises above its median (:attr:`RowsByMatching.prominence`) says
whether the scene tells the rows at all: thin structures before a blank wall and a fine repeating texture give
profiles within a few percent of flat, whose peak is anywhere.

>>> found = rows_from_counts({-2: 650, -1: 700, 0: 480, 1: 70, 2: 30})
>>> found.offset, round(found.prominence, 2)      # -1 beside a strong -2: the parabola says -1.3
(-1, 0.31)
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from cvstereo.geometry.rigcorrect import RigCorrection
from cvstereo.model.matches import concat_matches
from cvstereo.rigcheck.peaks import subsample_peak

__all__ = ["MATCHING_METHOD", "MATCHING_PARAMS", "RowsByMatching", "Span", "matching_span", "moved_matches",
           "over_offsets", "rows_by_matching", "rows_from_counts", "span_matches", "span_of"]

#: The matcher whose answers are counted (its ``adaptive`` default, one thread, with MATCHING_PARAMS on top).
MATCHING_METHOD = "frame-area"
#: What the counting matcher keeps of its own: no uniqueness check. The check's thresholds (answers, ratios, gains)
#: were chosen on frame-area's answers without it, and a rival's answer still tells that the rows fit somewhere.
MATCHING_PARAMS = {"uniqueness": 0.0}


class RowsByMatching(NamedTuple):
    """What :func:`rows_by_matching` found."""

    offset: int
    """Rows to add to the right camera's y (the whole offset nearest the profile's sub-row peak)."""
    prominence: float
    """1 - median / most of the answers over the offsets tried, in [0, 1]; 0 without answers."""
    counts: dict[int, int]
    """Answers per offset tried."""
    span_us: int
    """The span of the events matched, from the first event."""


def _most_answers(counts: dict[int, int]) -> int:
    """The offset with the most answers; of equal ones, the nearest 0."""
    return max(counts, key=lambda r: (counts[r], -abs(r)))


def rows_from_counts(counts: dict[int, int], span_us: int = 0) -> RowsByMatching:
    """The offset with the most answers (sub-row by a parabola through its neighbours where both were tried,
    rounded) and the prominence of the profile."""
    best = _most_answers(counts)
    top = float(counts[best])
    if top <= 0:
        return RowsByMatching(0, 0.0, dict(counts), int(span_us))
    peak = float(best)
    if best - 1 in counts and best + 1 in counts:
        peak = best - 1 + subsample_peak([counts[best - 1], top, counts[best + 1]], 1)
    prominence = 1.0 - float(np.median(list(counts.values()))) / top
    return RowsByMatching(round(peak), prominence, dict(sorted(counts.items())), int(span_us))


def matching_span(left: np.ndarray, right: np.ndarray, *, min_us: int, max_us: int, events: int) -> int:
    """End (exclusive, us) of the span matched: from the first event until each camera has ``events`` events,
    but at least ``min_us`` (the matcher's thresholds follow the signal level from its second 40 ms window on)
    and at most ``max_us``; never past the last event."""
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    last = max(int(left["t"][-1]), int(right["t"][-1])) + 1
    full = max(int(ev["t"][min(events, ev.size) - 1]) + 1 for ev in (left, right))
    return min(last, t0 + max_us, max(t0 + min_us, full))


def span_matches(left: np.ndarray, right: np.ndarray, *, resolution, end: int,
                 method: str = MATCHING_METHOD) -> np.ndarray:
    """``method``'s matches (its ``adaptive`` default with :data:`MATCHING_PARAMS`, one thread) of ``left`` and
    ``right`` up to ``end`` (us): one run of the rows by matching, with the right camera's events already moved."""
    from cvstereo.matchers.registry import create_matcher

    matcher = create_matcher(method, resolution=resolution, threads=1,
                             **(MATCHING_PARAMS if method == MATCHING_METHOD else {}))
    return concat_matches([matcher.feed(left, right, until=end), matcher.flush()])


class Span(NamedTuple):
    """The events a run by matching reads: each camera's up to ``end`` (us, exclusive), from ``t0``."""

    left: np.ndarray
    right: np.ndarray
    end: int
    t0: int


def span_of(left: np.ndarray, right: np.ndarray, *, min_us: int, max_us: int, events: int) -> Span:
    """The events of :func:`matching_span` of ``left`` and ``right``."""
    t0 = min(int(left["t"][0]), int(right["t"][0]))
    end = matching_span(left, right, min_us=min_us, max_us=max_us, events=events)
    return Span(*(ev[:np.searchsorted(ev["t"], end)] for ev in (left, right)), end, t0)


def moved_matches(span: Span, rows: int, *, resolution, exchanged: bool = False) -> np.ndarray:
    """:func:`span_matches` of the span with the right camera's rows moved by ``rows`` (events moved off the
    sensor dropped); ``exchanged``: the cameras the other way round (the span's right camera as the left)."""
    first, second = (span.right, span.left) if exchanged else (span.left, span.right)
    moved = RigCorrection(rows, 0, resolution).correct_right(second)[0]
    return span_matches(first, moved, resolution=resolution, end=span.end)


def over_offsets(run, offsets, threads: int = 1) -> list:
    """``[run(offset) for offset in offsets]``, on up to ``threads`` threads: each offset's run is independent and
    its kernels release the GIL, so on several threads the runs go side by side (the results do not depend on
    it)."""
    offsets = list(offsets)
    if threads <= 1 or len(offsets) <= 1:
        return [run(off) for off in offsets]
    with ThreadPoolExecutor(min(threads, len(offsets))) as pool:
        return list(pool.map(run, offsets))


def rows_by_matching(left: np.ndarray, right: np.ndarray, *, resolution, reach: int, min_us: int = 80_000,
                     max_us: int = 10_000_000, events: int = 100_000, threads: int = 1) -> RowsByMatching:
    """Match ``left`` with ``right`` moved by row offsets from ``-reach`` to ``reach`` and count the answers.

    Every second offset first (the even ones), then the two beside the best of them: the profile over the
    offsets is a few rows wide, so its peak lies within a row of the best even offset, at 11 runs of the matcher
    instead of 17 for a reach of 8.

    Parameters
    ----------
    left, right : ndarray of EVENT_DTYPE
        The events checked (a prefix of the stream), time-ordered, in the cameras' order after any swap.
    resolution : (width, height)
    reach : int
        The largest row offset tried, either way: the right camera's y + offset, events moved off the sensor
        dropped.
    min_us, max_us, events : int
        The span matched (:func:`matching_span`): a dense recording's first ``min_us``, a sparse one's first
        ``events`` per camera, at most ``max_us``.
    threads : int
        How many offsets are matched at once (one thread each; the same counts on any number).

    Returns
    -------
    RowsByMatching
    """
    span = span_of(left, right, min_us=min_us, max_us=max_us, events=events)
    counts = {}

    def answers(row: int) -> int:
        return moved_matches(span, row, resolution=resolution).size

    def count(rows) -> None:
        rows = [r for r in dict.fromkeys(rows) if abs(r) <= reach and r not in counts]
        counts.update(zip(rows, over_offsets(answers, rows, threads), strict=True))

    count(range(-(reach - reach % 2), reach + 1, 2))
    best = _most_answers(counts)
    count((best - 1, best + 1))
    return rows_from_counts(counts, span.end - span.t0)
