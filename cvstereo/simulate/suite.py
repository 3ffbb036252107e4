"""Recording suites: named lists of simulated recordings, committed as data, generated once and cached.

A suite file (TOML, in ``cvstereo/simulate/suites/``) of the robustness suite v1 names a base preset, a length
and a seed, and lists recordings; each sets some *factors* (:data:`FACTORS`) away from the base, and may change
the scene (``scene = "fan"``). A recording that sets one factor is labelled with it (``factor``, ``value``); one
that sets several is a ``joint`` draw. A file with ``[families]`` is a suite of scene families with a tuning and
an evaluation half (the generalization suite v2, :mod:`cvstereo.simulate.generalization`).
:func:`suite_recordings` generates each recording on first use into the preset cache
(:func:`~cvstereo.simulate.presets.default_cache_dir`), under a key of suite, name, length, seed, generator
version and a hash of the parameters, and returns the paths in the suite's order; :func:`tuning_recordings`
only the tuning half's, and :func:`require_tuning` refuses any recording of an evaluation half.

>>> [name for name, _ in load_suite("robustness").items()][:3]
['base', 'threshold-x0.5', 'threshold-x1.5']
"""

from __future__ import annotations

import dataclasses
import os
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from cvstereo.simulate.core import DEFAULT_RENDER_HZ, MAX_SECONDS
from cvstereo.simulate.fan import FanScene
from cvstereo.simulate.generalization import HALVES, EvaluationRecordingError, FamilySuite, parse_family_suite
from cvstereo.simulate.presets import _seeded, default_cache_dir, get_preset
from cvstereo.simulate.recipe import Recipe, Suite
from cvstereo.simulate.rig import SENSORS, Rig
from cvstereo.simulate.scenes import ArmsScene
from cvstereo.simulate.textures import SLEEVE_PATTERNS

__all__ = ["FACTORS", "JOINT_FACTORS", "SUITES", "SUITE_SCENES", "Factor", "SuiteRecording", "draw_joint",
           "load_suite", "parse_suite", "require_tuning", "suite_recordings", "tuning_recordings"]

#: Suite name -> its file in ``cvstereo/simulate/suites``.
SUITES: dict[str, str] = {"robustness": "robustness_v1.toml", "generalization": "generalization_v2.toml"}

#: The wall stays at least this far behind an arm moved back (the presets' wall is at 2.5 m).
_WALL_GAP_M = 1.5


def _sensors(rig: Rig, changes: dict) -> Rig:
    """The rig with the same fields of both sensor models changed."""
    return dataclasses.replace(rig, left=dataclasses.replace(rig.left, **changes),
                               right=dataclasses.replace(rig.right, **changes))


def _arms(scene, what: str) -> ArmsScene:
    if not isinstance(scene, ArmsScene):
        raise ValueError(f"factor {what} applies to the arms scene only, not to {type(scene).__name__}.")
    return scene


def _threshold(scene, rig, v):
    return scene, dataclasses.replace(rig, **{side: dataclasses.replace(
        getattr(rig, side), on_threshold=getattr(rig, side).on_threshold * v,
        off_threshold=getattr(rig, side).off_threshold * v) for side in ("left", "right")})


def _distance(scene, rig, v):
    scene = _arms(scene, "distance_m")
    return dataclasses.replace(scene, distance_m=v, background_m=max(scene.background_m, v + _WALL_GAP_M)), rig


def _sensor(scene, rig, v):
    return scene, rig.for_sensor(tuple(int(n) for n in v.split("x")))


@dataclass(frozen=True)
class Factor:
    """One way a suite recording differs from its base: how it applies and which values it takes.

    Attributes
    ----------
    apply : callable
        ``apply(scene, rig, value) -> (scene, rig)``.
    low, high : float or None
        Range of a numeric factor (inclusive); None for a factor with ``choices``.
    choices : tuple of str
    log : bool
        Joint draws take this factor log-uniform in its range (a scale), else uniform.
    doc : str
    """

    apply: Callable
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    log: bool = False
    doc: str = ""

    def check(self, name: str, value, where: str):
        """The value, or a ValueError naming the factor, the place and the allowed range."""
        if self.choices:
            if value not in self.choices:
                raise ValueError(f"{where}: {name} must be one of {', '.join(self.choices)}, got {value!r}.")
            return value
        if isinstance(value, bool) or not isinstance(value, int | float) or not self.low <= value <= self.high:
            raise ValueError(f"{where}: {name} must be a number in [{self.low:g}, {self.high:g}], got {value!r}.")
        return float(value)


