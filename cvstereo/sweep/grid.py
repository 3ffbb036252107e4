"""Sweep grids: cells (recording x method x variant x parameters x parameter set), grid files, recording specs."""

from __future__ import annotations

import glob
import itertools
import os
import tomllib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Cell:
    """One run of a sweep: a matcher configuration on one recording.

    Attributes
    ----------
    recording : str
        Path of the recording file (workers read it themselves).
    method : str
        Matcher name (formats.md).
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
    """

    methods: tuple[str, ...]
    variants: tuple[str, ...] = ()
    params: tuple[tuple[str, tuple], ...] = ()
    param_sets: tuple[str | None, ...] = (None,)

    def cells(self, recordings: Sequence[str]) -> list[Cell]:
        """Every cell, in a fixed order: recording, then method, variant and parameter values.

        Raises
        ------
        ValueError
            Unknown method, a variant a method does not have, or a parameter no method has.
        """
        from cvstereo.registry import matcher_class

        used: set[str] = set()
        configs = []
        for method in self.methods:
            cls = matcher_class(method)
            fields = set(cls.Params.__dataclass_fields__)
            if self.variants == ("all",):
                variants = list(cls.variants)
            elif self.variants:
                bad = [v for v in self.variants if v not in cls.variants]
                if bad:
                    raise ValueError(f"method '{method}' has no variant {', '.join(bad)}; it has: "
                                     f"{', '.join(cls.variants)}.")
                variants = list(self.variants)
            else:
                variants = [None]  # the method's default variant
            mine = [(k, vals) for k, vals in self.params if k in fields]
            used.update(k for k, _ in mine)
            names = [k for k, _ in mine]
            for variant in variants:
                for values in itertools.product(*(vals for _, vals in mine)):
                    for param_set in (self.param_sets if _has_param_sets(method) else (None,)):
                        configs.append((method, variant, tuple(sorted(zip(names, values, strict=True))),
                                        param_set))
        unknown = [k for k, _ in self.params if k not in used]
        if unknown:
            raise ValueError(f"parameter(s) {', '.join(unknown)} belong to none of the methods "
                             f"{', '.join(self.methods)}; see `cvstereo match --list-methods`.")
        return [Cell(os.fspath(r), m, v, p, ps) for r in recordings for m, v, p, ps in configs]


def _has_param_sets(method: str) -> bool:
    """Whether the parameter sets differ for a method: those :data:`cvstereo.param_sets.ADAPTIVE` lists (the
    thesis' five); the others run the same under both, so once."""
    from cvstereo.param_sets import ADAPTIVE

    return method in ADAPTIVE


def read_grid_file(path: str | os.PathLike) -> tuple[list[Grid], list[str], dict]:
    """Read a TOML grid file.

    The file has optional top-level ``recordings`` (list of specs, see :func:`resolve_recordings`) and
    ``figure``, and one ``[[grid]]`` table per block of methods::

        recordings = ["preset:1arm-100cm:2", "data/*.npz"]
        figure = "bad2"

        [[grid]]
        methods = ["event-area", "event-vector"]
        variants = ["all"]
        params = { threshold = [1.5, 2.5] }

    Returns
    -------
    grids : list of Grid
    recordings : list of str
    options : dict
        The other top-level keys (e.g. ``figure``).
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not a valid TOML grid file: {exc}") from None
    blocks = data.pop("grid", None)
    if not isinstance(blocks, list) or not blocks:
        raise ValueError(f"{path}: needs at least one [[grid]] table with `methods = [...]`.")
    grids = []
    for i, block in enumerate(blocks):
        methods = block.get("methods", [block["method"]] if "method" in block else None)
        if not methods:
            raise ValueError(f"{path}: [[grid]] number {i + 1} has no `methods`.")
        params = block.get("params", {})
        grids.append(Grid(tuple(methods), tuple(block.get("variants", ())),
                          tuple((k, tuple(v if isinstance(v, list) else [v])) for k, v in params.items()),
                          tuple(block.get("param_sets", (None,)))))
    recordings = data.pop("recordings", [])
    return grids, list(recordings), data


def resolve_recordings(specs: Iterable[str], *, progress: bool = False) -> list[str]:
    """Turn recording specs into file paths, in the order given (duplicates dropped).

    A spec is a path, a glob (``data/*.npz``), ``preset:NAME`` or ``preset:NAME:SECONDS`` (a simulated
    preset, generated once and cached, see :func:`cvstereo.simulate.presets.cached_preset`), or
    ``suite:NAME`` (every recording of a simulated suite, where the simulator has one; ``suite:NAME:tune`` or
    ``suite:NAME:eval`` one half of a suite that has a tuning and an evaluation half).

    Raises
    ------
    FileNotFoundError
        A path or glob that matches nothing.
    """
    out: list[str] = []
    for spec in specs:
        if spec.startswith("preset:"):
            from cvstereo.simulate.presets import cached_preset

            _, name, *rest = spec.split(":")
            seconds = float(rest[0]) if rest else None
            out.append(os.fspath(cached_preset(name, seconds=seconds, progress=progress)))
        elif spec.startswith("suite:"):
            out.extend(_suite_paths(spec.partition(":")[2], progress=progress))
        elif any(ch in spec for ch in "*?["):
            found = sorted(glob.glob(spec))
            if not found:
                raise FileNotFoundError(f"recording pattern '{spec}' matches no file.")
            out.extend(found)
        else:
            if not Path(spec).exists():
                raise FileNotFoundError(f"recording '{spec}' does not exist.")
            out.append(spec)
    return list(dict.fromkeys(out))


def _suite_paths(spec: str, *, progress: bool) -> list[str]:
    from cvstereo.simulate import suite_recordings

    name, _, half = spec.partition(":")  # NAME, or NAME:HALF of a suite with a tuning and an evaluation half
    extra = {"half": half} if half else {}
    return [os.fspath(path) for _, path in suite_recordings(name, progress=progress, **extra)]
