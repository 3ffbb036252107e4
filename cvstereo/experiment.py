"""The thesis' experiment: every matcher variant on a set of recordings, scored and tabulated.

Used by ``cvstereo demo`` and ``cvstereo bench`` (which adds memory sampling and its own figures through
the hooks of :func:`run_experiment`). Matchers are looked up by name in :mod:`cvstereo.registry`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

from cvstereo.evaluate import evaluate, markdown_table
from cvstereo.matches import MatchResult
from cvstereo.param_sets import ADAPTIVE
from cvstereo.pipeline import match
from cvstereo.recording import Recording
from cvstereo.registry import available_methods, matcher_class
from cvstereo.thesis import DISPARITY_TABLES


@dataclass(frozen=True)
class Combo:
    """One matcher configuration: method, variant, parameter set (:mod:`cvstereo.param_sets`) and overrides.

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
    """Figures per combo and recording, and the meta of each matches run."""

    figures: dict[Combo, dict[str, dict]] = field(default_factory=dict)
    meta: dict[Combo, dict[str, dict]] = field(default_factory=dict)

    def add(self, combo: Combo, recording: str, figures: dict, meta: dict) -> None:
        self.figures.setdefault(combo, {})[recording] = figures
        self.meta.setdefault(combo, {})[recording] = meta


def all_combos(methods: Iterable[str] | None = None, *, param_sets: Iterable[str] = ("thesis",)) -> list[Combo]:
    """Every variant of every importable method (or of ``methods``), in registry order, under ``thesis``;
    with ``"adaptive"`` in ``param_sets`` also each thesis method's ``adaptive`` default, right after its
    thesis variants."""
    names = available_methods() if methods is None else list(methods)
    out = []
    for m in names:
        out += [Combo(m, v) for v in matcher_class(m).variants] if "thesis" in param_sets else []
        if "adaptive" in param_sets and m in ADAPTIVE:
            out.append(Combo(m, ADAPTIVE[m].variant, param_set="adaptive"))
    return out


def run_combo(recording: Recording, combo: Combo) -> MatchResult:
    """Run one combo over a recording (the default ``run`` of :func:`run_experiment`)."""
    return match(recording, method=combo.method, variant=combo.variant, param_set=combo.param_set,
                 **dict(combo.params))


def score_result(name: str, recording: Recording, result: MatchResult) -> dict:
    """The figures of one run (the default ``score`` of :func:`run_experiment`): :func:`evaluate`."""
    return evaluate(recording, result)


def run_experiment(recordings: Mapping[str, Recording], combos: Iterable[Combo], *,
                   on_result: Callable[[Combo, str, dict], None] | None = None,
                   progress: bool = False, desc: str = "matching",
                   run: Callable[[Recording, Combo], MatchResult] = run_combo,
                   score: Callable[[str, Recording, MatchResult], dict] = score_result) -> ExperimentResult:
    """Run each combo on each recording and evaluate it.

    Parameters
    ----------
    recordings : mapping
        Name -> Recording (with or without ground truth).
    combos : iterable of Combo
    on_result : callable, optional
        Called with (combo, recording name, figures) after each run, e.g. to print progress.
    progress : bool
        Show a progress bar over the runs.
    desc : str
        The progress bar's label.
    run : callable, keyword-only
        ``run(recording, combo) -> MatchResult`` (e.g. with memory sampling); default :func:`run_combo`.
    score : callable, keyword-only
        ``score(name, recording, result) -> figures``; default :func:`score_result`.

    Returns
    -------
    ExperimentResult
    """
    combos = list(combos)
    jobs = [(c, name) for c in combos for name in recordings]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(jobs), unit="run", desc=desc, leave=False)
    result = ExperimentResult()
    for combo, name in jobs:
        if bar is not None:
            bar.set_postfix_str(f"{combo.label} on {name}")
        res = run(recordings[name], combo)
        figures = score(name, recordings[name], res)
        result.add(combo, name, figures, res.meta)
        if on_result is not None:
            on_result(combo, name, figures)
        if bar is not None:
            bar.update()
    if bar is not None:
        bar.close()
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
