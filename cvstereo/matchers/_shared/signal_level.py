"""The recording's own signal level, estimated online: what relative decision thresholds are relative to.

Every thesis matcher decides with thresholds on values that grow with the number of events per edge: the
filtered frame value (frame, frame-area) or the dynamic-frame value |D| (event-time, event-area,
event-vector). The thesis' constants (1.2, 2, 0.8 ...) fit the event density of its two sensors; on a recording
with fewer events per edge the matchers fall silent, with more they pass noise. In ``relative`` mode a matcher
sets such a threshold to ``scale * level``, where ``level`` is this module's estimate of the typical size of
the very values the threshold tests.

The estimator (:class:`SignalLevel`), one for all matchers:

* **What it sees.** Per camera, the values the matcher's threshold tests, where there is signal: the
  |filtered value| at each pixel with events in the window (frame matchers), the |D| each event reads at its
  own pixel (event matchers). Values are grouped by absolute window ``k = t // level_window_us``
  (40 ms windows ``[k*W, (k+1)*W)``, as the frame matchers cut time).
* **The statistic.** ``level`` = the ``level_quantile`` quantile (default 0.9) of the values of the last
  ``level_windows`` windows (default 25, one second) that held values of that camera, reaching further back
  (up to :data:`MAX_HISTORY_FACTOR` times as many windows) while they hold fewer than ``level_warmup``
  values, so that a sparse recording gets a level from enough values: a high quantile
  follows the edges, not the isolated noise events, which make up much of the active pixels on a sparse
  recording; a second of history is long against a 40 ms window and short against a change of scene.
  Per camera, because sensors differ in gain (the thesis' eDVS1 gives 7-28 % more events).
* **Causal.** The threshold in force for window k is computed from windows < k only, so every decision uses
  data the matcher has already seen, whatever the packets; and since the values are grouped by absolute
  window, the result does not depend on where packets are cut. Fast paths and references feed the same
  values (bit for bit), so they get the same thresholds.
* **Warm-up and floor.** Until a camera's history holds ``level_warmup`` values, its threshold is the
  absolute one (``threshold``, the thesis' value). A relative threshold never falls below
  ``level_floor`` times the value of one isolated event (the matcher's ``unit``: the kernel's centre weight),
  so a recording of noise alone cannot lower it to where single events pass.

The estimator also keeps the diagnostics that :func:`cvstereo.evaluation.diagnostics.silence_warning` turns
into a one-line explanation when a run yields (almost) nothing: windows seen, windows in which any value
reached the threshold in force, the highest value against its threshold, and the threshold over time.

>>> import numpy as np
>>> p = SignalLevelParams(threshold_mode="relative", threshold_scale=0.5, level_warmup=4)
>>> level = SignalLevel(p, absolute=1.2, unit=0.1)
>>> level.thresholds(0).tolist()                        # nothing seen yet: the absolute threshold
[1.2, 1.2]
>>> level.add(0, 0, np.array([1.0, 2.0, 3.0, 4.0, 5.0]))
>>> level.thresholds(1).tolist()                        # camera 0: 0.5 x the 0.9 quantile (4.6) of window 0
[2.3, 1.2]
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cvstereo._threads import both_cameras
from cvstereo.matchers._shared.sorted_runs import SortedRuns
from cvstereo.matchers.constraints import DeclaredParams, param

#: Threshold modes: the thesis' absolute numbers, or a multiple of the recording's signal level.
THRESHOLD_MODES = ("absolute", "relative")

#: A camera's history reaches back at most this many times ``level_windows`` windows to gather
#: ``level_warmup`` values.
MAX_HISTORY_FACTOR = 10

#: Report the threshold in force once every this many windows of values (1 s of 40 ms windows).
_TRACE_EVERY = 25
#: The run of a part that held no values in a window (each window appends one run per part).
_NONE = np.empty(0, np.float64)


@dataclass(frozen=True, kw_only=True)
class SignalLevelParams(metaclass=DeclaredParams):
    """The relative-threshold fields every thesis matcher's parameter class has (besides ``threshold``).

    Attributes
    ----------
    threshold_mode : {"absolute", "relative"}
        ``absolute``: the matcher's ``threshold`` (and its other value constants) are used as they are, the
        thesis' behaviour. ``relative``: they become ``scale * level`` (see the module docstring).
    threshold_scale : float
        The decision threshold in relative mode, as a multiple of the signal level.
    level_quantile : float
        Quantile of the values that defines the level, in (0, 1].
    level_windows : int
        History: the last this many windows that held values of a camera.
    level_window_us : int
        Length of the estimator's windows on the absolute clock, us.
    level_warmup : int
        Values a camera's history needs before relative thresholds apply (the absolute one until then).
    level_floor : float
        A relative threshold is at least this many times the value of one isolated event.
    """

    threshold_mode: Literal["absolute", "relative"] = "absolute"
    threshold_scale: float = param(1.0, gt=0)
    level_quantile: float = param(0.9, gt=0, le=1, note="e.g. 0.9")
    level_windows: int = param(25, ge=1)
    level_window_us: int = param(40_000, ge=1)
    level_warmup: int = param(200, ge=1, note="e.g. 200")
    level_floor: float = param(1.0, ge=0)

    @property
    def relative(self) -> bool:
        """Whether the thresholds follow the signal level."""
        return self.threshold_mode == "relative"


def level_params(params) -> SignalLevelParams:
    """The :class:`SignalLevelParams` part of a matcher's parameter object."""
    return SignalLevelParams(**{f.name: getattr(params, f.name) for f in dataclasses.fields(SignalLevelParams)})


