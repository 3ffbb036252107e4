"""What every suite's recordings and suites share: a recording made from a recipe, cached under its name.

A recipe is a scene, a rig, a length, a seed and a render rate, with a label (what the recording's meta says
under ``suite``). Its cache name hashes everything that determines the events, so that a changed recipe or
generator never reuses a stale file. :mod:`cvstereo.simulate.suite` (the one-factor suite v1) and
:mod:`cvstereo.simulate.generalization` (the scene families of suite v2) build their recordings on it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass

from cvstereo.model.recording import Recording
from cvstereo.simulate.core import GENERATOR_VERSION, simulate

__all__ = ["Recipe", "Suite"]


class Recipe:
    """A suite recording's generation: needs ``suite``, ``name``, ``scene``, ``rig``, ``seconds``, ``seed``,
    ``render_hz`` and a ``label()`` (a JSON-serialisable dict)."""

    @property
    def max_disparity(self) -> int:
        """Disparity range a matcher needs on this sensor: 64 px at 128 wide, scaled with the width."""
        return round(64 * self.rig.resolution[0] / 128)

    def label(self) -> dict:
        raise NotImplementedError

    def describe(self) -> dict:
        """Everything that determines the events (for the cache key)."""
        return {"label": self.label(), "scene": self.scene.describe(), "rig": self.rig.describe(),
                "seconds": self.seconds, "seed": self.seed, "render_hz": self.render_hz,
                "generator_version": GENERATOR_VERSION}

    def cache_name(self) -> str:
        """File name in the cache: suite, name, length, seed, generator version and a parameter hash."""
        digest = hashlib.sha256(json.dumps(self.describe(), sort_keys=True, default=str).encode()).hexdigest()[:10]
        return f"{self.suite}_{self.name}_{self.seconds:g}s_seed{self.seed}_v{GENERATOR_VERSION}_{digest}.npz"

    def simulate(self, *, progress: bool = False) -> Recording:
        """Generate the recording; its meta carries :meth:`label` under ``suite``."""
        rec = simulate(self.scene, rig=self.rig, seconds=self.seconds, seed=self.seed, render_hz=self.render_hz,
                       progress=progress)
        return dataclasses.replace(rec, meta={**rec.meta, "suite": self.label()})


@dataclass(frozen=True)
class Suite:
    """A suite as loaded from its file: name, version, base preset (suite v1; empty otherwise) and the
    recordings in order."""

    name: str
    version: int
    base: str
    seconds: float
    recordings: tuple
    description: str = ""

    def items(self) -> list[tuple[str, Recipe]]:
        """(name, recording) pairs in the suite's order."""
        return [(r.name, r) for r in self.recordings]

    def __getitem__(self, name: str) -> Recipe:
        for r in self.recordings:
            if r.name == name:
                return r
        raise KeyError(f"suite '{self.name}' has no recording '{name}'.")
