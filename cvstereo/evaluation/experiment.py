"""The thesis' experiment: every matcher variant on a set of recordings, scored and tabulated.

Used by ``cvstereo demo`` and ``cvstereo bench`` (which adds its own figures through the ``score`` hook
of :func:`run_experiment`). The runs are the cells of the sweep engine (:func:`cvstereo.sweep.run_sweep`),
the one loop over matcher configurations and recordings. Matchers are looked up by name in
:mod:`cvstereo.matchers.registry`.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from cvstereo.evaluation.metrics import FIGURES, markdown_table
from cvstereo.evaluation.thesis import DISPARITY_TABLES
from cvstereo.matchers.registry import available_methods, matcher_class
from cvstereo.matchers.sets import adaptive_of
from cvstereo.model.recording import Recording
from cvstereo.sweep.engine import Score, run_sweep
from cvstereo.sweep.grid import Cell

__all__ = ["Combo", "ExperimentResult", "all_combos", "experiment_markdown", "run_experiment"]


@dataclass(frozen=True)
class Combo:
    """One matcher configuration: method, variant, parameter set (:mod:`cvstereo.matchers.sets`) and overrides.

    The thesis-reproduction tables use the ``thesis`` set (the default here); ``adaptive`` rows stand beside.
    """

    method: str
    variant: str
    params: tuple[tuple[str, object], ...] = ()
    param_set: str = "thesis"

    @property
    def label(self) -> str:
        """``method/variant`` (plus `` (adaptive)`` and overrides), as tables show it."""
        extra = ",".join(f"{k}={v}" for k, v in self.params)
        tag = "" if self.param_set == "thesis" else f" ({self.param_set})"
        return f"{self.method}/{self.variant}{tag}" + (f" [{extra}]" if extra else "")


@dataclass
class ExperimentResult:
    """Figures per combo and recording."""

    figures: dict[Combo, dict[str, dict]] = field(default_factory=dict)

    def add(self, combo: Combo, recording: str, figures: dict) -> None:
        self.figures.setdefault(combo, {})[recording] = figures


def all_combos(methods: Iterable[str] | None = None, *, param_sets: Iterable[str] = ("thesis",)) -> list[Combo]:
    """Every variant of every importable method (or of ``methods``), in registry order, under ``thesis``;
    with ``"adaptive"`` in ``param_sets`` also the ``adaptive`` default of each method whose sets differ
    (:func:`~cvstereo.matchers.sets.adaptive_of`: the thesis' five and the OpenCV baselines), right after its thesis
    variants."""
    names = available_methods() if methods is None else list(methods)
    out = []
    for m in names:
        out += [Combo(m, v) for v in matcher_class(m).variants] if "thesis" in param_sets else []
        spec = adaptive_of(m) if "adaptive" in param_sets else None
        if spec is not None:
            out.append(Combo(m, spec.variant, param_set="adaptive"))
    return out


#: Fields of a sweep row that are bookkeeping or machine-dependent, not figures of the run.
_NOT_FIGURES = frozenset({"key", "recording", "method", "variant", "param_set", "params", "elapsed_s", "worker",
                          "error"})


def run_experiment(recordings: Mapping[str, Recording | str | os.PathLike], combos: Iterable[Combo], *,
                   progress: bool = False, workers: int | None = 0, score: Score | None = None) -> ExperimentResult:
    """Run each combo on each recording and evaluate it, as cells of :func:`cvstereo.sweep.run_sweep`.

    Parameters
    ----------
    recordings : mapping
        Name -> Recording (with or without ground truth; matched in this process) or the path of a
        recording file (workers read it themselves).
    combos : iterable of Combo
    progress : bool
        Show a progress bar over the runs.
    workers : int or None, keyword-only
        Worker processes (Dask; None: one per core); 0, the default: one run after another in this process.
        Recordings in memory need 0.
    score : callable, optional, keyword-only
        ``score(cell, recording, result) -> dict`` of figures added to :func:`evaluate`'s (a module-level
        function, so that workers can run it).

    Returns
    -------
    ExperimentResult
        Per combo and recording name: :func:`cvstereo.evaluation.metrics.evaluate`'s figures (NaN where undefined)
        and those of ``score``.

    Raises
    ------
    RuntimeError
        A run failed: which combo on which recording, and its error.
    """
    combos = list(combos)
    in_memory = {f"memory:{name}": rec for name, rec in recordings.items() if isinstance(rec, Recording)}
    where = {name: f"memory:{name}" if isinstance(rec, Recording) else os.fspath(rec)
             for name, rec in recordings.items()}
    cells = [Cell(where[name], c.method, c.variant, c.params, c.param_set) for c in combos for name in recordings]
    # Cell files only live for this call: an experiment is run whole (a sweep is the resumable kind).
    with tempfile.TemporaryDirectory(prefix="cvstereo-experiment-") as tmp:
        sweep = run_sweep(cells, tmp, workers=workers, progress=progress, score=score, recordings=in_memory)
    result = ExperimentResult()
    rows = iter(sweep.rows)
    for combo in combos:
        for name in recordings:
            row = next(rows)
            if row["error"] is not None:
                raise RuntimeError(f"{combo.label} on {name} failed: {row['error']}")
            figures = {f: row.get(f) for f in FIGURES}
            figures.update((k, v) for k, v in row.items() if k not in _NOT_FIGURES and not k.startswith("param."))
            result.add(combo, name, {k: math.nan if v is None else v for k, v in figures.items()})
    return result


def experiment_markdown(result: ExperimentResult, *, columns=None) -> str:
    """One thesis-style table per combo: rows are recordings, the thesis' mean/std beside ours.

    Each heading names the parameter set: the thesis reproduction is the ``thesis`` set's tables.
    """
    parts = []
    for combo, rows in result.figures.items():
        thesis = DISPARITY_TABLES.get((combo.method, combo.variant))
        kwargs = {} if columns is None else {"columns": columns}
        parts.append(f"### {combo.method}/{combo.variant} ({combo.param_set} set)\n\n"
                     + markdown_table(rows, thesis=thesis, **kwargs))
    return "\n\n".join(parts)