#: Factor name -> Factor. Thresholds, noise and jitter act on both sensors; speed, texture and distance on
#: the arm; the sensor size scales the focal length with the width (:meth:`Rig.for_sensor`).
FACTORS: dict[str, Factor] = {
    "threshold_scale": Factor(_threshold, 0.5, 3.0, log=True,
                              doc="both sensors' ON and OFF contrast thresholds times this"),
    "noise_hz": Factor(lambda s, r, v: (s, _sensors(r, {"noise_rate_hz": v})), 0.05, 1.0, log=True,
                       doc="background activity of both sensors, events per second per pixel"),
    "jitter_ms": Factor(lambda s, r, v: (s, _sensors(r, {"jitter_us": 1000.0 * v})), 0.0, 1.0,
                        doc="standard deviation of both sensors' timestamp jitter, ms"),
    "speed_scale": Factor(lambda s, r, v: (dataclasses.replace(_arms(s, "speed_scale"),
                                                               sweep_period_s=s.sweep_period_s / v), r),
                          0.5, 2.0, log=True, doc="the arm's sweep speed times this"),
    "texture": Factor(lambda s, r, v: (dataclasses.replace(_arms(s, "texture"), sleeve_pattern=v), r),
                      choices=SLEEVE_PATTERNS, doc="the sleeve's pattern (textures.SLEEVE_PATTERNS)"),
    "distance_m": Factor(_distance, 0.3, 3.0, log=True,
                         doc="the arm's distance (the wall moves back to stay 1.5 m behind it)"),
    "sensor": Factor(_sensor, choices=SENSORS, doc="sensor size; focal length and offsets scale with the width"),
    "time_offset_ms": Factor(lambda s, r, v: (s, dataclasses.replace(r, time_offset_us=1000.0 * v)), -20.0, 20.0,
                             doc="how much later the right camera stamps the same change (negative: early)"),
}

#: Factors of the joint random draws (not the clock offset: one recording tests it on its own).
JOINT_FACTORS = ("threshold_scale", "noise_hz", "jitter_ms", "speed_scale", "texture", "distance_m", "sensor")

#: Scenes a suite recording may replace the base preset's arms with.
SUITE_SCENES = {"fan": FanScene}


def draw_joint(seed: int) -> dict:
    """One joint random draw of :data:`JOINT_FACTORS` (how the suite file's ``joint-*`` entries were made).

    Scales log-uniform in their range, the jitter uniform, texture and sensor uniform over their choices;
    numbers rounded to 3 significant digits.
    """
    rng = np.random.default_rng([0x12, seed])
    out = {}
    for name in JOINT_FACTORS:
        f = FACTORS[name]
        if f.choices:
            out[name] = f.choices[int(rng.integers(len(f.choices)))]
        else:
            u = rng.uniform()
            v = f.low * (f.high / f.low) ** u if f.log else f.low + (f.high - f.low) * u
            out[name] = float(f"{v:.3g}")
    return out


@dataclass(frozen=True)
class SuiteRecording(Recipe):
    """One recording of a suite: what to simulate, and its label (factor and value).

    Attributes
    ----------
    suite : str
    name : str
    factor : str
        The factor it sets, ``joint`` for several, ``base`` for none (``scene`` when only the scene changes).
    value : object
        The factor's value (a dict for ``joint``, the scene's name for ``scene``, None for ``base``).
    settings : dict
        Factor name -> value.
    scene : scene object
    rig : Rig
    seconds : float
    seed : int
    render_hz : float
    """

    suite: str
    name: str
    factor: str
    value: object
    settings: dict
    scene: object
    rig: Rig
    seconds: float
    seed: int
    render_hz: float

    def label(self) -> dict:
        """What the recording's meta says under ``suite``."""
        out = {"name": self.suite, "recording": self.name, "factor": self.factor, "value": self.value,
               "settings": self.settings, "max_disparity": self.max_disparity}
        if isinstance(self.scene, FanScene):
            ideal = self.rig.focal_px * self.rig.baseline_m / self.scene.distance_m - self.rig.axis_offset_px
            out.update(blade_period_s=self.scene.blade_period_s, fan_disparity_px=ideal)
        return out


