"""The generalization suite (suite v2): scene families, sensors and rigs drawn per recording, two halves.

Its file (``suites/generalization_v2.toml``) lists the families, which photos belong to which half, the
ranges every recording's sensors and rig are drawn from (``[draw]``), and the recordings: name, family, half
(``tune`` or ``eval``), seed, sensor size and the photos it may show. From its seed a recording draws the two
sensor models (each camera its own: thresholds, mismatch, refractory period, noise, hot pixels, jitter), the
rig's imperfections (clock offset, row offset, axis offset, roll, focal mismatch, each lens' distortion) and
how far the fastest image motion moves between two renders (:func:`draw`); its family draws the scene
(:mod:`cvstereo.simulate.families`).

The halves share neither a seed nor a photo (:func:`parse_family_suite` refuses a file where they would):
what is tuned on the ``tune`` half is scored on scenes it never saw. Tuning code takes its recordings from
:func:`cvstereo.simulate.suite.tuning_recordings` and checks any other with
:func:`cvstereo.simulate.suite.require_tuning`.

>>> from cvstereo.simulate.suite import load_suite
>>> suite = load_suite("generalization")
>>> sorted({r.half for r in suite.recordings}), len(suite.families)
(['eval', 'tune'], 6)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from cvstereo.simulate.core import MAX_SECONDS
from cvstereo.simulate.families import FAMILIES, FamilyScene
from cvstereo.simulate.recipe import Recipe, Suite
from cvstereo.simulate.rig import SENSORS, Rig, SensorModel
from cvstereo.simulate.surfaces import PHOTOS

__all__ = ["HALVES", "RENDER_DRAWS", "RENDER_HZ_RANGE", "RIG_DRAWS", "SENSOR_DRAWS", "TRUTH",
           "EvaluationRecordingError", "FamilyRecording", "FamilySuite", "draw", "parse_family_suite"]

#: The two halves of every family: tuning may see the first only.
HALVES = ("tune", "eval")

#: Fields of each camera's :class:`~cvstereo.simulate.rig.SensorModel` drawn per recording, in drawing order.
SENSOR_DRAWS = ("on_threshold", "off_threshold", "threshold_mismatch", "refractory_us", "noise_rate_hz",
                "hot_pixel_fraction", "hot_pixel_rate_hz", "jitter_us")
#: Fields of the :class:`~cvstereo.simulate.rig.Rig` drawn per recording, in drawing order; ``distortion_k1`` is
#: drawn for each lens.
RIG_DRAWS = ("time_offset_us", "vertical_offset_px", "axis_offset_px", "roll_deg", "focal_ratio", "distortion_k1")
#: Rig fields in pixels: their ranges hold at 128 px across and scale with the sensor's width (same optics).
_PER_WIDTH = ("vertical_offset_px", "axis_offset_px")
#: How far the fastest image motion moves between two renders (px): above one pixel, edges jump between renders
#: and the events' linear interpolation shows it.
RENDER_DRAWS = ("render_step_px",)
#: Render rates (Hz) a drawn step is held within: the slowest scenes are still rendered often enough for their
#: sinusoidal motions, the fastest are not rendered needlessly finely.
RENDER_HZ_RANGE = (25.0, 2000.0)
#: Significant digits of the drawn values (the meta lists them; rounding makes them readable).
_DIGITS = 4

#: The truth, as the recordings' label states it.
TRUTH = ("x_left - x_right of where the scene point lands in the two recorded (distorted, misaligned) images, "
         "sub-pixel; its row in the other image (row offset, roll) is not part of it; NaN for noise and hot pixels")


class EvaluationRecordingError(ValueError):
    """A recording of an evaluation half where only tuning recordings may go."""


@dataclass(frozen=True)
class FamilyRecording(Recipe):
    """One recording of the generalization suite: its family and half, what was drawn, how to simulate it.

    Attributes
    ----------
    suite, name, family, half : str
    seed : int
    photos : tuple of str
    scene : FamilyScene
    rig : Rig
    seconds, render_hz : float
    drawn : dict
        The drawn values: ``left`` and ``right`` (sensor fields), ``rig``, ``render_step_px``.
    """

    suite: str
    name: str
    family: str
    half: str
    seed: int
    photos: tuple[str, ...]
    scene: FamilyScene
    rig: Rig
    seconds: float
    render_hz: float
    drawn: dict

    def label(self) -> dict:
        """What the recording's meta says under ``suite``."""
        w, h = self.rig.resolution
        return {"name": self.suite, "recording": self.name, "family": self.family, "half": self.half,
                "seed": self.seed, "sensor": f"{w}x{h}", "photos": list(self.photos),
                "max_disparity": self.max_disparity, "render_hz": self.render_hz, "drawn": self.drawn,
                "truth": TRUTH}

    def summary(self) -> str:
        """One line: family, half, sensor, the drawn sensors and rig, the render rate and the photos."""
        left, right, rig = self.drawn["left"], self.drawn["right"], self.drawn["rig"]

        def both(name, fmt="{:g}"):
            return f"{fmt.format(left[name])}/{fmt.format(right[name])}"

        w, h = self.rig.resolution
        return (f"{self.family:10s} {self.half:4s} {w}x{h}  ON {both('on_threshold')} OFF {both('off_threshold')} "
                f"mismatch {both('threshold_mismatch')} refractory {both('refractory_us', '{:.0f}')} us "
                f"noise {both('noise_rate_hz', '{:.2f}')} Hz hot {both('hot_pixel_fraction', '{:.1e}')} at "
                f"{both('hot_pixel_rate_hz', '{:.0f}')} Hz jitter {both('jitter_us', '{:.0f}')} us; "
                f"clock {rig['time_offset_us']:.0f} us rows {rig['vertical_offset_px']:g} c {rig['axis_offset_px']:g} "
                f"roll {rig['roll_deg']:g} deg focal x{rig['focal_ratio']:g} k1 {rig['distortion_k1']:g}/"
                f"{rig['right_distortion_k1']:g}; render {self.render_hz:g} Hz; "
                f"photos {', '.join(self.photos) or '-'}")


