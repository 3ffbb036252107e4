"""The gains between the two cameras' frame values: what the area matchers' ``value_units`` multiplies the other
camera's values by before a SAD: 1 (``"own"``), one per camera (``"camera"``) or one per frame (``"polarity"``: OFF
and ON apart with separate frames).

Two sensors of different contrast thresholds fire different numbers of events at one edge, so their frame values
differ in amplitude by about the ratio of their thresholds, and a SAD counts that difference as a mismatch. The ON
and the OFF threshold of a sensor are set apart (two biases), so the ratio differs by polarity, and may even lie on
opposite sides of 1 (the left camera's ON events thinner than the right's, its OFF events denser). With one gain per
camera it is the ratio of the two cameras' thresholds in force (:func:`threshold_gains`: they follow each camera's
signal level over all its frames). With one per frame, the matcher's own signal level
(:class:`~cvstereo.matchers._shared.signal_level.SignalLevel`: a high quantile of the values the events read at
their own pixels over the last second, from windows before the current one) keeps each camera's values split by
frame (an OFF and an ON part with ``polarity="separate"``; :attr:`FrameGains.parts`), and each part has a level of
its own from the same windows; the gain of a frame is the ratio of the thresholds the two cameras' levels of that
frame imply: ``max(threshold_scale * level, level_floor * unit)`` each, as the thresholds themselves are made. The
floor matters: a sparse recording's frames read mostly decayed values far below one isolated event's, whose ratio
is noise (it reached thousands on movingPersons); at the floor both cameras count alike. Until both levels of a
frame are known (the warm-up: ``level_warmup`` values of that frame), its gain is the ratio of the thresholds in
force. The parts share the thresholds' history and its sorted runs, so the per-frame levels cost a few searches per
window, not a second estimator.

>>> import numpy as np
>>> from cvstereo.matchers._shared.signal_level import SignalLevel, SignalLevelParams
>>> params = SignalLevelParams(level_warmup=2, threshold_scale=0.5)
>>> gains = FrameGains(params, n_frames=2, unit=0.1, units="polarity")
>>> level = SignalLevel(params, absolute=1.0, unit=0.1, n_parts=gains.parts)
>>> gains.add(level, 0, 0, np.array([1.0, 1.0, 4.0, 4.0]), np.array([0, 0, 1, 1]))  # window 0, left: OFF, ON
>>> gains.add(level, 0, 1, np.array([2.0, 2.0, 2.0, 2.0]), np.array([0, 0, 1, 1]))
>>> gains.gains(1, level.thresholds(1), level).tolist()  # [camera][frame]: left OFF 0.5 x the right's, ON 2 x
[[0.5, 2.0], [2.0, 0.5]]
"""

from __future__ import annotations

import numpy as np

__all__ = ["VALUE_UNITS", "FrameGains", "threshold_gains"]

#: The ``value_units`` of the area matchers: no gain, one per camera, one per frame.
VALUE_UNITS = ("own", "camera", "polarity")


def threshold_gains(thresholds) -> np.ndarray:
    """(2,) ``thresholds[c] / thresholds[1 - c]`` per camera ``c`` where both are positive, else 1: the gains of a
    frame whose own levels are not known yet (the thresholds in force follow each camera's level over all frames)."""
    t = np.asarray(thresholds, np.float64)
    if t[0] > 0 and t[1] > 0:
        return np.array([t[0] / t[1], t[1] / t[0]])
    return np.ones(2)


class FrameGains:
    """The gains between the cameras in ``value_units``, from the thresholds in force and the frames' own levels.

    Parameters
    ----------
    params : SignalLevelParams (or a matcher's parameters that extend it)
        The thresholds' scale and floor.
    n_frames : int
        Frames per camera (2 for separate OFF and ON frames).
    unit : float
        The value of one isolated event (the matcher's; the floor is ``level_floor * unit``).
    units : {"own", "camera", "polarity"}
        ``own``: every gain 1; ``camera``: one per camera, the thresholds' ratio; ``polarity``: one per frame from
        the frames' own levels. Only ``polarity`` estimates anything (:attr:`estimates`): the matcher's signal level
        then keeps :attr:`parts` parts.
    """

    def __init__(self, params, *, n_frames: int, unit: float, units: str = "own"):
        if units not in VALUE_UNITS:
            raise ValueError(f"FrameGains: units must be one of {', '.join(VALUE_UNITS)}, got {units!r}.")
        self.n_frames = int(n_frames)
        self.units = units
        self.scale = float(params.threshold_scale)
        self.floor = float(params.level_floor) * float(unit)

    @property
    def estimates(self) -> bool:
        """Whether the gains come from the frames' own levels (``polarity``)."""
        return self.units == "polarity"

    @property
    def parts(self) -> int:
        """The parts the matcher's :class:`~cvstereo.matchers._shared.signal_level.SignalLevel` keeps of each
        camera's values (``n_parts``): one per frame where the gains estimate, else 1."""
        return self.n_frames if self.estimates else 1

    def part_of(self, slot: int) -> int:
        """The part of the signal level that the values of frame ``slot`` go to."""
        return slot if self.estimates else 0

    def add(self, level, k: int, cam: int, values: np.ndarray, slots: np.ndarray) -> None:
        """Add values of camera ``cam`` seen in window ``k``, each of frame ``slots[i]``, to the signal level
        ``level`` (split by frame where the gains estimate; NaN values are left out)."""
        if level.n_parts == 1:
            level.add(k, cam, values)
            return
        for slot in range(self.n_frames):
            level.add(k, cam, values[slots == slot], part=slot)

    def gains(self, k: int, thresholds, level=None) -> np.ndarray:
        """(2, n_frames) float64 for window ``k``: entry ``[c, s]`` multiplies the other camera's values of frame
        ``s`` in the SAD of camera ``c``: the threshold camera ``c``'s level of frame ``s`` implies over the other
        camera's, where both are known (``level``'s :meth:`~cvstereo.matchers._shared.signal_level.SignalLevel.
        part_levels`, read only where the gains estimate); else the ratio of the ``thresholds`` in force
        (:func:`threshold_gains`), which is every frame's gain with one gain per camera; all 1 for ``own``."""
        if self.units == "own":
            return np.ones((2, self.n_frames))
        out = np.repeat(threshold_gains(thresholds)[:, None], self.n_frames, axis=1)
        if not self.estimates:
            return out
        levels = level.part_levels(k)
        for s in range(self.n_frames):
            if np.isfinite(levels[0, s]) and np.isfinite(levels[1, s]):
                a, b = (max(self.scale * float(lv), self.floor) for lv in levels[:, s])
                if a > 0 and b > 0:
                    out[0, s], out[1, s] = a / b, b / a
        return out