def _suite_text(name: str) -> tuple[str, str]:
    if name not in SUITES:
        raise ValueError(f"no suite '{name}'; choose one of {', '.join(SUITES)}.")
    res = resources.files("cvstereo.simulate").joinpath("suites", SUITES[name])
    return res.read_text(encoding="utf-8"), SUITES[name]


def load_suite(name: str, *, seconds: float | None = None) -> Suite:
    """Read a suite's file and build its recordings.

    Parameters
    ----------
    name : str
        One of :data:`SUITES`.
    seconds : float or None, keyword-only
        Length of every recording instead of the suite's (short clips for tests).

    Raises
    ------
    ValueError
        Unknown suite; a malformed entry (named by its index and name), an unknown factor or a value out of
        its range.
    """
    text, filename = _suite_text(name)
    data = tomllib.loads(text)
    if "families" in data:
        return parse_family_suite(data, where=filename, seconds=seconds)
    return parse_suite(data, where=filename, seconds=seconds)


def parse_suite(data: dict, *, where: str = "suite", seconds: float | None = None) -> Suite:
    """Build a :class:`Suite` from the parsed TOML of a suite file (see :func:`load_suite`)."""
    try:
        name, version, base = str(data["name"]), int(data["version"]), str(data["base_preset"])
        length = float(data["seconds"] if seconds is None else seconds)
        seed = int(data.get("seed", 0))
        entries = data["recording"]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: needs name, version, base_preset, seconds and [[recording]] entries ({exc}).") \
            from None
    if not 0 < length <= MAX_SECONDS:
        raise ValueError(f"{where}: seconds must lie in (0, {MAX_SECONDS:g}], got {length}.")
    preset = get_preset(base)
    recordings, names = [], set()
    for i, entry in enumerate(entries):
        here = f"{where}, recording {i} ({entry.get('name', '?')})"
        rec_name = entry.get("name")
        if not isinstance(rec_name, str) or not rec_name or rec_name in names:
            raise ValueError(f"{here}: every recording needs a unique name.")
        names.add(rec_name)
        unknown = sorted(set(entry) - {"name", "set", "scene", "seed", "note"})
        if unknown:
            raise ValueError(f"{here}: unknown key(s) {', '.join(unknown)}; allowed: name, set, scene, seed, note.")
        if not isinstance(entry.get("set", {}), dict):
            raise ValueError(f"{here}: 'set' must be a table of factor = value, e.g. set = {{ noise_hz = 0.5 }}.")
        settings = dict(entry.get("set", {}))
        rec_seed = int(entry.get("seed", seed))
        scene, render_hz = _seeded(preset.scene, rec_seed), DEFAULT_RENDER_HZ
        if "scene" in entry:
            if entry["scene"] not in SUITE_SCENES:
                raise ValueError(f"{here}: scene must be one of {', '.join(SUITE_SCENES)}, got {entry['scene']!r}.")
            scene = SUITE_SCENES[entry["scene"]](seed=rec_seed)
            render_hz = float(getattr(scene, "render_hz", DEFAULT_RENDER_HZ))
        rig = preset.rig
        for factor, value in settings.items():
            if factor not in FACTORS:
                raise ValueError(f"{here}: unknown factor '{factor}'; choose one of {', '.join(FACTORS)}.")
            settings[factor] = FACTORS[factor].check(factor, value, here)
            try:
                scene, rig = FACTORS[factor].apply(scene, rig, settings[factor])
            except ValueError as exc:
                raise ValueError(f"{here}: {exc}") from None
        if len(settings) == 1:
            factor, value = next(iter(settings.items()))
        elif settings:
            factor, value = "joint", settings
        elif "scene" in entry:
            factor, value = "scene", entry["scene"]
        else:
            factor, value = "base", None
        recordings.append(SuiteRecording(name, rec_name, factor, value, settings, scene, rig, length, rec_seed,
                                         render_hz))
    return Suite(name, version, base, length, tuple(recordings), str(data.get("description", "")))


