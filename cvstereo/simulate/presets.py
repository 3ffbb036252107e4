"""The thesis' six recordings re-created, and a cache that generates each preset once.

``1arm-50cm`` ... ``2arms-150cm``: one or two arms moving through the view at 50, 100 or 150 cm for 11 s,
seen by the thesis' rig. Their parameters are tuned (with ``bench/bench_simulate.py``) so that each camera
gives within 25 % of the events of the thesis' table 4.1 (left = its eDVS2, right = eDVS1), noise stays
below a quarter of the events, and the arms' mean true disparity lies where the thesis measured it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from cvstereo.model.recording import Recording
from cvstereo.simulate.core import GENERATOR_VERSION, simulate
from cvstereo.simulate.rig import Rig
from cvstereo.simulate.scenes import ArmsScene

__all__ = ["PRESETS", "Preset", "cache_key", "cached_preset", "default_cache_dir", "get_preset", "simulate_preset"]


@dataclass(frozen=True)
class Preset:
    """A named scene with a rig and a length, and what the thesis measured on its recording.

    Parameters
    ----------
    name : str
    scene : scene object
    rig : Rig
    seconds : float
        Length of the thesis' recording.
    thesis_events : dict
        ``{"left": (on, off), "right": (on, off)}`` from table 4.1 (left = eDVS2, right = eDVS1).
    thesis_disparity : (float, float)
        Range of the mean disparities the thesis' matchers found (px).
    """

    name: str
    scene: object
    rig: Rig = field(default_factory=Rig)
    seconds: float = 11.0
    thesis_events: dict = field(default_factory=dict)
    thesis_disparity: tuple[float, float] = (0.0, 0.0)

    def describe(self) -> dict:
        return {"name": self.name, "seconds": self.seconds, "scene": self.scene.describe(),
                "rig": self.rig.describe()}


# Table 4.1 of the thesis (eDVS1 on/off, eDVS2 on/off), and the disparity its matchers found.
_THESIS = {
    (1, 50): ((199146, 176505), (160854, 133498), (28.0, 30.0)),
    (1, 100): ((93221, 79848), (77250, 61010), (13.0, 14.0)),
    (1, 150): ((52178, 45655), (43006, 35298), (7.0, 8.0)),
    (2, 50): ((323125, 288549), (308605, 261931), (28.0, 30.0)),
    (2, 100): ((174696, 149009), (158456, 128643), (13.0, 14.0)),
    (2, 150): ((77733, 64721), (72342, 56745), (7.0, 8.0)),
}

# Sweep period (s) and shirt contrast per recording, tuned against table 4.1 with bench/bench_simulate.py.
# The event rate grows with the arm's speed in pixels and with the shirt's contrast in pixels. An arm further
# away shows its texture at a finer scale in pixels, so at a constant sweep the counts would rise with the
# distance, while the thesis' fall (to about a quarter from 50 to 150 cm). The tuned arms move slower further
# away (peak 0.54 m/s at 50 cm, 0.36 at 100 cm, 0.28 at 150 cm) and the shirt's contrast is lower there (as
# if the lenses, focused for the near range, lost its fine texture).
_TUNING = {
    (1, 50): dict(sweep_period_s=1.8, sleeve_contrast=0.35),
    (1, 100): dict(sweep_period_s=5.4, sleeve_contrast=0.20),
    (1, 150): dict(sweep_period_s=10.5, sleeve_contrast=0.18),
    (2, 50): dict(sweep_period_s=1.55, sleeve_contrast=0.35),
    (2, 100): dict(sweep_period_s=4.1, sleeve_contrast=0.20),
    (2, 150): dict(sweep_period_s=8.8, sleeve_contrast=0.18),
}


def _make_presets() -> dict[str, Preset]:
    presets = {}
    for (arms, cm), (edvs1, edvs2, disparity) in _THESIS.items():
        name = f"{arms}arm{'s' if arms > 1 else ''}-{cm}cm"
        presets[name] = Preset(
            name=name,
            scene=ArmsScene(arms=arms, distance_m=cm / 100, **_TUNING[arms, cm]),
            thesis_events={"left": edvs2, "right": edvs1},
            thesis_disparity=disparity,
        )
    return presets


#: Name -> Preset, in the thesis' order.
PRESETS: dict[str, Preset] = _make_presets()


def get_preset(name: str) -> Preset:
    """The preset called ``name``; a ValueError lists the names when there is none."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"no preset '{name}'; choose one of {', '.join(PRESETS)}.") from None


