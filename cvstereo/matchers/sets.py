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
thesis' while it covers more. Which fields and values, and why, is said once per method, by its parameter class
(its ``adaptive`` attribute, an :class:`AdaptiveDefaults`: ``params`` and ``why``; ``cvstereo match --list-methods``
prints them, :data:`ADAPTIVE` reads them all). The rig check's time offset is NOT applied
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

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

from cvstereo.matchers._registry import matcher_class, registered_methods

__all__ = ["ADAPTIVE", "ADAPTIVE_BORDER", "ADAPTIVE_THESIS", "DEFAULT_PARAM_SET", "PARAM_SETS", "AdaptiveDefaults",
           "adaptive_of", "check_param_set", "default_variant", "resolve"]

#: The parameter sets, the default first.
PARAM_SETS = ("adaptive", "thesis")
DEFAULT_PARAM_SET = "adaptive"


@dataclass(frozen=True)
class AdaptiveDefaults:
    """What the ``adaptive`` set changes for one method: its parameter class' ``adaptive`` class attribute
    (e.g. :attr:`cvstereo.matchers.frame.params.FrameClusterParams.adaptive`).

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
ADAPTIVE_BORDER = {"border_horizon_us": 40_000, "border_rows": 16}

#: What every thesis method gets under ``adaptive``: relative thresholds and the border rule.
ADAPTIVE_THESIS = {"threshold_mode": "relative", **ADAPTIVE_BORDER}


def adaptive_of(method: str) -> AdaptiveDefaults | None:
    """What ``adaptive`` sets for ``method``: its parameter class' ``adaptive`` attribute, or None (the method runs
    the same under both sets: dv-semidense, fused, a plugin without one).

    Raises
    ------
    ValueError
        Unknown method (the known ones listed).
    """
    return getattr(matcher_class(method).Params, "adaptive", None)


class _AdaptiveView(Mapping):
    """method -> :class:`AdaptiveDefaults`, read-only, of the registered methods whose parameters have a set."""

    def _table(self) -> dict[str, AdaptiveDefaults]:
        out = {}
        for method in registered_methods():
            try:
                spec = adaptive_of(method)
            except ImportError:  # a plugin whose module cannot be imported here has no set to show
                continue
            if spec is not None:
                out[method] = spec
        return out

    def __getitem__(self, method: str) -> AdaptiveDefaults:
        return self._table()[method]

    def __iter__(self) -> Iterator[str]:
        return iter(self._table())

    def __len__(self) -> int:
        return len(self._table())

    def __repr__(self) -> str:
        return f"ADAPTIVE({self._table()!r})"


#: method -> what ``adaptive`` sets, as every parameter class declares it (its ``adaptive`` attribute), in listing
#: order: a view for reading, built from the registry. The OpenCV baselines have no thresholds of the thesis' kind:
#: ``adaptive`` gives them the border rule only. Methods not listed (dv-semidense, fused) are the same under both sets.
ADAPTIVE: Mapping[str, AdaptiveDefaults] = _AdaptiveView()


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
    spec = None if param_set == "thesis" else adaptive_of(method)
    if spec is None:
        return variant, {}
    chosen = spec.variant if variant is None else variant
    return chosen, {**spec.params, **spec.variant_params.get(chosen, {})}


def default_variant(method: str, variants, param_set: str = DEFAULT_PARAM_SET) -> str:
    """The variant a method runs when none is given, under ``param_set``."""
    chosen, _ = resolve(method, None, param_set)
    return chosen if chosen is not None else next(iter(variants))
