"""``cvstereo bench``: every matcher on the same recordings, with truth, speed, memory and distance.

One run covers: every matcher and variant (and the OpenCV and dv-processing baselines where installed)
on the thesis' six presets and the motorcycle scene, scored against ground truth (docs/evaluation.md) beside
the thesis' published mean/std; speed (events per second, times real time, speed-up over the thesis'
Matlab times on ``2arms-50cm``) and peak memory; the real TUM recordings where present (share of estimates
within 1 px of their known disparity); and distance: d = a/Z - c fitted per matcher on the 50 and 150 cm
recordings, its error in cm at 75, 100 and 125 cm.

The accuracy cells (every recording x matcher configuration: match + evaluate) run on the sweep engine
(:func:`cvstereo.sweep.run_sweep`, one worker process per core by default); the speed and memory cells run
afterwards in this process, one after another, with no worker alive, each timing repeated until two runs
agree (:mod:`cvstereo.benchmark.timing`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import os
import platform
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from cvstereo.benchmark.timing import measure
from cvstereo.evaluation.experiment import Combo, all_combos, run_experiment
from cvstereo.evaluation.metrics import FIGURES, format_figure, markdown_table, to_json
from cvstereo.evaluation.thesis import DISPARITY_TABLES, MATLAB_SECONDS, RECORDING_SECONDS, RECORDINGS
from cvstereo.geometry.depth import fit_depth_model
from cvstereo.io.atomic import write_text_atomic
from cvstereo.matchers.registry import METHODS, available_methods, matcher_class
from cvstereo.model.matches import MatchResult
from cvstereo.model.recording import Recording
from cvstereo.run import match
from cvstereo.sweep import Cell

__all__ = ["ACCURACY_FIGURES", "EXTRA_SECONDS", "FIT_DISTANCES", "QUICK_SECONDS", "REAL_DISPARITIES", "RESULT_FILES",
           "TEST_DISTANCES", "BenchConfig", "PeakMemory", "accuracy_cells", "bench_cell_figures", "bench_markdown",
           "distance_recordings", "distance_table", "machine_info", "real_recordings", "run_bench", "share_within",
           "simulated_recordings", "speed_cells", "speed_table", "warm_up", "write_results"]

#: The real recordings and the disparities known in them (README of tum-stereo): px.
REAL_DISPARITIES: dict[str, tuple[float, ...]] = {
    "Fan_disp8.dat": (8.0,),
    "NSTlogo_disp12-8-3.dat": (12.0, 8.0, 3.0),
    "movingPersons.dat": (13.0,),
}

#: Distances of the 1-arm recordings used to fit d = a/Z - c, and those the fit is tested on, metres.
FIT_DISTANCES = (0.5, 1.5)
TEST_DISTANCES = (0.75, 1.0, 1.25)
#: Length of the extra recordings (motorcycle, distance set); the presets keep the thesis' 11 s.
EXTRA_SECONDS = 4.0
#: Length of every recording with --quick.
QUICK_SECONDS = 1.5


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """What one benchmark run covers.

    Attributes
    ----------
    quick : bool
        Short clips (QUICK_SECONDS) of every recording: about a minute once the recordings are cached.
    methods : tuple of str or None
        Methods to run (default: every importable one).
    shared : Path or None
        Shared data folder holding ``data/tum-stereo`` (skipped when absent).
    distance : bool
        Run the distance fit.
    workers : int or None
        Worker processes for the accuracy cells (:func:`cvstereo.sweep.run_sweep`): None, one per core
        (in this process when Dask is not installed); 0, in this process without Dask. One thread per cell.
    threads : int
        Threads of the speed and memory cells' matchers (1: every figure is one core's).
    """

    quick: bool = False
    methods: tuple[str, ...] | None = None
    shared: Path | None = None
    distance: bool = True
    workers: int | None = None
    threads: int = 1

    @property
    def preset_seconds(self) -> float | None:
        return QUICK_SECONDS if self.quick else None

    @property
    def extra_seconds(self) -> float:
        return QUICK_SECONDS if self.quick else EXTRA_SECONDS


class PeakMemory:
    """Peak resident memory of this process during a block, sampled from /proc (Linux), MB.

    Counts everything (numpy, numba's allocations, OpenCV), which tracemalloc would not. ``increase_mb``
    is the peak minus the resident size when the block started; NaN where /proc is not available.
    """

    def __init__(self, interval_s: float = 0.002):
        self.interval_s = interval_s
        self.start_mb = self.peak_mb = float("nan")
        self._stop = threading.Event()

    @staticmethod
    def rss_mb() -> float:
        try:
            with open("/proc/self/statm") as fh:
                return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6
        except (OSError, ValueError, IndexError):
            return float("nan")

    def _sample(self):
        while not self._stop.wait(self.interval_s):
            self.peak_mb = max(self.peak_mb, self.rss_mb())

    def __enter__(self):
        self.start_mb = self.peak_mb = self.rss_mb()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak_mb = max(self.peak_mb, self.rss_mb())

    @property
    def increase_mb(self) -> float:
        return self.peak_mb - self.start_mb


def _cached_simulation(name: str, make: Callable[[], Recording]) -> Path:
    """The path of a simulated recording in the preset cache folder, generated once."""
    from cvstereo.io import write_recording_npz
    from cvstereo.simulate import GENERATOR_VERSION, default_cache_dir

    path = default_cache_dir() / f"bench-{name}-v{GENERATOR_VERSION}.npz"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        write_recording_npz(path, make())
    return path


def simulated_recordings(config: BenchConfig) -> dict[str, Path]:
    """Paths of the six presets and the motorcycle scene (cached)."""
    from cvstereo.simulate import MotorcycleScene, cached_preset, simulate

    recs = {name: Path(cached_preset(name, seconds=config.preset_seconds)) for name in RECORDINGS}
    secs = config.extra_seconds
    recs["motorcycle"] = _cached_simulation(f"motorcycle-{secs}s",
                                            lambda: simulate(MotorcycleScene(), seconds=secs, seed=0))
    return recs


def distance_recordings(config: BenchConfig) -> dict[float, Path]:
    """Paths of one arm at each fit and test distance (cached)."""
    from cvstereo.simulate import ArmsScene, simulate

    secs = config.extra_seconds
    return {
        z: _cached_simulation(f"1arm-{round(z * 100)}cm-{secs}s",
                              lambda z=z: simulate(ArmsScene(arms=1, distance_m=z), seconds=secs, seed=0))
        for z in FIT_DISTANCES + TEST_DISTANCES
    }


def real_recordings(shared: Path | None) -> dict[str, Path]:
    """Paths of the real TUM recordings present (the readers detect the left retina from the data)."""
    folder = (shared or Path()) / "data" / "tum-stereo"
    return {name: folder / name for name in REAL_DISPARITIES if (folder / name).exists()}


def bench_cell_figures(cell: Cell, recording: Recording, result: MatchResult) -> dict:
    """The bench's figures of an accuracy cell beside the sweep's (the ``score`` of
    :func:`cvstereo.sweep.run_sweep`): the median disparity and, on the real recordings, the share within
    1 px of the known disparities."""
    figures = {"median": float(np.median(result.disparity)) if len(result) else float("nan")}
    name = Path(cell.recording).name
    if name in REAL_DISPARITIES:
        figures["within_1px"] = share_within(result.disparity, REAL_DISPARITIES[name])
    return figures


#: Figures of an accuracy cell (docs/evaluation.md's, without the speed figures: cells may share the machine).
ACCURACY_FIGURES = tuple(f for f in FIGURES if f not in ("events_per_s", "realtime_x"))
#: What :func:`bench_cell_figures` adds.
_BENCH_FIGURES = ("median", "within_1px")


def accuracy_cells(recordings: dict[str, Path], combos: list[Combo], *, workers: int | None,
                   progress: bool) -> dict[str, dict[str, dict]]:
    """Figures per combo label and recording name, every cell run by :func:`run_experiment` on the sweep
    engine (speed figures left out: cells may run side by side).

    Raises
    ------
    RuntimeError
        A cell failed (a matcher's bug or an unreadable recording): its configuration, recording and error.
    """
    if workers is None and importlib.util.find_spec("dask") is None:
        workers = 0  # without the sweep extra the cells run here, one after another
    experiment = run_experiment(recordings, combos, workers=workers, progress=progress, score=bench_cell_figures)
    return {c.label: {name: {f: v for f, v in figures.items() if f in ACCURACY_FIGURES or f in _BENCH_FIGURES}
                      for name, figures in by_name.items()} for c, by_name in experiment.figures.items()}


def speed_cells(recording: Recording, combos: list[Combo], *, threads: int = 1) -> dict[str, dict]:
    """Speed and peak memory of each combo on ``recording``, in this process, one after another, on ``threads``.

    Memory is sampled on one run; the time is the matcher's own (``elapsed_s``), repeated until two runs
    agree within 10 % (:func:`cvstereo.benchmark.timing.measure`), with the load average before and after.
    """
    out = {}
    for c in combos:
        def run(c=c):
            return match(recording, method=c.method, variant=c.variant, param_set=c.param_set, threads=threads,
                         **dict(c.params))
        with PeakMemory() as mem:
            first = run()
        timing = measure(lambda run=run: run().meta["elapsed_s"])
        out[c.label] = {"events_per_s": first.meta["input_events"] / timing.seconds,
                        "realtime_x": recording.duration_s / timing.seconds, "elapsed_s": timing.seconds,
                        "runs": timing.runs, "agreed": timing.agreed, "load_before": timing.load_before,
                        "load_after": timing.load_after, "peak_rss_mb": mem.peak_mb,
                        "rss_increase_mb": mem.increase_mb}
    return out


def share_within(disparity: np.ndarray, known: tuple[float, ...], tolerance: float = 1.0) -> float:
    """Share of estimates within ``tolerance`` px of any of the ``known`` disparities."""
    if disparity.size == 0:
        return float("nan")
    near = np.zeros(disparity.size, dtype=bool)
    for d in known:
        near |= np.abs(disparity - d) <= tolerance
    return float(near.mean())


def warm_up(combos: list[Combo]) -> dict[str, float]:
    """Run every method once on a tiny stream so compile time (numba) is not counted as matching time."""
    from cvstereo.model.events import make_events

    rng = np.random.default_rng(0)
    n = 2000
    t = np.sort(rng.integers(0, 100_000, n))
    ev = make_events(t, rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n))
    tiny = Recording(ev, ev)
    seconds = {}
    for combo in combos:
        start = time.perf_counter()
        match(tiny, method=combo.method, variant=combo.variant, param_set=combo.param_set, threads=1)
        seconds[combo.label] = time.perf_counter() - start
    return seconds


def run_bench(config: BenchConfig, *, progress: bool = True, log: Callable[[str], None] = print) -> dict:
    """Run the whole benchmark; return a JSON-ready dict (see :func:`bench_markdown`)."""
    requested = list(config.methods or METHODS)
    for method in requested:
        matcher_class(method)  # an unknown name is an error (it lists the known ones)
    # Matchers whose optional extra is not installed are left out with a note, never an error.
    installed = set(available_methods())
    skipped = [m for m in requested if m not in installed]
    combos = all_combos([m for m in requested if m in installed], param_sets=("thesis", "adaptive"))
    log(f"matchers: {', '.join(c.label for c in combos)}")
    if skipped:
        log(f"skipped (not installed here): {', '.join(skipped)}; dv-semidense needs pip install 'cvstereo[compare]'")
    log("recordings: simulating the presets and extra scenes (cached after the first run) ...")
    sims = simulated_recordings(config)
    reals = real_recordings(config.shared)
    dists = distance_recordings(config) if config.distance else {}
    # Compiled here first, the kernels are in numba's on-disk cache when the workers start: they load them.
    compile_s = warm_up(combos)

    # The distance set is named like the presets (1arm-50cm, 1arm-150cm): under a shared name its recording
    # is the one run and tabulated.
    recordings = {**sims, **reals, **{f"1arm-{round(z * 100)}cm": r for z, r in dists.items()}}
    log(f"accuracy: {len(combos) * len(recordings)} cells on the sweep engine "
        f"({_workers_text(config.workers)}) ...")
    runs = accuracy_cells(recordings, combos, workers=config.workers, progress=progress)
    speed = {}
    if "2arms-50cm" in sims:
        from cvstereo.io import read_recording

        log("speed and memory: on 2arms-50cm in this process, one cell after another ...")
        speed = speed_cells(read_recording(sims["2arms-50cm"]), combos, threads=config.threads)

    results = {
        "machine": machine_info(),
        "config": {"quick": config.quick, "preset_seconds": config.preset_seconds or RECORDING_SECONDS,
                   "extra_seconds": config.extra_seconds},
        "combos": {c.label: {"method": c.method, "variant": c.variant, "param_set": c.param_set} for c in combos},
        "skipped": skipped,
        "compile_s": compile_s,
        "workers": config.workers,
        "threads": config.threads,
        "runs": runs,
        "speed": speed_table(combos, speed),
        "real": {c.label: {n: runs[c.label][n]["within_1px"] for n in reals} for c in combos} if reals else {},
        "distance": distance_table(combos, runs, dists) if dists else {},
    }
    return results


def speed_table(combos: list[Combo], speed: dict[str, dict]) -> dict:
    """Speed and memory per combo on 2arms-50cm (``speed``: :func:`speed_cells`' figures per label), with the
    speed-up over the thesis' Matlab."""
    out = {}
    for c in combos:
        fig = speed.get(c.label)
        if fig is None:
            continue
        matlab = MATLAB_SECONDS.get((c.method, c.variant))
        # Matlab times are for 11 s of data; scale them to the length we ran.
        seconds_of_data = fig["realtime_x"] * fig["elapsed_s"] if fig["elapsed_s"] else float("nan")
        speedup = (matlab * seconds_of_data / RECORDING_SECONDS) / fig["elapsed_s"] if matlab else float("nan")
        out[c.label] = {**fig, "matlab_s": matlab if matlab else float("nan"), "speedup_vs_matlab": speedup}
    return out


def distance_table(combos: list[Combo], runs: dict, dists: dict[float, Recording]) -> dict:
    """Per combo: d = a/Z - c fitted on the median disparity at FIT_DISTANCES, error at TEST_DISTANCES (cm)."""
    out = {}
    for c in combos:
        med = {z: runs[c.label][f"1arm-{round(z * 100)}cm"]["median"] for z in dists}
        fit_z = [z for z in FIT_DISTANCES if np.isfinite(med.get(z, np.nan))]
        if len(fit_z) < 2:
            out[c.label] = {"error": "too few matches at the fit distances"}
            continue
        try:
            model = fit_depth_model(fit_z, [med[z] for z in fit_z])
        except ValueError as exc:  # e.g. medians that do not shrink with distance: that combo's row says so
            out[c.label] = {"error": str(exc)}
            continue
        errors = {f"{round(z * 100)}cm": float((model.distance(med[z]) - z) * 100) if np.isfinite(med[z])
                  else float("nan") for z in TEST_DISTANCES}
        out[c.label] = {"a": model.a, "c": model.c, "error_cm": errors}
    return out


def machine_info() -> dict:
    """What the benchmark ran on."""
    import cv2
    import numba

    import cvstereo
    from cvstereo._threads import available_cores, threading_layer

    info = {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
            "cores_usable": available_cores(), "processor": platform.processor() or platform.machine(),
            "numpy": np.__version__, "opencv": cv2.__version__, "numba": numba.__version__,
            "numba_threading_layer": threading_layer(), "cvstereo": cvstereo.__version__,
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    with contextlib.suppress(OSError), open("/proc/cpuinfo") as fh:  # the CPU's name, where Linux tells it
        info["processor"] = next((line.split(":", 1)[1].strip() for line in fh if line.startswith("model name")),
                                 info["processor"])
    return info


def _workers_text(workers: int | None) -> str:
    return "one worker per core" if workers is None else f"workers={workers}"


def bench_markdown(results: dict) -> str:
    """The benchmark as a markdown report: machine, thesis tables with truth, speed, real data, distance."""
    m = results["machine"]
    cfg = results["config"]
    lines = [
        "# cvstereo benchmark",
        "",
        f"Machine: {m['processor']}, {m['cpus']} CPUs, {m['platform']}; Python {m['python']}, numpy {m['numpy']}, "
        f"OpenCV {m['opencv']}, numba {m.get('numba', '-')}; cvstereo {m['cvstereo']}; {m['date']}.",
        f"Presets: {cfg['preset_seconds']:g} s each{' (--quick)' if cfg['quick'] else ''}; extra scenes "
        f"{cfg['extra_seconds']:g} s. Accuracy cells ran on the sweep engine "
        f"({_workers_text(results.get('workers'))}); "
        f"speed and memory in one process afterwards, alone, threads={results.get('threads', 1)}."
        + (f" Not installed, so not run: {', '.join(results['skipped'])}." if results.get("skipped") else ""),
        "",
        "## Accuracy against ground truth, beside the thesis' mean/std",
        "",
        "Rows are recordings; `thesis mean/std` are the thesis' published numbers (tables 4.2-4.14, real "
        "recordings of the same scenes), ours are on the simulated re-creations. MAE, bad>1px (share of "
        "errors above 1 px), false (share of matches on noise/background) and coverage are against the truth "
        "(docs/evaluation.md). The thesis reproduction is the `thesis` parameter set (the thesis' constants); each "
        "method's `adaptive` default (thresholds relative to the recording's signal level) follows its thesis "
        "variants.",
    ]
    columns = ("mean", "std", "truth_mean", "mae", "bad1", "false_rate", "coverage", "matches")
    for label, info in results["combos"].items():
        rows = {n: f for n, f in results["runs"][label].items() if n in RECORDINGS or n == "motorcycle"}
        thesis = DISPARITY_TABLES.get((info["method"], info["variant"]))
        heading = f"{info['method']}/{info['variant']} ({info.get('param_set', 'thesis')} set)"
        lines += ["", f"### {heading}", "", markdown_table(rows, columns=columns, thesis=thesis)]
    lines += ["", "## Speed and memory on 2arms-50cm", "",
              "Each time is the faster of the first two runs within 10 % of each other (at most 6 runs; `*`: none "
              "agreed, the fastest shown), with the 1-minute load average before and after.", "",
              "| matcher | events/s | x real time | Matlab s (11 s) | speed-up vs Matlab | peak RSS MB | "
              "RSS increase MB | compile s | runs | load |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for label, s in results["speed"].items():
        lines.append(
            f"| {label} | {format_figure('events_per_s', s['events_per_s'])} | "
            f"{format_figure('realtime_x', s['realtime_x'])} | {format_figure('x', s['matlab_s'])} | "
            f"{format_figure('x', s['speedup_vs_matlab'])}x | {format_figure('x', s['peak_rss_mb'])} | "
            f"{format_figure('x', s['rss_increase_mb'])} | {format_figure('x', results['compile_s'].get(label))} | "
            f"{s['runs']}{'' if s['agreed'] else ' *'} | {s['load_before']:.1f} -> {s['load_after']:.1f} |")
    if results["real"]:
        names = list(next(iter(results["real"].values())))
        lines += ["", "## Real TUM recordings: share of estimates within 1 px of the known disparity", "",
                  "Known: " + "; ".join(f"{n}: {', '.join(f'{d:g}' for d in REAL_DISPARITIES[n])} px" for n in names)
                  + " (movingPersons: about 13 px, from overlaying windows; an approximate reference).", "",
                  "| matcher | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
        for label, shares in results["real"].items():
            lines.append(f"| {label} | " + " | ".join(format_figure("bad1", shares[n]) for n in names) + " |")
    if results["distance"]:
        tests = [f"{round(z * 100)}cm" for z in TEST_DISTANCES]
        lines += ["", "## Distance: d = a/Z - c fitted at 50 and 150 cm, error at other distances (cm)", "",
                  "Each matcher's median disparity on a 1-arm recording at 50 and 150 cm fits a and c; the "
                  "error is the distance that fit gives from the median at 75, 100, 125 cm minus the arm's "
                  "nominal distance.", "",
                  "| matcher | a (px m) | c (px) | " + " | ".join(tests) + " |",
                  "|---|---:|---:|" + "---:|" * len(tests)]
        for label, d in results["distance"].items():
            if "error" in d:
                lines.append(f"| {label} | - | - | " + " | ".join("-" for _ in tests) + " |")
                continue
            lines.append(f"| {label} | {d['a']:.2f} | {d['c']:.2f} | "
                         + " | ".join(format_figure("x", d["error_cm"][t]) for t in tests) + " |")
    return "\n".join(lines) + "\n"


#: The files :func:`write_results` writes into its folder.
RESULT_FILES = ("results.json", "results.md")


def write_results(results: dict, folder: Path) -> tuple[Path, Path]:
    """Write ``results.json`` and ``results.md`` into ``folder`` (atomically)."""
    folder.mkdir(parents=True, exist_ok=True)
    json_path, md_path = (folder / name for name in RESULT_FILES)
    write_text_atomic(json_path, to_json(results, indent=1))
    write_text_atomic(md_path, bench_markdown(results))
    return json_path, md_path
