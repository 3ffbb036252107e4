"""Reference event-area matcher (algorithms.md section 4, thesis Algorithm 3)."""

from __future__ import annotations

import numpy as np

from calibration_free.event_area import EventAreaParams
from calibration_free.reference import LevelByWindow, merged_events
from cvstereo.dynamic_frames import DynamicFrames
from cvstereo.events import DEFAULT_RESOLUTION
from cvstereo.matches import empty_matches, make_matches


def event_area_reference(left: np.ndarray, right: np.ndarray, params: EventAreaParams | None = None, *,
                         resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the event-area algorithm, one event at a time.

    Parameters
    ----------
    left, right : (N,) ndarray of EVENT_DTYPE
    params : EventAreaParams, optional
    resolution : (width, height), keyword-only

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        One row per matched event of either camera, in processing order (time-ordered).
    """
    prm = params if params is not None else EventAreaParams()
    width, height = resolution
    frames = [DynamicFrames(prm.frame_params(), resolution=resolution) for _ in range(2)]
    half = prm.block // 2
    level = LevelByWindow(prm)
    rows = []
    for cam, _, e in merged_events(left, right):
        t, x, y, p = int(e["t"]), int(e["x"]), int(e["y"]), int(e["p"])
        threshold = level.at(t)[cam]
        own, other = frames[cam], frames[1 - cam]
        slot = own.slot(p)
        if slot < 0:
            continue
        own.advance(t)
        other.advance(t)
        level.seen(cam, own.value(slot, x, y))
        # Matching happens before the event updates its own frame.
        if abs(own.value(slot, x, y)) >= threshold and half <= x < width - half and half <= y < height - half:
            minimum = prm.max_sad
            disparity = None
            for d in range(prm.max_disparity + 1):
                x2 = x + d if cam == 1 else x - d  # right camera: towards larger x; left: smaller
                if x2 - half < 0 or x2 + half >= width:
                    break
                sad = 0.0
                for j in range(-half, half + 1):
                    for i in range(-half, half + 1):
                        sad += abs(own.value(slot, x + i, y + j) - other.value(slot, x2 + i, y + j))
                if sad < minimum:  # strict: ties keep the smaller disparity
                    minimum = sad
                    disparity = d
            if disparity is not None:
                rows.append((t, x, y, p, cam, float(disparity)))
        own.add(slot, x, y, 1.0 if p else -1.0)
    if not rows:
        return empty_matches()
    return make_matches(*zip(*rows, strict=True))