@dataclass(frozen=True)
class FamilySuite(Suite):
    """A suite of scene families: :class:`~cvstereo.simulate.recipe.Suite` with the families' descriptions, the
    photos of each half and the ranges of the draws."""

    families: dict = field(default_factory=dict)
    photos: dict = field(default_factory=dict)
    ranges: dict = field(default_factory=dict)


def _round(value: float) -> float:
    return float(f"{value:.{_DIGITS}g}")


def draw(seed: int, ranges: dict, resolution: tuple[int, int]) -> tuple[Rig, float, dict]:
    """A recording's sensors, rig and render step, drawn from ``seed`` uniformly within ``ranges``.

    Parameters
    ----------
    seed : int
    ranges : dict
        Name -> (low, high) for every name of :data:`SENSOR_DRAWS`, :data:`RIG_DRAWS`, :data:`RENDER_DRAWS`.
    resolution : (width, height)

    Returns
    -------
    rig : Rig
        The thesis' optics on this sensor (:meth:`Rig.for_sensor`) with the drawn sensors and imperfections.
    render_step_px : float
    drawn : dict
        ``left``, ``right`` (sensor fields), ``rig`` (with ``distortion_k1`` and ``right_distortion_k1``) and
        ``render_step_px``, as drawn (rounded to 4 significant digits, as used).
    """
    rng = np.random.default_rng([0x24, seed])

    def one(name: str) -> float:
        lo, hi = ranges[name]
        return _round(lo + (hi - lo) * rng.uniform())

    drawn = {side: {name: one(name) for name in SENSOR_DRAWS} for side in ("left", "right")}
    drawn["rig"] = {name: one(name) for name in RIG_DRAWS}
    drawn["rig"]["right_distortion_k1"] = one("distortion_k1")
    drawn["render_step_px"] = one("render_step_px")
    scale = resolution[0] / 128
    rig = dataclasses.replace(
        Rig().for_sensor(resolution),
        **{name: value * scale if name in _PER_WIDTH else value for name, value in drawn["rig"].items()},
        left=dataclasses.replace(SensorModel(), **drawn["left"]),
        right=dataclasses.replace(SensorModel(), **drawn["right"]))
    return rig, drawn["render_step_px"], drawn


def _pair(value, what: str) -> tuple[float, float]:
    ok = (isinstance(value, list) and len(value) == 2
          and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value) and value[0] <= value[1])
    if not ok:
        raise ValueError(f"{what} must be a range [low, high] of two numbers, low <= high, got {value!r}.")
    return float(value[0]), float(value[1])


def _ranges(table, where: str) -> dict:
    if not isinstance(table, dict):
        raise ValueError(f"{where}: [draw] must be a table of name = [low, high].")
    names = (*SENSOR_DRAWS, *RIG_DRAWS, *RENDER_DRAWS)
    missing, unknown = [n for n in names if n not in table], sorted(set(table) - set(names))
    if missing or unknown:
        raise ValueError(f"{where}: [draw] needs exactly {', '.join(names)}; "
                         + (f"missing {', '.join(missing)}" if missing else f"unknown {', '.join(unknown)}") + ".")
    return {n: _pair(table[n], f"{where}: [draw] {n}") for n in names}