class SignalLevel:
    """Online, causal estimate of a recording's signal level per camera, and the thresholds it implies.

    Parameters
    ----------
    params : SignalLevelParams (or a matcher's parameters that extend it)
    absolute : float
        The absolute threshold (the matcher's ``threshold``): in force in absolute mode and during warm-up.
    unit : float
        The value of one isolated event (the floor is ``level_floor * unit``).
    value_name : str
        What the values are, for messages ("filtered value", "dynamic-frame value").
    n_cameras : int
    n_parts : int
        Parts of each camera's values (the frames of a matcher with separate OFF and ON frames), each with a level
        of its own (:meth:`part_levels`) from the same windows as the camera's; 1: no parts.
    """

    def __init__(self, params, *, absolute: float, unit: float, value_name: str = "value", n_cameras: int = 2,
                 n_parts: int = 1):
        self.params = level_params(params)
        self.n_parts = int(n_parts)
        self.absolute = float(absolute)
        self.unit = float(unit)
        self.value_name = value_name
        self.n_cameras = n_cameras
        # Each camera's history: one sorted run of values per window and part, oldest first (quantiles without a
        # partition of the whole history per window: see cvstereo.matchers._shared.sorted_runs).
        self._history = [SortedRuns() for _ in range(n_cameras)]
        self._open: dict[int, list[list[list[np.ndarray]]]] = {}  # window -> per camera, per part chunks of values
        self._levels: dict[int, np.ndarray] = {}  # window -> level in force (NaN: warming up)
        self._part_levels: dict[int, np.ndarray] = {}  # window -> (cameras, parts) levels in force, n_parts > 1
        self._seen = 0
        self._with_candidates = 0
        self._best_ratio = -1.0
        self._best = (math.nan, math.nan)  # (value, threshold in force) of the best ratio
        self._trace: list[tuple[int, list[float]]] = []
        self._warm = (False,) * n_cameras  # which cameras had a level at the last trace entry
        #: Close the cameras' windows and compute their levels side by side, the second on
        #: :func:`~cvstereo._threads.side_thread` (the copies, sorts and selections of
        #: :mod:`~cvstereo.matchers._shared.sorted_runs` release the GIL): the same levels and diagnostics, for a
        #: matcher on several threads, where they are a serial part of every window.
        self.side_by_side = False

    # -- the level ---------------------------------------------------------------------------------------

    def levels(self, k: int) -> np.ndarray:
        """The level of each camera in force for window ``k`` (from windows < k); NaN while warming up.

        Every window < k must be complete: values of earlier windows may not be added afterwards.
        """
        k = int(k)
        if k not in self._levels:
            closing = self._closing(k)
            per_camera = self._each_camera(closing, True)
            self._close_diagnostics(closing, per_camera)
            self._levels[k] = np.array([level for _, (level, _) in per_camera])
            if self.n_parts > 1:
                self._part_levels[k] = np.stack([parts for _, (_, parts) in per_camera])
        return self._levels[k]

    def part_levels(self, k: int) -> np.ndarray:
        """(cameras, parts) float64: the level of each part of each camera's values in force for window ``k``:
        the quantile of that part's values in the camera's history (the windows of :meth:`levels`); NaN while the
        part holds fewer than ``level_warmup`` values. With one part, :meth:`levels` as a column."""
        levels = self.levels(k)
        return self._part_levels[int(k)] if self.n_parts > 1 else levels[:, None]

    def relative(self, k: int, *, absolute: float, scale: float, floor: float = 0.0) -> np.ndarray:
        """``max(scale * level, floor)`` per camera for window ``k``; ``absolute`` in absolute mode or warm-up."""
        if not self.params.relative:
            return np.full(self.n_cameras, float(absolute))
        return _scaled(self.levels(k), absolute, scale, floor)

    def thresholds(self, k: int) -> np.ndarray:
        """The decision threshold of each camera in force for window ``k``, as float64."""
        p = self.params
        return self.relative(k, absolute=self.absolute, scale=p.threshold_scale, floor=p.level_floor * self.unit)

    def add(self, k: int, cam: int, values: np.ndarray, part: int = 0) -> None:
        """Add values of camera ``cam`` (of its part ``part``) seen in window ``k`` (|value| is taken; NaN values
        are left out)."""
        k = int(k)
        v = np.abs(np.asarray(values, dtype=np.float64))
        v = v[~np.isnan(v)]
        if v.size == 0:
            return
        if self._levels and k < max(self._levels):
            raise ValueError(f"SignalLevel: values of window {k} come after window {max(self._levels)} was used.")
        window = self._open.get(k)
        if window is None:
            window = self._open[k] = [[[] for _ in range(self.n_parts)] for _ in range(self.n_cameras)]
        window[cam][part].append(v)

    def _closing(self, k: int) -> list[tuple[int, list[list[list[np.ndarray]]], np.ndarray | None]]:
        """Take the open windows < k out, in window order: (window, its values per camera and part, the levels that
        were in force for it or None); forget the levels of windows < k."""
        closing = [(j, self._open.pop(j), self._levels.pop(j, None)) for j in sorted(w for w in self._open if w < k)]
        for j in [w for w in self._levels if w < k]:
            del self._levels[j]
        for j in [w for w in self._part_levels if w < k]:
            del self._part_levels[j]
        return closing

    def _each_camera(self, closing, with_level: bool) -> list:
        """:meth:`_camera_step` for every camera; side by side (:func:`~cvstereo._threads.both_cameras`) where
        :attr:`side_by_side` is set: the cameras' histories are
        independent, and their sorts, selections and copies are a serial part of every window."""
        if self.n_cameras == 2:
            return both_cameras(self._camera_step, closing, with_level, side_by_side=self.side_by_side)
        return [self._camera_step(cam, closing, with_level) for cam in range(self.n_cameras)]

    def _camera_step(self, cam: int, closing, with_level: bool):
        """Move camera ``cam``'s values of the closing windows into its history, in window order, and then (with
        ``with_level``) its levels in force after them (:meth:`_camera_levels`).

        Returns
        -------
        (list of (level in force, highest value or None) per closing window, the levels or None)
        """
        relative = self.params.relative
        warmup = self.params.level_warmup
        seen = []
        for _, window, known in closing:
            # The history holds exactly the windows < this one now: the level that was (or would have been) in force.
            if known is not None:
                level = float(known[cam])
            elif relative:
                level = self._camera_levels(cam, with_parts=False)[0]
            else:  # absolute mode needs only whether the camera is warm (the trace), not the level itself
                level = 0.0 if self._history[cam].size >= warmup else math.nan
            by_part = window[cam]
            top = None
            if any(by_part):
                # add() copied the chunks: no need to again
                runs = [np.concatenate(c) if len(c) > 1 else c[0] if c else _NONE for c in by_part]
                self._remember(cam, runs)
                top = max(float(v.max()) for v in runs if v.size)
            seen.append((level, top))
        return seen, self._camera_levels(cam) if with_level else None

    def _close_diagnostics(self, closing, per_camera) -> None:
        """The diagnostics of the windows :meth:`_camera_step` closed, in window order (camera order within one)."""
        p = self.params
        for j, (window, _, _) in enumerate(closing):
            lv = np.array([seen[j][0] for seen, _ in per_camera])
            thr = _scaled(lv, self.absolute, p.threshold_scale, p.level_floor * self.unit) if p.relative else \
                np.full(self.n_cameras, self.absolute)
            reached = False
            for cam, (seen, _) in enumerate(per_camera):
                top = seen[j][1]
                if top is None:
                    continue
                reached |= bool(top >= thr[cam])
                ratio = top / thr[cam] if thr[cam] > 0 else math.inf
                if ratio > self._best_ratio:
                    self._best_ratio, self._best = ratio, (top, float(thr[cam]))
            warm = tuple(bool(x) for x in ~np.isnan(lv))
            if self._seen % _TRACE_EVERY == 0 or warm != self._warm:
                self._trace.append((window, [round(float(x), 6) for x in thr]))
                self._warm = warm
            self._seen += 1
            self._with_candidates += reached

    def _remember(self, cam: int, runs: list[np.ndarray]) -> None:
        """Append a window's values (one run per part); forget the oldest windows beyond ``level_windows`` that are
        not needed to hold ``level_warmup`` values (and any beyond ``MAX_HISTORY_FACTOR * level_windows``)."""
        p = self.params
        hist = self._history[cam]
        for run in runs:
            hist.append(run)
        g = self.n_parts
        while len(hist) > g * p.level_windows and (hist.size - hist.first_size(g) >= p.level_warmup
                                                   or len(hist) > g * MAX_HISTORY_FACTOR * p.level_windows):
            hist.popleft(g)

    def _camera_levels(self, cam: int, *, with_parts: bool = True) -> tuple[float, np.ndarray | None]:
        """Camera ``cam``'s level (NaN while warming up) and, with several parts (and ``with_parts``), its parts'
        levels: the quantiles of its history (= ``np.quantile`` of the history's values)."""
        p = self.params
        hist = self._history[cam]
        warm = hist.size >= p.level_warmup
        level = hist.quantile(p.level_quantile) if warm else math.nan
        if self.n_parts == 1 or not with_parts:
            return level, None
        parts = hist.part_quantiles(p.level_quantile, self.n_parts, p.level_warmup) if warm else \
            np.full(self.n_parts, np.nan)
        return level, parts

    # -- diagnostics -------------------------------------------------------------------------------------

    def finish(self) -> None:
        """End of stream: close every open window (for the diagnostics)."""
        if self._open:
            closing = self._closing(max(self._open) + 1)
            self._close_diagnostics(closing, self._each_camera(closing, False))

    def diagnostics(self) -> dict:
        """Windows seen, windows with candidates, the highest value against its threshold, thresholds over time.

        Returns
        -------
        dict
            ``windows_seen`` (windows with values), ``windows_with_candidates`` (some value reached the
            threshold in force), ``value_name``, ``highest_value`` and ``its_threshold`` (the window whose highest
            value came nearest its threshold), ``threshold_mode``, ``threshold_trace``: [window end us,
            [threshold per camera]] every 25 windows with values and where a camera's warm-up ends.
        """
        self.finish()
        w = int(self.params.level_window_us)
        value, thr = self._best
        return {
            "windows_seen": int(self._seen),
            "windows_with_candidates": int(self._with_candidates),
            "value_name": self.value_name,
            "highest_value": None if math.isnan(value) else round(value, 6),
            "its_threshold": None if math.isnan(thr) else round(thr, 6),
            "threshold_mode": self.params.threshold_mode,
            "threshold_trace": [[(j + 1) * w, thr] for j, thr in self._trace],
        }


def _scaled(levels: np.ndarray, absolute: float, scale: float, floor: float) -> np.ndarray:
    """``max(scale * level, floor)``, and ``absolute`` where the level is NaN (warm-up)."""
    return np.where(np.isnan(levels), float(absolute), np.maximum(float(scale) * levels, float(floor)))
