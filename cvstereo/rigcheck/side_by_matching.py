"""Camera order by matching: :func:`side_by_matching`, for when the overlay of frames cannot tell which camera is left.

The check's side stage compares how strongly the two cameras' accumulated frames overlay at positive and at
negative shifts; on scenes of one depth, of repeating texture or of thin structures the two sides come out
nearly equal and the stage is unsure. A stereo matcher tells the order more sharply: it searches disparities of
one sign only, so with the cameras the wrong way round most of its block matches fail the left-right check.
This runs one (``frame-area`` under ``adaptive``, as the rows by matching) on a span of the prefix in the given
order and in the exchanged one, with the rows the overlay found, and exchanges the cameras only where the
exchanged order answers at least :data:`SIDE_MIN_RATIO` times as often (a swap in error ruins every match).

>>> SideByMatching(swap=False, given=4924, exchanged=1259, span_us=80_000).ratio
0.2557
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cvstereo.rigcheck.rows_by_matching import moved_matches, over_offsets, span_of

__all__ = ["SIDE_MIN_ANSWERS", "SIDE_MIN_RATIO", "SideByMatching", "side_by_matching"]

#: The exchanged order must answer this many times as often as the given one: chosen on suite v2's tuning half and
#: 48 more tuning draws, each in both orders (bench/bench_rig_side.py): the given order, when it was the right
#: one, never answered less than half as often as the exchanged one, and 3 leaves a margin against a swap in error.
SIDE_MIN_RATIO = 3.0
#: ... and at least this many times in all: a handful of answers tells nothing.
SIDE_MIN_ANSWERS = 100


class SideByMatching(NamedTuple):
    """What :func:`side_by_matching` found."""

    swap: bool
    """Exchange the cameras."""
    given: int
    """The matcher's answers in the given order."""
    exchanged: int
    """... and with the cameras exchanged."""
    span_us: int
    """The span of the events matched, from the first event."""

    @property
    def ratio(self) -> float:
        """Answers exchanged over given (4 decimals; inf where the given order has none)."""
        return round(self.exchanged / self.given, 4) if self.given else float("inf")


def side_by_matching(left: np.ndarray, right: np.ndarray, *, resolution, rows: int, min_us: int = 80_000,
                     max_us: int = 10_000_000, events: int = 100_000, threads: int = 1) -> SideByMatching:
    """Match in the given and in the exchanged camera order; exchange where the second answers far more.

    Parameters
    ----------
    left, right : ndarray of EVENT_DTYPE
        The events checked (a prefix of the stream), time-ordered, in the given order.
    resolution : (width, height)
    rows : int
        Rows to add to the given right camera's y (the overlay's row offset in the given order); the exchanged
        order gets ``-rows`` added to the given left camera's.
    min_us, max_us, events : int
        The span matched, as the rows by matching (:func:`~cvstereo.rigcheck.rows_by_matching.matching_span`).
    threads : int
        Both orders are matched at once on two or more (the same counts on any number).

    Returns
    -------
    SideByMatching
    """
    span = span_of(left, right, min_us=min_us, max_us=max_us, events=events)

    def answers(exchanged: bool) -> int:
        return int(moved_matches(span, -rows if exchanged else rows, resolution=resolution, exchanged=exchanged).size)

    given, exchanged = over_offsets(answers, [False, True], threads)
    swap = exchanged >= max(SIDE_MIN_RATIO * given, SIDE_MIN_ANSWERS)
    return SideByMatching(bool(swap), given, exchanged, span.end - span.t0)
