"""Stereo event simulator with per-event ground truth: the thesis' rig, arms, a turning rig, a real stereo pair.

>>> from cvstereo.simulate import simulate, ArmsScene, Rig
>>> rec = simulate(ArmsScene(arms=1, distance_m=1.0), rig=Rig(), seconds=0.05, seed=0)  # doctest: +SKIP
>>> rec.left_disparity  # x_left - x_right of the scene point behind each event, NaN for noise  # doctest: +SKIP

- :mod:`~cvstereo.simulate.rig`: rig geometry (baseline, focal length, barrel distortion, axis and vertical
  offsets, roll, focal mismatch) and the sensors' pixel models (thresholds, mismatch, refractory period, noise,
  hot pixels, jitter).
- :mod:`~cvstereo.simulate.scenes`: arms, the rotating rig in a room, the motorcycle pair, textured layers.
- :mod:`~cvstereo.simulate.render`, :mod:`~cvstereo.simulate.dvs`: rendering and event generation.
- :mod:`~cvstereo.simulate.fan`: a rotating fan (the real TUM recordings' scene).
- :mod:`~cvstereo.simulate.presets`: the thesis' six recordings and a cache (:func:`cached_preset`).
- :mod:`~cvstereo.simulate.suite`: suites of recordings committed as data (``suites/*.toml``), cached like
  the presets (:func:`suite_recordings`); the tuning guard (:func:`tuning_recordings`, :func:`require_tuning`).
- :mod:`~cvstereo.simulate.generalization`, :mod:`~cvstereo.simulate.families`,
  :mod:`~cvstereo.simulate.surfaces`: suite v2, its scene families and their textures.
"""

from cvstereo.simulate.core import DEFAULT_RENDER_HZ, GENERATOR_VERSION, MAX_SECONDS, simulate
from cvstereo.simulate.families import FAMILIES, FamilyScene
from cvstereo.simulate.fan import FAN_RENDER_HZ, FanScene
from cvstereo.simulate.presets import PRESETS, Preset, cached_preset, default_cache_dir, get_preset, simulate_preset
from cvstereo.simulate.rig import EDVS1_RIGHT, EDVS2_LEFT, Rig, SensorModel
from cvstereo.simulate.scenes import SCENES, ArmsScene, LayeredScene, Motion, MotorcycleScene, PlaneLayer, RotationScene
from cvstereo.simulate.suite import FACTORS, SUITES, load_suite, require_tuning, suite_recordings, tuning_recordings

__all__ = [
    "DEFAULT_RENDER_HZ", "EDVS1_RIGHT", "EDVS2_LEFT", "FACTORS", "FAMILIES", "FAN_RENDER_HZ", "GENERATOR_VERSION",
    "MAX_SECONDS", "PRESETS", "SCENES", "SUITES", "ArmsScene", "FamilyScene", "FanScene", "LayeredScene", "Motion",
    "MotorcycleScene", "PlaneLayer", "Preset", "Rig", "RotationScene", "SensorModel", "cached_preset",
    "default_cache_dir", "get_preset", "load_suite", "require_tuning", "simulate", "simulate_preset",
    "suite_recordings", "tuning_recordings",
]