def suite_recordings(name: str = "robustness", *, seconds: float | None = None, half: str | None = None,
                     cache_dir: str | os.PathLike | None = None, only: list[str] | None = None,
                     progress: bool = False, on_generate: Callable[[Recipe, Path, float], None] | None = None
                     ) -> list[tuple[str, Path]]:
    """The recordings of a suite, in order, as ``(name, path)``; each generated once into the cache.

    Parameters
    ----------
    name : str
        One of :data:`SUITES`.
    seconds : float or None, keyword-only
        Length of every recording (None: the suite's).
    half : {"tune", "eval"} or None, keyword-only
        Only this half's recordings (suites of scene families); None: all.
    cache_dir : path-like or None, keyword-only
        Folder; default :func:`~cvstereo.simulate.presets.default_cache_dir`.
    only : list of str or None, keyword-only
        Names of the recordings to return (in the suite's order); None: all.
    progress : bool, keyword-only
        Progress bars on stderr while generating.
    on_generate : callable or None, keyword-only
        Called as ``on_generate(recording, path, seconds_taken)`` after each recording is generated.

    Returns
    -------
    list of (str, pathlib.Path)
        Read a path with :func:`cvstereo.io.npz.read_recording_npz`.

    Raises
    ------
    ValueError
        Unknown suite or recording name; a half that is not ``tune`` or ``eval``, or one asked of a suite
        without halves.

    Examples
    --------
    >>> from cvstereo.io.npz import read_recording_npz
    >>> for name, path in suite_recordings("robustness", seconds=0.3):  # doctest: +SKIP
    ...     rec = read_recording_npz(path)
    """
    import time

    from cvstereo.io.npz import write_recording_npz

    suite = load_suite(name, seconds=seconds)
    recordings = list(suite.recordings)
    if half is not None:
        if half not in HALVES:
            raise ValueError(f"suite '{name}': half must be one of {', '.join(HALVES)}, got {half!r}.")
        if not isinstance(suite, FamilySuite):
            halved = [n for n in SUITES if "families" in tomllib.loads(_suite_text(n)[0])]
            raise ValueError(f"suite '{name}' has no tuning and evaluation halves (take it whole: "
                             f"suite:{name}); {', '.join(halved)} {'has' if len(halved) == 1 else 'have'} them.")
        recordings = [r for r in recordings if r.half == half]
    if only is not None:
        missing = sorted(set(only) - {r.name for r in recordings})
        if missing:
            raise ValueError(f"suite '{name}'{f' ({half} half)' if half else ''} has no recording "
                             f"{', '.join(missing)}; it has {', '.join(r.name for r in recordings)}.")
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    out = []
    for rec in recordings:
        if only is not None and rec.name not in only:
            continue
        path = folder / rec.cache_name()
        if not path.exists():
            folder.mkdir(parents=True, exist_ok=True)
            start = time.perf_counter()
            write_recording_npz(path, rec.simulate(progress=progress))
            if on_generate is not None:
                on_generate(rec, path, time.perf_counter() - start)
        out.append((rec.name, path))
    return out


def tuning_recordings(name: str = "generalization", **kwargs) -> list[tuple[str, Path]]:
    """The tuning half of a suite with halves: what a tuning script may see (:func:`suite_recordings` with
    ``half="tune"``; the other keywords as there)."""
    return suite_recordings(name, half="tune", **kwargs)


def require_tuning(recording) -> None:
    """Refuse a recording of an evaluation half: tuning code calls this on every recording it is given.

    What is tuned on the evaluation half is no longer scored on scenes it has not seen (issue 24). Recordings
    without a half (real ones, suite v1's, the presets) pass.

    Parameters
    ----------
    recording : path-like, Recording or suite recording
        A recording file (``.npz``: only its meta is read), a :class:`~cvstereo.model.recording.Recording` or an entry
        of a loaded suite.

    Raises
    ------
    EvaluationRecordingError
        (a ValueError) naming the recording, its suite and half, and what to use instead.

    Examples
    --------
    >>> eval_half = [r for r in load_suite("generalization").recordings if r.half == "eval"]
    >>> require_tuning(eval_half[0])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    cvstereo.simulate.generalization.EvaluationRecordingError: objects-eval-128x128 (suite generalization) ...
    """
    where = None
    if isinstance(recording, Recipe):
        label = recording.label()
    elif hasattr(recording, "meta"):
        label = recording.meta.get("suite") or {}
    else:
        from cvstereo.io.npz import read_npz_header

        where = os.fspath(recording)
        label = read_npz_header(where)[1].get("suite") or {} if where.endswith(".npz") else {}
    if label.get("half") == "tune" or "half" not in label:
        return
    name = f"{label.get('recording', '?')} (suite {label.get('name', '?')})"
    raise EvaluationRecordingError(
        f"{name}{f' in {where}' if where else ''} belongs to the {label['half']} half, which tuning must never see;"
        f" tune on tuning_recordings('{label.get('name', 'generalization')}') (sweep: "
        f"suite:{label.get('name', 'generalization')}:tune)")
