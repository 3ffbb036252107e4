"""The two parameter sets of the thesis matchers: ``adaptive`` (the default) and ``thesis``.

``thesis`` is docs/algorithms.md's constants and the thesis' default variants (each method's first): the matches are
those of the thesis' algorithms, bit for bit. ``adaptive`` keeps every step of each algorithm but expresses its
decision thresholds relative to the recording's own signal level (:mod:`cvstereo.matchers._shared.signal_level`), and
picks as
each method's default variant the one that does best on the density sweep and the real recordings.

The scales were tuned on the density sweep of issue 12 (``ArmsScene(arms=1, distance_m=1.0)``, 3 s, seed 7,
contrast thresholds x 0.5 ... 3) together with the real TUM recordings (Fan_disp8, NSTlogo, movingPersons),
never to one file. They lie below the thesis' threshold over the level of thesis-like data (e.g. 1.2 / 1.57 =
0.76 for the frame matcher on 1arm-100cm): at the thesis' density ``adaptive`` keeps more pixels at about the
same error. Besides the scales, ``adaptive`` adds checks that the thesis does not make (each a parameter field whose
thesis value switches it off), chosen so that its median bad2 over the robustness suite is at most the
thesis' while it covers more. Which fields and values, and why, is said once per method, in :data:`ADAPTIVE`
(its ``params`` and ``why``; ``cvstereo match --list-methods`` prints them). The rig check's time offset is NOT applied
by default: on Fan_disp8 it finds +0.01 ms at confidence 0.25 (no offset to apply), and forcing -3 ms or +3 ms
made every matcher worse under ``adaptive``; what cancelled the
fan's blades was ON and OFF events sharing one frame. A set gives the defaults; ``--param key=value`` overrides
any field, and a variant given explicitly wins over the set's default variant.

>>> resolve("frame", None, "adaptive")[0]
'separate'
>>> resolve("frame", "shared", "thesis")
('shared', {})
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["ADAPTIVE", "DEFAULT_PARAM_SET", "PARAM_SETS", "AdaptiveDefaults", "check_param_set", "default_variant",
           "resolve"]

#: The parameter sets, the default first.
PARAM_SETS = ("adaptive", "thesis")
DEFAULT_PARAM_SET = "adaptive"


@dataclass(frozen=True)
class AdaptiveDefaults:
    """What the ``adaptive`` set changes for one method.

    Attributes
    ----------
    variant : str
        The default variant under ``adaptive``.
    why : str
        Printed by ``--list-methods``: why that variant and those values (the before/after figures behind them are
        in bench/results/docstring-figures.md).
    params : dict
        Parameter values of the set (relative thresholds and their scales).
    variant_params : dict
        Extra values per variant (where a variant's values differ in kind, e.g. unfiltered frames).
    """

    variant: str
    why: str
    params: dict = field(default_factory=dict)
    variant_params: dict = field(default_factory=dict)


#: The border rule (:mod:`cvstereo.matchers._shared.border`) of every matcher under ``adaptive``: an accepted match
#: stays evidence for one 40 ms window, and the nearest 3 rows within 16 that hold evidence vote (the frame matcher
#: answers in a few rows a window: within 8 rows its 346x260 plane kept 2.6 % of its answers in the strip, within 16 0.9
#: %). On the border planes (a textured plane at an eighth of the width, 128x128 and 346x260, 1.5 s) it cut the answers
#: whose partner lies outside the other image from 1-9 % to 0.05-0.9 % of each matcher's answers (event-time at 346x260:
#: 1.1 %), costing 0.1-1.3 % of the correct ones.
_BORDER = {"border_horizon_us": 40_000, "border_rows": 16}

_RELATIVE = {"threshold_mode": "relative"}

#: What every thesis method gets under ``adaptive``: relative thresholds and the border rule.
_THESIS_METHODS = {**_RELATIVE, **_BORDER}

#: method -> what ``adaptive`` sets. The OpenCV baselines have no thresholds of the thesis' kind: ``adaptive``
#: gives them the border rule only. Methods not listed (dv-semidense, fused) are the same under both sets.
ADAPTIVE: dict[str, AdaptiveDefaults] = {
    "frame": AdaptiveDefaults(
        variant="separate",
        why="ON and OFF events in one frame cancel where both fall in a window (a fan's blades): on Fan_disp8 "
            "shared gave 631 estimates, 74 % within 1 px of 8, separate 8358, 99 %; separate also covered more "
            "of the density sweep (0.35 vs 0.23 at thresholds x3)",
        params={**_THESIS_METHODS, "threshold_scale": 0.42, "min_support": 3},
    ),
    "frame-area": AdaptiveDefaults(
        variant="gaussian",
        why="filtered frames give the SAD smooth blocks; unfiltered ones covered a third as much of the density "
            "sweep (0.09 vs 0.42 at x1) and were half as often right on Fan_disp8; adaptive matches OFF and ON "
            "frames apart (a fan's blades cancel in one frame) and "
            "keeps disparities the left-right check confirms; the no-gaussian variant has the same scale (the level "
            "is that of its own unfiltered values; at 1.6 x it kept 556 estimates on movingPersons against the thesis "
            "set's 4613, now 3720, of which 3670 within 1 px of 13: 111 % of the thesis set's 3320)",
        params={**_THESIS_METHODS, "threshold_scale": 0.6, "polarity": "separate", "lr_check": True},
    ),
    "event-time": AdaptiveDefaults(
        variant="separate",
        why="ON and OFF events cancel in a shared dynamic frame as in a shared frame: on Fan_disp8 separate "
            "frames gave 15932 estimates, 84 % within 1 px of 8, shared 2180, 73 % (when the variant was chosen, "
            "before the checks below); adaptive reads D1 after "
            "e1's update as D2 is read (reading it before put one event's weight between corresponding values: "
            "NSTlogo gave nothing) and lets the time window follow the events' pace (a fixed 300 us kept 20 % of "
            "the true partners at thresholds x1, 6 % at x3); where the recent matches within 4 px agree on "
            "another disparity it takes the candidate nearest theirs or none (consensus_radius: the nearest "
            "partner was a look-alike one texture period off in 10-12 % of the matches on 1arm-50cm; it cut bad2 "
            "there and made more cells agree when every second event is dropped), which lets the threshold fall "
            "from 0.65 to 0.55 x the level, covering more of the density sweep and Fan_disp8; it compares D2 with "
            "D1 in the reference camera's units (value_units: the cameras' level ratio; sensors of different "
            "contrast thresholds gave one edge D values several times apart), which raised coverage and lowered "
            "bad2 on the objects of suite v2's tuning half at 346x260",
        params={**_THESIS_METHODS, "threshold_scale": 0.55, "value_tolerance_scale": 0.4, "reference_read": "after",
                "time_window_scale": 0.5, "consensus_radius": 4, "value_units": "reference"},
    ),
    "event-area": AdaptiveDefaults(
        variant="gaussian",
        why="the 3x3 update spreads each event over its neighbours, so a 5x5 block holds a signal after a few "
            "events; with single-pixel updates the density sweep and Fan_disp8 gave (almost) nothing; adaptive "
            "sums the SAD over separate OFF and ON frames (one shared frame cancels a fan's blades; the own "
            "polarity's frame alone confuses a bar's edge with the next bar's) and drops matches that explain "
            "little of the patch or have a rival (they made most of the density sweep's bad2 at thresholds x3); "
            "the no-gaussian variant has the same scale (at 1.5 x it kept 288 "
            "estimates on movingPersons, now 1471, of which 1467 within 1 px of 13: 71 % of the thesis set's 2079)",
        params={**_THESIS_METHODS, "threshold_scale": 0.5, "level_floor": 0.5, "cost_scale": 0.6,
                "polarity": "separate", "sad_frames": "all", "own_ratio": 0.6, "uniqueness": 0.2},
    ),
    "event-vector": AdaptiveDefaults(
        variant="default",
        why="its only variant; adaptive matches OFF and ON frames apart (a fan's blades cancel in one frame), "
            "places each candidate within its own run (run_ends: a row with one run per camera then still "
            "has something to compare), reports the middle of equally good disparities (the smallest sat at "
            "the low end of a flat cost) and bounds the cost by 2 px + 0.3 x the vector's length, which made it "
            "right far more often on Fan_disp8 and cut the density sweep's bad2 at thresholds x3; it splats each "
            "event with a 5x5 Gaussian of sigma 1.5 px (thesis 3x3, sigma 1): with fewer events per edge a 3x3 "
            "splat leaves holes where no event fell within a pixel, which split the runs the vectors measure, so "
            "dropping every second event lost a quarter of the coverage; the 5x5 splat keeps more of it and "
            "covers more of the density sweep",
        params={**_THESIS_METHODS, "threshold_scale": 0.5, "level_floor": 0.5, "polarity": "separate", "run_ends": True,
                "tie_break": "centre", "cost_ratio": 0.3, "cost_slack": 2.0, "kernel_size": 5, "kernel_sigma": 1.5},
    ),
    "stereobm": AdaptiveDefaults(
        variant="default",
        why="OpenCV's block matcher as it is, with the border rule: no answer where the nearest answers inward "
            "say the partner lies outside the other image",
        params=_BORDER,
    ),
    "sgbm": AdaptiveDefaults(
        variant="default",
        why="OpenCV's SGBM as it is, with the border rule: no answer where the nearest answers inward say the "
            "partner lies outside the other image",
        params=_BORDER,
    ),
}


def check_param_set(param_set: str) -> str:
    """``param_set`` if it is a known set; ValueError naming the sets otherwise."""
    if param_set not in PARAM_SETS:
        raise ValueError(f"unknown parameter set {param_set!r}; choose one of: {', '.join(PARAM_SETS)} "
                         f"(default {DEFAULT_PARAM_SET}).")
    return param_set


def resolve(method: str, variant: str | None, param_set: str = DEFAULT_PARAM_SET) -> tuple[str | None, dict]:
    """The variant and the parameter values a set gives a method (before the caller's own overrides).

    Parameters
    ----------
    method : str
    variant : str or None
        Given explicitly, it wins over the set's default variant.
    param_set : {"adaptive", "thesis"}

    Returns
    -------
    variant : str or None
        None: the method's first variant (the thesis' default).
    params : dict
        Values to apply on top of the variant's settings; the caller's overrides go on top of these.
    """
    check_param_set(param_set)
    spec = ADAPTIVE.get(method)
    if param_set == "thesis" or spec is None:
        return variant, {}
    chosen = spec.variant if variant is None else variant
    return chosen, {**spec.params, **spec.variant_params.get(chosen, {})}


def default_variant(method: str, variants, param_set: str = DEFAULT_PARAM_SET) -> str:
    """The variant a method runs when none is given, under ``param_set``."""
    chosen, _ = resolve(method, None, param_set)
    return chosen if chosen is not None else next(iter(variants))
