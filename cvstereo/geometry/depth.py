"""Disparity to distance without a calibration pattern: d = a / Z - c, with a = f*B.

Two or more recordings at measured distances (the thesis used a cord) fit ``a`` and ``c`` by least
squares; or they come from the rig (focal length in px, baseline in m, axis offset in px).

>>> model = fit_depth_model([0.5, 1.5], [29.0, 8.0])
>>> round(model.a, 3), round(model.c, 3)
(15.75, 2.5)
>>> round(float(model.distance(13.25)), 3)
1.0
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["DepthModel", "depth_from_meta", "fit_depth_model"]


@dataclass(frozen=True)
class DepthModel:
    """``d = a / Z - c``: disparity d (px) of a point at distance Z (m).

    Attributes
    ----------
    a : float
        f * B, px * m (focal length in px times baseline in m).
    c : float
        Offset in px from optical axes that are not exactly parallel.
    """

    a: float
    c: float = 0.0

    def __post_init__(self):
        # A zero, negative or infinite a gives "distance 0.00 m" (or nonsense) for every match: refuse it here,
        # where every model is made (--depth, a rig's meta, a fit).
        try:
            a, c = float(self.a), float(self.c)
        except (TypeError, ValueError):
            raise ValueError(f"depth model d = a/Z - c needs numbers, got a={self.a!r}, c={self.c!r}.") from None
        if not (np.isfinite(a) and a > 0):
            raise ValueError(f"depth model d = a/Z - c: a (focal length px x baseline m) must be a finite number "
                             f"> 0, got {a:g}.")
        if not np.isfinite(c):
            raise ValueError(f"depth model d = a/Z - c: c (px) must be a finite number, got {c:g}.")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "c", c)

    @classmethod
    def from_rig(cls, *, focal_px: float, baseline_m: float, offset_px: float = 0.0) -> DepthModel:
        """The model of a rig with known focal length, baseline and axis offset."""
        return cls(a=focal_px * baseline_m, c=offset_px)

    def disparity(self, distance_m):
        """Disparity in px at distance(s) Z in metres."""
        return self.a / np.asarray(distance_m, dtype=np.float64) - self.c

    def distance(self, disparity_px):
        """Distance in metres for disparity(ies) in px; inf where ``d + c <= 0`` (at or beyond infinity)."""
        d = np.asarray(disparity_px, dtype=np.float64) + self.c
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(d > 0, self.a / np.where(d > 0, d, 1.0), np.inf)

    def to_dict(self) -> dict:
        return {"a": self.a, "c": self.c}


def depth_from_meta(meta: Mapping) -> DepthModel | None:
    """The disparity-to-distance model a file's meta holds or implies, or None.

    Uses ``meta["depth"] = {"a": ..., "c": ...}`` when present (what `cvstereo match` stores), else the rig's
    ``focal_px`` and ``baseline_m`` (and ``axis_offset_px`` as c), as the simulator writes them.

    Raises
    ------
    ValueError, TypeError
        The values are not a valid model (:class:`DepthModel`).
    """
    depth = meta.get("depth")
    if isinstance(depth, Mapping) and "a" in depth:
        return DepthModel(a=float(depth["a"]), c=float(depth.get("c", 0.0)))
    rig = meta.get("rig")
    if isinstance(rig, Mapping) and "focal_px" in rig and "baseline_m" in rig and float(rig["baseline_m"]) > 0:
        return DepthModel.from_rig(focal_px=float(rig["focal_px"]), baseline_m=float(rig["baseline_m"]),
                                   offset_px=float(rig.get("axis_offset_px", rig.get("offset_px", 0.0))))
    return None


def fit_depth_model(distances_m, disparities_px, *, weights=None) -> DepthModel:
    """Least-squares fit of ``d = a / Z - c`` to disparities measured at known distances.

    Parameters
    ----------
    distances_m : (N,) array_like
        Measured distances, metres (N >= 2, at least two different values).
    disparities_px : (N,) array_like
        A disparity per distance, typically the median of a matcher's output on that recording.
    weights : (N,) array_like, optional
        Per-point weights (e.g. the number of matches).

    Returns
    -------
    DepthModel

    Raises
    ------
    ValueError
        Fewer than two distinct distances, non-positive distances, mismatched lengths, non-finite values, or
        disparities that do not shrink with distance (no model d = a/Z - c with a > 0 fits them).
    """
    z = np.asarray(distances_m, dtype=np.float64).ravel()
    d = np.asarray(disparities_px, dtype=np.float64).ravel()
    if z.shape != d.shape:
        raise ValueError(f"got {z.size} distances and {d.size} disparities; give one disparity per distance.")
    if not (np.isfinite(z).all() and np.isfinite(d).all()):
        raise ValueError("distances and disparities must be finite numbers.")
    if (z <= 0).any():
        raise ValueError(f"distances must be positive metres, got {z.tolist()}.")
    if np.unique(z).size < 2:
        raise ValueError("fitting a and c needs recordings at two or more different distances.")
    # Linear in (a, c): d = a * (1/Z) - c.
    design = np.column_stack([1.0 / z, -np.ones_like(z)])
    if np.ptp(d) == 0:
        raise ValueError(f"every disparity is {d[0]:g} px at every distance: distance cannot be told from "
                         "disparity; check the files and the distances given.")
    if weights is not None:
        w = np.sqrt(np.asarray(weights, dtype=np.float64).ravel())
        design, d = design * w[:, None], d * w
    (a, c), *_ = np.linalg.lstsq(design, d, rcond=None)
    if not a > 0:
        raise ValueError(f"the disparities grow with distance (fit: a = {a:.4g} <= 0); nearer objects must have "
                         "larger disparities: check the distances given (or the cameras are swapped).")
    return DepthModel(a=float(a), c=float(c))