def _photo_halves(table, where: str) -> dict:
    if not isinstance(table, dict) or set(table) != set(HALVES):
        raise ValueError(f"{where}: [photos] must list the photos of each half: tune = [...] and eval = [...].")
    out = {}
    for half in HALVES:
        photos = table[half]
        bad = [p for p in photos if p not in PHOTOS] if isinstance(photos, list) else [repr(photos)]
        if bad:
            raise ValueError(f"{where}: [photos] {half}: unknown photo(s) {', '.join(map(str, bad))}; choose from "
                             f"{', '.join(PHOTOS)}.")
        out[half] = tuple(photos)
    both = sorted(set(out["tune"]) & set(out["eval"]))
    if both:
        raise ValueError(f"{where}: [photos]: {', '.join(both)} in both halves; a photo belongs to one half only.")
    return out


_ENTRY_KEYS = ("name", "family", "half", "seed", "sensor", "photos", "note")


def parse_family_suite(data: dict, *, where: str = "suite", seconds: float | None = None) -> FamilySuite:
    """Build a :class:`FamilySuite` from the parsed TOML of a families suite file (see the module doc).

    Raises
    ------
    ValueError
        A missing or malformed table; an entry (named by its index and name) with an unknown key, family, half
        or sensor, a duplicate name or seed, or a photo outside its half's list; a photo in both halves.
    """
    try:
        name, version = str(data["name"]), int(data["version"])
        length = float(data["seconds"] if seconds is None else seconds)
        families, entries = dict(data["families"]), list(data["recording"])
        photos, ranges = _photo_halves(data["photos"], where), _ranges(data["draw"], where)
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{where}: a families suite needs name, version, seconds, [families], [photos], [draw] "
                         f"and [[recording]] entries ({exc}).") from None
    if not 0 < length <= MAX_SECONDS:
        raise ValueError(f"{where}: seconds must lie in (0, {MAX_SECONDS:g}], got {length}.")
    unknown = sorted(set(families) - set(FAMILIES))
    if unknown:
        raise ValueError(f"{where}: [families] {', '.join(unknown)} unknown; choose from {', '.join(FAMILIES)}.")
    recordings, names, seeds = [], set(), {}
    for i, entry in enumerate(entries):
        here = f"{where}, recording {i} ({entry.get('name', '?') if isinstance(entry, dict) else '?'})"
        if not isinstance(entry, dict):
            raise ValueError(f"{here}: every recording is a table with {', '.join(_ENTRY_KEYS[:-1])}.")
        bad = sorted(set(entry) - set(_ENTRY_KEYS))
        missing = [k for k in _ENTRY_KEYS[:5] if k not in entry]
        if bad or missing:
            raise ValueError(f"{here}: " + (f"unknown key(s) {', '.join(bad)}" if bad else
                                            f"missing {', '.join(missing)}") + f"; keys: {', '.join(_ENTRY_KEYS)}.")
        rec_name, family, half, seed, sensor = (entry[k] for k in _ENTRY_KEYS[:5])
        rec_photos = entry.get("photos", [])
        if not isinstance(rec_name, str) or not rec_name or rec_name in names:
            raise ValueError(f"{here}: every recording needs a unique name.")
        if family not in families:
            raise ValueError(f"{here}: family must be one of {', '.join(families)}, got {family!r}.")
        if half not in HALVES:
            raise ValueError(f"{here}: half must be one of {', '.join(HALVES)}, got {half!r}.")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed in seeds:
            raise ValueError(f"{here}: seed must be a whole number no other recording has"
                             + (f" ({seeds[seed]} has {seed})." if seed in seeds else f", got {seed!r}."))
        if sensor not in SENSORS:
            raise ValueError(f"{here}: sensor must be one of {', '.join(SENSORS)}, got {sensor!r}.")
        if not isinstance(rec_photos, list) or any(p not in photos[half] for p in rec_photos):
            raise ValueError(f"{here}: photos must come from the {half} half's list ({', '.join(photos[half])}), "
                             f"got {rec_photos!r}.")
        names.add(rec_name)
        seeds[seed] = rec_name
        resolution = tuple(int(n) for n in sensor.split("x"))
        try:
            rig, step, drawn = draw(seed, ranges, resolution)
        except ValueError as exc:
            raise ValueError(f"{here}: {exc}") from None
        scene = FamilyScene(family, seed, resolution, rig.focal_px, length, tuple(rec_photos))
        render_hz = _round(float(np.clip(scene.plan.image_speed_px_s / step, *RENDER_HZ_RANGE)))
        recordings.append(FamilyRecording(name, rec_name, family, half, seed, tuple(rec_photos), scene, rig, length,
                                          render_hz, drawn))
    return FamilySuite(name, version, "", length, tuple(recordings), str(data.get("description", "")),
                       families=families, photos=photos, ranges=ranges)
