"""The gains between the two cameras' frame values: what the area matchers' ``value_units`` multiplies the other
camera's values by before a SAD: 1 (``"own"``), one per camera (``"camera"``) or one per frame (``"polarity"``: OFF
and ON apart with separate frames).

Two sensors of different contrast thresholds fire different numbers of events at one edge, so their frame values
differ in amplitude by about the ratio of their thresholds, and a SAD counts that difference as a mismatch. The ON
and the OFF threshold of a sensor are set apart (two biases), so the ratio differs by polarity, and may even lie on
opposite sides of 1 (the left camera's ON events thinner than the right's, its OFF events denser). With one gain per
camera it is the ratio of the two cameras' thresholds in force (:func:`threshold_gains`: they follow each camera's
signal level over all its frames). With one per frame, :class:`FrameGains` estimates each camera's signal level per
frame (an OFF and an ON frame with ``polarity="separate"``, one frame
otherwise) with the same causal estimator as the thresholds (:class:`~cvstereo.matchers._shared.signal_level.
SignalLevel`: a high quantile of the values the events read at their own pixels over the last second, from windows
before the current one), and the gain of a frame as the ratio of the thresholds the two cameras' levels of that
frame imply: ``max(threshold_scale * level, level_floor * unit)`` each, as the thresholds themselves are made. The
floor matters: a sparse recording's frames read mostly decayed values far below one isolated event's, whose ratio
is noise (it reached thousands on movingPersons); at the floor both cameras count alike. Until both levels of a
frame are known (the warm-up), its gain is the ratio of the thresholds in force.

>>> import numpy as np
>>> from cvstereo.matchers._shared.signal_level import SignalLevelParams
>>> gains = FrameGains(SignalLevelParams(level_warmup=2, threshold_scale=0.5), n_frames=2, unit=0.1, units="polarity")
>>> gains.add(0, 0, np.array([1.0, 1.0]), np.array([0, 0]))     # window 0: left OFF values ...
>>> gains.add(0, 0, np.array([4.0, 4.0]), np.array([1, 1]))     # ... left ON values
>>> gains.add(0, 1, np.array([2.0, 2.0, 2.0, 2.0]), np.array([0, 0, 1, 1]))
>>> gains.gains(1, np.array([1.0, 1.0])).tolist()             # [camera][frame]: left OFF 0.5 x the right's, ON 2 x
[[0.5, 2.0], [2.0, 0.5]]
"""

from __future__ import annotations

import numpy as np

from cvstereo.matchers._shared.signal_level import SignalLevel

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
    """Each camera's signal level per frame, online and causal, and the gains between the cameras they imply.

    Parameters
    ----------
    params : SignalLevelParams (or a matcher's parameters that extend it)
        The level's windows, quantile and warm-up (the thresholds' own).
    n_frames : int
        Frames per camera (2 for separate OFF and ON frames).
    unit : float
        The value of one isolated event (the matcher's; the floor is ``level_floor * unit``).
    units : {"own", "camera", "polarity"}
        ``own``: every gain 1; ``camera``: one per camera, the thresholds' ratio; ``polarity``: one per frame from
        the frames' own levels. Only ``polarity`` estimates anything (:attr:`estimates`).
    """

    def __init__(self, params, *, n_frames: int, unit: float, units: str = "own"):
        if units not in VALUE_UNITS:
            raise ValueError(f"FrameGains: units must be one of {', '.join(VALUE_UNITS)}, got {units!r}.")
        self.n_frames = int(n_frames)
        self.units = units
        self.scale = float(params.threshold_scale)
        self.floor = float(params.level_floor) * float(unit)
        # One "camera" of the estimator per (camera, frame); the absolute threshold and unit are unused.
        self._level = SignalLevel(params, absolute=0.0, unit=0.0, n_cameras=2 * self.n_frames) \
            if units == "polarity" else None

    @property
    def estimates(self) -> bool:
        """Whether the gains come from the frames' own levels (``polarity``): only then do they need values."""
        return self._level is not None

    def add(self, k: int, cam: int, values: np.ndarray, slots: np.ndarray) -> None:
        """Add values of camera ``cam`` seen in window ``k``, each in frame ``slots[i]`` (NaN values are left out)."""
        if self._level is None:
            return
        values = np.asarray(values)
        if self.n_frames == 1:
            self.add_frame(k, cam, 0, values)
            return
        for slot in range(self.n_frames):
            self.add_frame(k, cam, slot, values[slots == slot])

    def add_frame(self, k: int, cam: int, slot: int, values: np.ndarray) -> None:
        """Add values of frame ``slot`` of camera ``cam`` seen in window ``k`` (NaN values are left out)."""
        if self._level is not None:
            self._level.add(k, cam * self.n_frames + slot, values)

    def gains(self, k: int, thresholds) -> np.ndarray:
        """(2, n_frames) float64 for window ``k``: entry ``[c, s]`` multiplies the other camera's values of frame
        ``s`` in the SAD of camera ``c``: the threshold camera ``c``'s level of frame ``s`` implies over the other
        camera's, where both levels are known (past the warm-up); else the ratio of the ``thresholds`` in force
        (:func:`threshold_gains`), which is every frame's gain with one gain per camera; all 1 for ``own``."""
        if self.units == "own":
            return np.ones((2, self.n_frames))
        out = np.repeat(threshold_gains(thresholds)[:, None], self.n_frames, axis=1)
        if self._level is None:
            return out
        levels = self._level.levels(k).reshape(2, self.n_frames)
        for s in range(self.n_frames):
            if np.isfinite(levels[0, s]) and np.isfinite(levels[1, s]):
                a, b = (max(self.scale * float(lv), self.floor) for lv in levels[:, s])
                if a > 0 and b > 0:
                    out[0, s], out[1, s] = a / b, b / a
        return out
