"""Reference event-vector matcher (docs/algorithms.md section 5, thesis Algorithm 4)."""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.reference import sign
from cvstereo.matchers._shared.reference_frames import DynamicFrames, match_merged
from cvstereo.matchers.event_vector.params import EventVectorParams
from cvstereo.model.events import DEFAULT_RESOLUTION

__all__ = ["accumulation_vector", "choose", "event_vector_reference", "run_sides"]


def accumulation_vector(frames: DynamicFrames, slot: int, x: int, y: int, threshold: float) -> tuple[int, int]:
    """The vector (a, b) of pixel (x, y): signed distances to the next accumulation left and right of its run.

    Walk out of x's own run of above-threshold pixels (no step if x itself is below), then on to the next
    above-threshold pixel; the distance carries the sign of D there; 0 when the row ends first.
    """
    width = frames.stored.shape[2]

    def above(k: int) -> bool:
        return abs(frames.value(slot, k, y)) >= threshold

    k = x
    while k >= 0 and above(k):
        k -= 1
    while k >= 0 and not above(k):
        k -= 1
    a = sign(frames.value(slot, k, y)) * (x - k) if k >= 0 else 0
    k = x
    while k < width and above(k):
        k += 1
    while k < width and not above(k):
        k += 1
    b = sign(frames.value(slot, k, y)) * (k - x) if k < width else 0
    return a, b


def run_sides(frames: DynamicFrames, slot: int, x: int, y: int, threshold: float) -> tuple[int, int]:
    """How many pixels of x's run of above-threshold pixels lie left and right of x; (0, 0) if x is below."""
    width = frames.stored.shape[2]

    def above(k: int) -> bool:
        return 0 <= k < width and abs(frames.value(slot, k, y)) >= threshold

    if not above(x):
        return 0, 0
    left = right = 0
    while above(x - left - 1):
        left += 1
    while above(x + right + 1):
        right += 1
    return left, right


def choose(costs: dict[int, float], prm: EventVectorParams, bound: float | None) -> float | None:
    """The disparity of the least cost among ``costs`` (disparity -> cost), if below ``max_cost`` and at most
    ``bound``: the smallest of equal cost, or (``tie_break="centre"``) the middle of the smallest and largest."""
    if not costs:
        return None
    best = min(costs.values())
    if not best < prm.max_cost or (bound is not None and best > bound):
        return None
    tied = [d for d, c in costs.items() if c == best]
    return 0.5 * (min(tied) + max(tied)) if prm.tie_break == "centre" else float(min(tied))


def event_vector_reference(left: np.ndarray, right: np.ndarray, params: EventVectorParams | None = None, *,
                           resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the event-vector algorithm, one event at a time.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        One row per matched event of either camera, in processing order (time-ordered). Everything is
        computed before the event updates its own frame.

    See Also
    --------
    cvstereo.matchers._shared.reference : the arguments, the same for every reference function.
    """
    prm = params if params is not None else EventVectorParams()
    width = resolution[0]

    def vector(frames: DynamicFrames, slot: int, x: int, y: int, threshold: float) -> tuple[int, ...]:
        # (a, b), with run_ends also the pixels of x's run left and right of x.
        a, b = accumulation_vector(frames, slot, x, y, threshold)
        return (a, b, *run_sides(frames, slot, x, y, threshold)) if prm.run_ends else (a, b)

    def search(own: DynamicFrames, other: DynamicFrames, slot: int, cam: int, x: int, y: int,
               thresholds: np.ndarray) -> float | None:
        # The event's own row by its camera's threshold, the candidate row by the other camera's.
        own_threshold, other_threshold = thresholds[cam], thresholds[1 - cam]
        value = own.value(slot, x, y)
        if not abs(value) >= own_threshold:
            return None
        v1 = vector(own, slot, x, y, own_threshold)
        costs = {}
        for d in range(prm.max_disparity + 1):
            x2 = x + d if cam == 1 else x - d  # right camera: towards larger x; left: smaller
            if x2 < 0 or x2 >= width:
                break
            v2 = other.value(slot, x2, y)
            if prm.require_candidate_threshold and not (abs(v2) >= other_threshold and sign(v2) == sign(value)):
                continue
            costs[d] = sum(abs(p - q) for p, q in zip(v1, vector(other, slot, x2, y, other_threshold), strict=True))
        bound = prm.cost_slack + prm.cost_ratio * sum(abs(v) for v in v1) if prm.cost_ratio > 0 else None
        return choose(costs, prm, bound)

    return match_merged(left, right, prm, search, resolution=resolution)
