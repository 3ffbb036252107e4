"""A stereo recording held in memory: two event streams, optional ground truth, resolution and metadata."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from cvstereo.errors import EventFormatError
from cvstereo.model.events import (
    DEFAULT_RESOLUTION,
    StereoPacket,
    as_events,
    check_resolution,
    distinct_sorted,
    time_slice,
)

__all__ = ["CAMERAS", "ORIGIN_KEY", "Recording", "check_origin", "origin_of"]

CAMERAS = ("left", "right")

#: Meta key of the recording's time origin (docs/formats.md): the absolute time, us, that every time shown and
#: every time option counts from.
ORIGIN_KEY = "origin_us"


def check_origin(value, *, source: str = "meta") -> int:
    """``value`` as an origin in us: a whole number within int64 (a bool or a float is a corrupt meta, not a time).

    Raises
    ------
    ValueError
        Naming ``source`` and the key, and what an origin must be.
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not -2**63 <= int(value) < 2**63:
        raise EventFormatError(f"{source}: {ORIGIN_KEY} must be a whole number of microseconds (the absolute time "
                               f"of t = 0), got {value!r}; remove the key to count from the first event.")
    return int(value)


def origin_of(meta: dict, first_times) -> int | None:
    """The time (us) a recording's times are shown from: its stored ``meta["origin_us"]`` (a slice keeps its
    recording's), else the earliest of ``first_times`` (each camera's first event time; empty cameras left out);
    None when there is neither. One rule for a recording in memory (:attr:`Recording.origin_us`) and for a stream
    whose first times come from its fingerprint (:func:`cvstereo.run.match`)."""
    if meta.get(ORIGIN_KEY) is not None:
        return int(meta[ORIGIN_KEY])
    firsts = [int(t) for t in first_times if t is not None]
    return min(firsts) if firsts else None


@dataclass(frozen=True, eq=False)
class Recording:
    """Events of the left and right camera on one clock (docs/formats.md, "Stereo recording file").

    Parameters
    ----------
    left, right : (N,) ndarray
        Event arrays; converted to EVENT_DTYPE and validated.
    left_disparity, right_disparity : (N,) float32 ndarray or None
        True disparity ``x_left - x_right`` per event, NaN where unknown (noise); None without ground truth.
    resolution : (width, height)
    meta : dict
        JSON-serialisable: rig, scene, source.
    """

    left: np.ndarray
    right: np.ndarray
    left_disparity: np.ndarray | None = None
    right_disparity: np.ndarray | None = None
    resolution: tuple[int, int] = DEFAULT_RESOLUTION
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        res = check_resolution(self.resolution, source="Recording resolution")
        object.__setattr__(self, "resolution", res)
        for name in CAMERAS:
            ev = as_events(getattr(self, name), resolution=res, source=f"{name} camera")
            object.__setattr__(self, name, ev)
            truth = getattr(self, f"{name}_disparity")
            if truth is not None:
                truth = np.asarray(truth, dtype=np.float32)
                if truth.shape != ev.shape:
                    raise EventFormatError(
                        f"{name}_disparity has {truth.shape[0] if truth.ndim else 0} values for {ev.size} "
                        f"{name} events; give one disparity (NaN if unknown) per event."
                    )
                object.__setattr__(self, f"{name}_disparity", truth)
        if (self.left_disparity is None) != (self.right_disparity is None):
            raise EventFormatError("give ground truth for both cameras or for neither (NaN where unknown).")
        if ORIGIN_KEY in self.meta:
            check_origin(self.meta[ORIGIN_KEY])

    @property
    def has_truth(self) -> bool:
        """True when both cameras carry per-event ground truth."""
        return self.left_disparity is not None

    def events(self, camera: int) -> np.ndarray:
        """Events of camera 0 (left) or 1 (right)."""
        return self.left if camera == 0 else self.right

    def truth(self, camera: int) -> np.ndarray | None:
        """Ground truth of camera 0 (left) or 1 (right), or None."""
        return self.left_disparity if camera == 0 else self.right_disparity

    @property
    def t_start(self) -> int:
        """Earliest timestamp of either camera (0 for an empty recording)."""
        firsts = [int(e["t"][0]) for e in (self.left, self.right) if e.size]
        return min(firsts) if firsts else 0

    @property
    def t_end(self) -> int:
        """Latest timestamp of either camera (0 for an empty recording)."""
        lasts = [int(e["t"][-1]) for e in (self.left, self.right) if e.size]
        return max(lasts) if lasts else 0

    @property
    def origin_us(self) -> int:
        """The absolute time (us) that times shown count from: ``meta["origin_us"]`` where stored (a slice keeps
        its recording's), else the earliest event of either camera; windows stay on the absolute clock."""
        return origin_of(self.meta, [int(e["t"][0]) for e in (self.left, self.right) if e.size]) or 0

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last event of either camera."""
        return (self.t_end - self.t_start) / 1e6

    def packets(self, packet_us: int = 10_000) -> Iterator[StereoPacket]:
        """Iterate over time-aligned packets of both cameras.

        The same packets as :func:`cvstereo.model.events.iter_stereo_packets` (absolute windows ``[k*P, (k+1)*P)``,
        windows without events skipped), cut from the arrays in memory as views, without copying.
        """
        if packet_us <= 0:
            raise ValueError(f"packet_us must be positive, got {packet_us}.")
        ks = np.union1d(distinct_sorted(self.left["t"] // packet_us), distinct_sorted(self.right["t"] // packet_us))
        bounds = ks * packet_us
        cuts = [(np.searchsorted(ev["t"], bounds, side="left"), np.searchsorted(ev["t"], bounds + packet_us,
                                                                                  side="left"))
                for ev in (self.left, self.right)]
        for i, stop in enumerate((bounds + packet_us).tolist()):
            sl, sr = (slice(int(lo[i]), int(hi[i])) for lo, hi in cuts)
            yield StereoPacket(self.left[sl], self.right[sr], stop,
                               None if self.left_disparity is None else self.left_disparity[sl],
                               None if self.right_disparity is None else self.right_disparity[sr])

    def slice_time(self, t_start: int | None = None, t_stop: int | None = None) -> Recording:
        """The part of the recording with ``t_start <= t < t_stop`` (absolute times, us); it keeps the
        recording's origin, so that its times read as they did in the whole."""
        sl, sr = time_slice(self.left, t_start, t_stop), time_slice(self.right, t_start, t_stop)
        return Recording(
            self.left[sl], self.right[sr],
            None if self.left_disparity is None else self.left_disparity[sl],
            None if self.right_disparity is None else self.right_disparity[sr],
            self.resolution, {**self.meta, ORIGIN_KEY: self.origin_us},
        )

    def swapped(self) -> Recording:
        """The same recording with the cameras exchanged (truth negated, so that it stays x_left - x_right)."""
        return Recording(
            self.right, self.left,
            None if self.right_disparity is None else -self.right_disparity,
            None if self.left_disparity is None else -self.left_disparity,
            self.resolution, dict(self.meta),
        )
