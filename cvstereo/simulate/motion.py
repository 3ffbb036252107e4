"""How a scene's layers move: a position as a sum of sinusoids of time, vectorised over instants."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Motion"]


@dataclass(frozen=True)
class Motion:
    """A smooth path: a centre, a constant velocity and a sum of sinusoids per axis.

    ``position(t) = center + velocity * t + sum(amplitude * sin(2*pi*t / period + phase) * e_axis)``.

    Parameters
    ----------
    center : tuple of float
        Position at t = 0 without the sinusoids (metres, or radians for an angle).
    velocity : tuple of float
        Per second.
    terms : tuple of (axis, amplitude, period_s, phase) tuples
    """

    center: tuple[float, ...] = (0.0, 0.0, 0.0)
    velocity: tuple[float, ...] | None = None
    terms: tuple[tuple[int, float, float, float], ...] = ()

    def position(self, times_s: np.ndarray) -> np.ndarray:
        """(T, D) positions at the instants ``times_s`` (T,), D = len(center)."""
        t = np.asarray(times_s, np.float64)[:, None]
        pos = np.asarray(self.center, np.float64)[None, :] + 0 * t
        if self.velocity is not None:
            pos = pos + np.asarray(self.velocity, np.float64)[None, :] * t
        for axis, amplitude, period, phase in self.terms:
            pos[:, axis] += amplitude * np.sin(2 * np.pi * t[:, 0] / period + phase)
        return pos

    @property
    def is_static(self) -> bool:
        """True when the position never changes."""
        return (self.velocity is None or not any(self.velocity)) and not any(term[1] for term in self.terms)

    def describe(self) -> dict:
        return {"center": list(self.center), "velocity": None if self.velocity is None else list(self.velocity),
                "terms": [list(term) for term in self.terms]}
