"""Sweep grids: cells (recording x method x variant x parameters x parameter set), each configuration checked
before any runs."""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Cell", "Grid", "toml_text"]


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a matcher configuration on one recording.

    Attributes
    ----------
    recording : str
        Path of the recording file (workers read it themselves).
    method : str
        Matcher name (docs/formats.md).
    variant : str or None
        Variant name; None: the method's default.
    params : tuple of (name, value)
        Parameter overrides, sorted by name.
    param_set : str or None
        The parameter set (``thesis``, ``adaptive``) the overrides apply to; None: the default set.
    """

    recording: str
    method: str
    variant: str | None
    params: tuple[tuple[str, object], ...] = ()
    param_set: str | None = None

    @property
    def label(self) -> str:
        """``method/variant [k=v,...] on FILE``, as progress and errors show it."""
        extra = ",".join(f"{k}={v}" for k, v in self.params)
        config = f"{self.method}/{self.variant or 'default'}" + (f" [{extra}]" if extra else "")
        if self.param_set:
            config += f" ({self.param_set} set)"
        return f"{config} on {Path(self.recording).name}"


@dataclass(frozen=True)
class Grid:
    """Methods x variants x parameter values, expanded over recordings by :meth:`cells`.

    Attributes
    ----------
    methods : tuple of str
    variants : tuple of str, optional
        Variants to run for every method; empty: each method's default variant; ``("all",)``: every variant.
    params : tuple of (name, values)
        Each parameter with the values to try. A parameter applies to the methods whose parameter class
        has it; a name that no chosen method knows is an error.
    param_sets : tuple of str or None
        Parameter sets to run each configuration under (``thesis``, ``adaptive``); ``(None,)``: the default.
        Applied to the methods that have sets (the thesis' five), others run once.
    origin : str, optional
        Where the grid was written (``grid.toml [[grid]] 2``, ``--param``): the start of every message about it.
    """

    methods: tuple[str, ...]
    variants: tuple[str, ...] = ()
    params: tuple[tuple[str, tuple], ...] = ()
    param_sets: tuple[str | None, ...] = (None,)
    origin: str = "grid"

    def configs(self) -> list[tuple[str, str | None, tuple[tuple[str, object], ...], str | None]]:
        """Every configuration (method, variant, sorted parameters, parameter set), in a fixed order, each
        checked as its matcher would check it: a value that would fail every cell fails here, before any runs.

        Raises
        ------
        ValueError
            Unknown method, variant or parameter set, a parameter no method has or without values, a value
            of the wrong type or range for its field, or a combination the matcher refuses; the message
            starts with :attr:`origin` and names the key and value.
        """
        from cvstereo.matchers.registry import check_param_item, matcher_class, matcher_params
        from cvstereo.matchers.sets import DEFAULT_PARAM_SET, check_param_set

        for ps in self.param_sets:
            if ps is not None:
                self._fail(f"param_sets = {toml_text(ps)}", check_param_set, ps)
        used: set[str] = set()
        configs = []
        for method in self.methods:
            cls = self._fail(f"method {toml_text(method)}", matcher_class, method)
            fields = set(cls.Params.__dataclass_fields__)
            if self.variants == ("all",):
                variants = list(cls.variants)
            elif self.variants:
                bad = [v for v in self.variants if v not in cls.variants]
                if bad:
                    raise ValueError(f"{self.origin}: method '{method}' has no variant {', '.join(bad)}; it has: "
                                     f"{', '.join(cls.variants)}.")
                variants = list(self.variants)
            else:
                variants = [None]  # the method's default variant
            mine = [(k, vals) for k, vals in self.params if k in fields]
            for key, values in mine:
                if not values:
                    raise ValueError(f"{self.origin}: parameter '{key}' has no values; give at least one.")
                for value in values:
                    self._fail(f"{key} = {toml_text(value)}", check_param_item, cls.Params, key, value,
                               where=f"{method} parameter")
            used.update(k for k, _ in mine)
            names = [k for k, _ in mine]
            for variant in variants:
                for values in itertools.product(*(vals for _, vals in mine)):
                    params = tuple(sorted(zip(names, values, strict=True)))
                    for param_set in (self.param_sets if _has_param_sets(method) else (None,)):
                        shown = ", ".join(f"{k} = {toml_text(v)}" for k, v in params) or "defaults"
                        self._fail(f"{method}/{variant or 'default'} with {shown}", matcher_params, method, variant,
                                   param_set=param_set or DEFAULT_PARAM_SET, **dict(params))
                        configs.append((method, variant, params, param_set))
        unknown = [k for k, _ in self.params if k not in used]
        if unknown:
            raise ValueError(f"{self.origin}: parameter(s) {', '.join(unknown)} belong to none of the methods "
                             f"{', '.join(self.methods)}; see `cvstereo match --list-methods`.")
        return configs

    def cells(self, recordings: Sequence[str]) -> list[Cell]:
        """Every cell, in a fixed order: recording, then method, variant and parameter values.

        Raises
        ------
        ValueError
            A configuration that would fail (:meth:`configs`).
        """
        configs = self.configs()
        return [Cell(os.fspath(r), m, v, p, ps) for r in recordings for m, v, p, ps in configs]

    def _fail(self, what: str, check, *args, **kwargs):
        """``check(*args, **kwargs)``, its ValueError prefixed with the origin and ``what`` was checked."""
        try:
            return check(*args, **kwargs)
        except ValueError as exc:
            raise ValueError(f"{self.origin}: {what}: {exc}") from None


def _has_param_sets(method: str) -> bool:
    """Whether the parameter sets differ for a method: those whose parameters have an ``adaptive`` set (the
    thesis' five, and the OpenCV baselines, which ``adaptive`` gives the border rule); the others run the same
    under both, so once."""
    from cvstereo.matchers.sets import adaptive_of

    return adaptive_of(method) is not None


#: Longest value text a message quotes.
_SHOWN_CHARS = 60


def toml_text(value) -> str:
    """A value as a grid file writes it (``true``, ``nan``, ``"frame"``, ``[1, 2]``), shortened for messages."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float) and not math.isfinite(value):
        text = str(value)
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(toml_text(v) for v in value) + "]"
    elif isinstance(value, dict):
        text = "{ " + ", ".join(f"{k} = {toml_text(v)}" for k, v in value.items()) + " }"
    elif isinstance(value, str):
        text = json.dumps(value)
    else:
        text = repr(value)
    return text if len(text) <= _SHOWN_CHARS else text[: _SHOWN_CHARS - 3] + "..."