def simulate_preset(name: str, *, seconds: float | None = None, seed: int = 0, progress: bool = False) -> Recording:
    """Simulate a preset (by default for its full length, 11 s).

    Parameters
    ----------
    name : str
        One of :data:`PRESETS`.
    seconds : float or None, keyword-only
        Length; None: the preset's (the first ``seconds`` of the full recording, the same scene motion).
    seed : int, keyword-only
        Seeds the sensors (mismatch, noise, jitter) and the scene (textures, motion phases).
    progress : bool, keyword-only
        Progress bar on stderr.

    Returns
    -------
    Recording
        With ``meta["preset"]`` set to the name.
    """
    preset = get_preset(name)
    scene = _seeded(preset.scene, seed)
    rec = simulate(scene, rig=preset.rig, seconds=preset.seconds if seconds is None else seconds, seed=seed,
                   progress=progress)
    return dataclasses.replace(rec, meta={**rec.meta, "preset": name})


def _seeded(scene, seed: int):
    return dataclasses.replace(scene, seed=seed) if hasattr(scene, "seed") else scene


def default_cache_dir() -> Path:
    """Where :func:`cached_preset` keeps recordings: ``$CVSTEREO_CACHE``, else ``<repo>/.cache/presets`` in a
    source checkout, else ``~/.cache/cvstereo/presets``."""
    env = os.environ.get("CVSTEREO_CACHE")
    if env:
        return Path(env)
    repo = Path(__file__).resolve().parents[2]
    if (repo / "pyproject.toml").exists():
        return repo / ".cache" / "presets"
    return Path.home() / ".cache" / "cvstereo" / "presets"


def cache_key(name: str, *, seconds: float | None = None, seed: int = 0) -> str:
    """File name of a cached preset: name, length, seed, generator version and a hash of the parameters,
    so that a retuned preset or a changed generator never reuses a stale file."""
    preset = get_preset(name)
    seconds = preset.seconds if seconds is None else float(seconds)
    digest = hashlib.sha256(json.dumps(preset.describe(), sort_keys=True, default=str).encode()).hexdigest()[:10]
    return f"{name}_{seconds:g}s_seed{seed}_v{GENERATOR_VERSION}_{digest}.npz"


def cached_preset(name: str, *, seconds: float | None = None, seed: int = 0, cache_dir: str | os.PathLike | None = None,
                  progress: bool = False) -> Path:
    """Path of a preset's recording ``.npz``, generated on first use and kept for later calls.

    Parameters
    ----------
    name : str
        One of :data:`PRESETS`.
    seconds : float or None, keyword-only
        Length (None: the preset's 11 s). Tests use short clips, e.g. ``seconds=2``.
    seed : int, keyword-only
    cache_dir : path-like or None, keyword-only
        Folder; default :func:`default_cache_dir`.
    progress : bool, keyword-only

    Returns
    -------
    pathlib.Path
        Read it with :func:`cvstereo.io.npz.read_recording_npz`.

    Examples
    --------
    >>> from cvstereo.io.npz import read_recording_npz
    >>> rec = read_recording_npz(cached_preset("1arm-100cm", seconds=0.2))  # doctest: +SKIP
    """
    from cvstereo.io.npz import write_recording_npz

    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = folder / cache_key(name, seconds=seconds, seed=seed)
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        write_recording_npz(path, simulate_preset(name, seconds=seconds, seed=seed, progress=progress))
    return path
