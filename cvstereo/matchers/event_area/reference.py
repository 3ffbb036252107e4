"""Reference event-area matcher (docs/algorithms.md section 4, thesis Algorithm 3)."""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.reference_frames import DynamicFrames, match_merged
from cvstereo.matchers.event_area.params import EventAreaParams
from cvstereo.model.events import DEFAULT_RESOLUTION

__all__ = ["event_area_reference"]


def event_area_reference(left: np.ndarray, right: np.ndarray, params: EventAreaParams | None = None, *,
                         resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> np.ndarray:
    """Match a whole stereo stream with the event-area algorithm, one event at a time.

    Returns
    -------
    (M,) ndarray of MATCH_DTYPE
        One row per matched event of either camera, in processing order (time-ordered). Each event is
        matched before it updates its own frame.

    See Also
    --------
    cvstereo.matchers._shared.reference : the arguments, the same for every reference function.
    """
    prm = params if params is not None else EventAreaParams()
    width, height = resolution
    half = prm.block // 2

    def search(own: DynamicFrames, other: DynamicFrames, slot: int, cam: int, x: int, y: int,
               thresholds: np.ndarray, gains: np.ndarray) -> int | None:
        if not (abs(own.value(slot, x, y)) >= thresholds[cam] and half <= x < width - half and
                half <= y < height - half):
            return None
        minimum = prm.max_costs(thresholds)[cam]
        # The frames compared: the event's own, or (sad_frames="all") all of the camera's, in slot order.
        slots = range(own.n_frames) if prm.sad_frames == "all" else (slot,)
        gain = gains[cam]  # the other camera's values of each frame in this camera's units (value_units)
        if prm.own_ratio > 0:
            own_abs = 0.0
            for s in slots:
                for j in range(-half, half + 1):
                    for i in range(-half, half + 1):
                        own_abs += abs(own.value(s, x + i, y + j))
            minimum = min(minimum, prm.own_ratio * own_abs)
        disparity = None
        sads = {}
        for d in range(prm.max_disparity + 1):
            x2 = x + d if cam == 1 else x - d  # right camera: towards larger x; left: smaller
            if x2 - half < 0 or x2 + half >= width:
                break
            sad = 0.0
            for s in slots:
                for j in range(-half, half + 1):
                    for i in range(-half, half + 1):
                        sad += abs(own.value(s, x + i, y + j) - other.value(s, x2 + i, y + j) * gain[s])
            sads[d] = sad
            if sad < minimum:  # strict: ties keep the smaller disparity
                minimum = sad
                disparity = d
        if prm.uniqueness > 0 and disparity is not None:
            # Ambiguous: another candidate more than 1 px away within the factor 1 + uniqueness of the best.
            if any(abs(d - disparity) > 1 and sad <= minimum * (1.0 + prm.uniqueness) for d, sad in sads.items()):
                return None
        return disparity

    return match_merged(left, right, prm, search, resolution=resolution, value_units=prm.value_units)
