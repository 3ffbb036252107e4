"""The fused matcher beside dv-semidense and SGBM: accuracy at equal coverage, false rate, ablation, speed.

Recordings: 2 s clips of four presets, the motorcycle scene, one arm at 1 m with both sensors' thresholds
scaled by k (event density), and the real file Fan_disp8.dat (share within 1 px of 8). All matchers run
through the same streaming path (40 ms packets) on the same events; fused's matches are also scored after
keeping only its most certain ones, as many as each peer's coverage allows (issue 17). Speed: one core,
2arms-50cm, and a 346x260 recording at about 1 M events/s; the load average is printed beside each figure.
Writes ``bench/results/fused.md`` (``-o DIR``: ``DIR/fused.md``; ``--no-write``: print only); with ``--suite``
``fused-suite.md`` instead, so that the two comparisons (and the ablation of the default run) stand side by side.

``--suite``: the peer comparison over the robustness suite v1 (29 recordings of 2.5 s, cached by
:func:`cvstereo.simulate.suite_recordings`) and the motorcycle clip instead of the presets and density clips,
with issue 17's four criteria (:func:`criteria`). The peers' figures do not depend on fused, so they are kept in
``DIR/fused-peers.json`` and reused by the next run with the same ``-o``.

Run::

    .venv/bin/python bench/bench_fused.py             # everything (about 10 minutes on a shared machine)
    .venv/bin/python bench/bench_fused.py --quick     # fewer recordings, no ablation
    .venv/bin/python bench/bench_fused.py --suite -o /tmp/fused --no-speed   # issue 17 over the suite
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
os.environ["NUMBA_NUM_THREADS"] = "1"
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from cvstereo.benchmark.timing import MAX_RUNS, load_average, measure  # noqa: E402
from cvstereo.evaluation.metrics import evaluate, match_truth  # noqa: E402
from cvstereo.matchers.fused.matcher import FusedMatcher  # noqa: E402
from cvstereo.matchers.fused.params import FusedParams  # noqa: E402
from cvstereo.matchers.registry import available_methods, parse_param_strings  # noqa: E402
from cvstereo.model.matches import concat_matches  # noqa: E402
from cvstereo.run import match  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "fused.md"
SUITE_OUT_NAME = "fused-suite.md"
SECONDS = 2.0
PRESETS = ("1arm-50cm", "1arm-100cm", "2arms-100cm", "2arms-150cm")
DENSITY_K = (0.5, 1.0, 2.0, 3.0)
PACKET_US = 40_000
#: Both sensors' thresholds times this in the 346x260 speed recording: about 1 M events/s (issue 17's target).
#: (2 s clips, simulator of 2026-12-01: x0.07 gave 8.7 M events/s, x0.3 1.65 M, x0.43 1.02 M, x0.65 0.56 M.)
BIG_THRESHOLD_K = 0.43
#: Fused parameters of every run of this bench (``--set NAME=VALUE``), under each run's own overrides.
FUSED_SET: dict = {}
#: The recordings of the ablation table (a subset, to keep the run short).
ABLATION_RECORDINGS = ("1arm-50cm", "2arms-150cm", "motorcycle", "1arm-100cm thr x3.0")
#: Ablation rows: name -> parameter overrides of fused.
ABLATION = {
    "full": {},
    "no temporal coherence": {"temporal_weight": 0.0},
    "no left-right check": {"lr_tolerance": -1},
    "no filling of left-right failures": {"fill_radius": 0},
    "no occlusion test": {"occlusion_margin": -1},
    "no partner test": {"border_rows": -1},
    "no row tolerance": {"row_tolerance": 0},
    "no sub-pixel": {"subpixel": False},
    "no noise filter": {"min_neighbours": 1},
    "SGM rows only (2 paths)": {"sgm_paths": 2},
    "no SGM (winner of pixel cost)": {"sgm_paths": 0},
    "no support square": {"support_radius": 0},
}


def _sim(name, make):
    from cvstereo.io.npz import read_recording_npz, write_recording_npz
    from cvstereo.simulate.presets import default_cache_dir

    path = default_cache_dir() / f"fused-{name}.npz"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        write_recording_npz(path, make())
    return read_recording_npz(path)


def dense_rig(rig, k: float):
    """``rig`` with both sensors' ON and OFF thresholds times ``k`` (and the threshold floor with them)."""
    def scaled(sensor):
        return dataclasses.replace(sensor, on_threshold=sensor.on_threshold * k, off_threshold=sensor.off_threshold * k,
                                   min_threshold=min(sensor.min_threshold, sensor.min_threshold * k))
    return dataclasses.replace(rig, left=scaled(rig.left), right=scaled(rig.right))


def recordings(quick: bool) -> dict:
    """Name -> Recording of every simulated clip (cached)."""
    from cvstereo.io.npz import read_recording_npz
    from cvstereo.simulate import ArmsScene, simulate
    from cvstereo.simulate.presets import cached_preset
    from cvstereo.simulate.rig import Rig

    recs = {n: read_recording_npz(cached_preset(n, seconds=SECONDS)) for n in (PRESETS[:2] if quick else PRESETS)}
    recs["motorcycle"] = _motorcycle()
    for k in (DENSITY_K[::3] if quick else DENSITY_K):
        if k == 1.0:
            continue
        rig = dense_rig(Rig(), k)
        recs[f"1arm-100cm thr x{k}"] = _sim(f"1arm-100cm-thr{k}-{SECONDS}s", lambda rig=rig: simulate(
            ArmsScene(arms=1, distance_m=1.0), rig=rig, seconds=SECONDS, seed=0))
    return recs


def _motorcycle():
    """The motorcycle clip of both comparisons (cached)."""
    from cvstereo.simulate import MotorcycleScene, simulate

    return _sim(f"motorcycle-{SECONDS}s", lambda: simulate(MotorcycleScene(), seconds=SECONDS, seed=0))


def suite_recordings(only: list[str] | None = None) -> dict:
    """Name -> Recording of the robustness suite v1 (its own 2.5 s; cached) and the motorcycle clip."""
    from cvstereo.io.npz import read_recording_npz
    from cvstereo.simulate import suite_recordings as suite

    names = None if only is None else [n for n in only if n != "motorcycle"]
    recs = {n: read_recording_npz(p) for n, p in suite("robustness", only=names)} if names != [] else {}
    if only is None or "motorcycle" in only:
        recs["motorcycle"] = _motorcycle()
    return recs


def run_fused(rec, **params):
    """Fused over a recording through feed/flush (40 ms packets): (matches, uncertainty, meta, (wall s, CPU s)).

    The CPU time of this process is the fairer speed figure on a shared machine (the wall time counts the
    time other processes held the core)."""
    # from_variant scales the default disparity range with the sensor width, as the pipeline does for the peers.
    m = FusedMatcher.from_variant(resolution=rec.resolution, **{**FUSED_SET, **params})
    start, cpu = time.perf_counter(), time.process_time()
    parts = [m.feed(p.left, p.right, until=p.until) for p in rec.packets(PACKET_US)]
    parts.append(m.flush())
    elapsed = (time.perf_counter() - start, time.process_time() - cpu)
    return concat_matches(parts), m.take_uncertainty(), m.describe(), elapsed


def most_certain(matches, uncertainty, rec, meta, coverage: float):
    """Fused's most certain matches whose coverage is at most ``coverage`` (keeping the order)."""
    order = np.argsort(uncertainty, kind="stable")
    has = np.isfinite(match_truth(rec, matches, anchor="window", window_us=meta["window_us"])[order])
    full = evaluate(rec, matches, meta)
    if not full["coverage"] or coverage >= full["coverage"]:
        return matches
    # Anchors are distinct (pixel, window) cells: coverage grows by one cell per match with truth.
    n_truth_needed = int(np.floor(coverage / full["coverage"] * np.count_nonzero(has)))
    keep_n = int(np.searchsorted(np.cumsum(has), n_truth_needed, side="right"))
    keep = np.sort(order[:keep_n])
    return matches[keep]


def load_avg() -> str:
    return f"{load_average():.2f}"


def peers() -> list[str]:
    return [m for m in ("sgbm", "dv-semidense") if m in available_methods()]


def _figures(f: dict) -> dict:
    """The figures the tables use, as plain floats (JSON-safe)."""
    return {k: float(f[k]) for k in ("coverage", "bad2", "false_rate", "matches")}


def peer_figures(rec, name: str, peer: str, cache: dict | None) -> dict:
    """A peer's figures on a recording, from ``cache`` (name -> peer -> figures, updated) when it has them."""
    key = f"{name} {rec.left.size} {rec.right.size}"  # a regenerated recording has other event counts
    if cache is not None and peer in cache.get(key, {}):
        return cache[key][peer]
    f = _figures(evaluate(rec, match(rec, method=peer, packet_us=PACKET_US)))
    if cache is not None:
        cache.setdefault(key, {})[peer] = f
    return f


def accuracy_section(recs, peer_cache: dict | None = None, clips: str = "2 s clips") -> tuple[str, dict]:
    lines = [f"## Accuracy ({clips}; window anchors at the left camera's event pixels)", "",
             "bad2 = share of matches with error > 2 px, false = share of matches on noise or background "
             "(evaluation.md). `fused @ peer coverage`: fused run with `max_uncertainty=1` (every winner, the "
             "left-right inconsistent ones ranked last), keeping its most certain matches down to the peer's "
             "coverage (all of them when the peer covers more).", "",
             "| recording | method | coverage | bad2 | false | matches | fused bad2 @ peer coverage | load |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    summary = {}
    for name, rec in recs.items():
        fm, _, meta, _ = run_fused(rec)
        ranked, unc, _, _ = run_fused(rec, max_uncertainty=1.0)
        f_full = _figures(evaluate(rec, fm, meta))
        rows = {"fused": f_full}
        lines.append(f"| {name} | fused | {f_full['coverage']:.1%} | {f_full['bad2']:.1%} | "
                     f"{f_full['false_rate']:.1%} | {f_full['matches']:.0f} | - | {load_avg()} |")
        for peer in peers():
            pf = peer_figures(rec, name, peer, peer_cache)
            ff = _figures(evaluate(rec, most_certain(ranked, unc, rec, meta, pf["coverage"]), meta))
            rows[peer] = pf
            rows[f"fused@{peer}"] = ff
            lines.append(f"| {name} | {peer} | {pf['coverage']:.1%} | {pf['bad2']:.1%} | {pf['false_rate']:.1%} | "
                         f"{pf['matches']:.0f} | {ff['bad2']:.1%} at {ff['coverage']:.1%} | {load_avg()} |")
        summary[name] = rows
        print("\n".join(lines[-3:]), flush=True)
    return "\n".join(lines), summary


def _beats(fused: dict, peer: dict) -> bool:
    """Fused's bad2 below the peer's, or both without a single bad match (nothing left to beat)."""
    return _bad2(fused) < _bad2(peer) or _bad2(fused) == _bad2(peer) == 0.0


def _bad2(f: dict) -> float:
    """bad2, counting a result without matches as 1 (bench_robustness's rule: silence counts against it)."""
    return 1.0 if not f["matches"] or np.isnan(f["bad2"]) else f["bad2"]


def criteria(summary: dict) -> dict:
    """Issue 17's "done when" over the recordings of ``summary`` (name -> rows of :func:`accuracy_section`).

    Returns
    -------
    dict
        ``median`` peer -> (median fused bad2 at the peer's coverage, the peer's median bad2); ``better``
        (recordings where fused at each peer's coverage has a lower bad2 than that peer, for both peers; a
        tie counts only at bad2 = 0), ``margin`` (the largest ``fused bad2 at the better peer's coverage - that
        peer's bad2``) and where it is, ``false`` (recordings where fused's own false rate is at most the lower
        peer's) and the medians of those false rates, ``n`` recordings.
    """
    ps = [p for p in peers() if all(p in rows for rows in summary.values())]
    out = {"n": len(summary), "median": {}, "better": 0, "margin": -np.inf, "margin_at": "", "false": 0}
    for p in ps:
        out["median"][p] = (statistics.median(_bad2(r[f"fused@{p}"]) for r in summary.values()),
                            statistics.median(_bad2(r[p]) for r in summary.values()))
    fused_false, low_false = [], []
    for name, rows in summary.items():
        out["better"] += all(_beats(rows[f"fused@{p}"], rows[p]) for p in ps)
        best = min(ps, key=lambda p: _bad2(rows[p]))
        margin = _bad2(rows[f"fused@{best}"]) - _bad2(rows[best])
        if margin > out["margin"]:
            out["margin"], out["margin_at"] = margin, name
        low = min(rows[p]["false_rate"] for p in ps)
        out["false"] += rows["fused"]["false_rate"] <= low
        fused_false.append(rows["fused"]["false_rate"])
        low_false.append(low)
    out["false_median"] = (statistics.median(fused_false), statistics.median(low_false))
    return out


def verdict_section(summary: dict) -> str:
    """Issue 17's "done when" on these recordings: per recording fused against each peer at the peer's
    coverage, then the four criteria (:func:`criteria`)."""
    lines = ["## Against the targets (issue 17)", "",
             "| recording | fused bad2 (own cov.) | better peer bad2 | fused bad2 @ SGBM cov. | SGBM bad2 | "
             "fused bad2 @ dv cov. | dv bad2 | better than both | fused false | lower peer false |",
             "|---|---:|---:|---:|---:|---:|---:|:-:|---:|---:|"]
    for name, rows in summary.items():
        ps = [p for p in peers() if p in rows]
        cells = [f"{_bad2(rows['fused']):.1%}", f"{min(_bad2(rows[p]) for p in ps):.1%}"]
        for p in ("sgbm", "dv-semidense"):
            cells += [f"{_bad2(rows[f'fused@{p}']):.1%}", f"{_bad2(rows[p]):.1%}"] if p in rows else ["-", "-"]
        beat = all(_beats(rows[f"fused@{p}"], rows[p]) for p in ps)
        cells += ["yes" if beat else "**no**", f"{rows['fused']['false_rate']:.1%}",
                  f"{min(rows[p]['false_rate'] for p in ps):.1%}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    c = criteria(summary)
    n = c["n"]
    lines += ["", "| criterion | target | measured | met |", "|---|---|---|:-:|"]
    for p, (fused_med, peer_med) in c["median"].items():
        lines.append(f"| median bad2 at {p}'s coverage | below {p}'s | {fused_med:.2%} vs {peer_med:.2%} | "
                     f"{'yes' if fused_med < peer_med else 'no'} |")
    lines += [f"| recordings better than both peers | >= 80 % | {c['better']}/{n} ({c['better'] / n:.0%}) | "
              f"{'yes' if c['better'] >= 0.8 * n else 'no'} |",
              f"| worst margin against the better peer | <= 0.02 | {c['margin']:+.3f} ({c['margin_at']}) | "
              f"{'yes' if c['margin'] <= 0.02 else 'no'} |",
              f"| false rate at most the lower peer's | every recording | {c['false']}/{n} (medians "
              f"{c['false_median'][0]:.2%} vs {c['false_median'][1]:.2%}) | {'yes' if c['false'] == n else 'no'} |"]
    return "\n".join(lines)


def ablation_section(recs, summary) -> str:
    recs = {n: r for n, r in recs.items() if n in ABLATION_RECORDINGS}
    names = list(recs)
    head = "| variant | " + " | ".join(f"{n}" for n in names) + " |"
    lines = ["## Ablation (fused with one part off)", "",
             "Each cell: bad2 / coverage / false rate of the default output, then bad2 at SGBM's coverage (the "
             "ranking run, `max_uncertainty=1`). Without the left-right check every winner is output; the "
             "filling only changes left-right failures, so it shows at SGBM's coverage only.", "", head,
             "|---|" + "---:|" * len(names)]
    for label, over in ABLATION.items():
        cells = []
        for name, rec in recs.items():
            fm, _, meta, _ = run_fused(rec, **over)
            f = evaluate(rec, fm, meta)
            cell = f"{f['bad2']:.1%} / {f['coverage']:.1%} / {f['false_rate']:.1%}"
            if "sgbm" in summary.get(name, {}):
                ranked, unc, _, _ = run_fused(rec, **{**over, "max_uncertainty": 1.0})
                at = evaluate(rec, most_certain(ranked, unc, rec, meta, summary[name]["sgbm"]["coverage"]), meta)
                cell += f"; {at['bad2']:.1%}"
            cells.append(cell)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


def fan_section() -> str:
    from cvstereo.io import read_recording

    path = Path(os.environ.get("CVSTEREO_SHARED", "/work/shared")) / "data" / "tum-stereo" / "Fan_disp8.dat"
    if not path.exists():
        return "## Fan_disp8\n\n(file not found)"
    rec = read_recording(path)
    lines = ["## Fan_disp8.dat (real; nominal disparity 8 px)", "",
             "| method | estimates | within 1 px of 8 |", "|---|---:|---:|"]
    results = {"fused": run_fused(rec)[0], "fused, max_uncertainty=1": run_fused(rec, max_uncertainty=1.0)[0]}
    for peer in peers():
        results[peer] = match(rec, method=peer, packet_us=PACKET_US).matches
    for name, m in results.items():
        within = float(np.mean(np.abs(m["disparity"] - 8.0) <= 1.0)) if m.size else float("nan")
        lines.append(f"| {name} | {m.size} | {within:.1%} |")
    return "\n".join(lines)


def dense_346x260():
    """The speed recording at 346x260: two arms at 50 cm, thresholds x BIG_THRESHOLD_K, about 1 M events/s (cached;
    bench/bench_threads.py times it too)."""
    from cvstereo.simulate import ArmsScene, simulate
    from cvstereo.simulate.rig import Rig

    return _sim(f"arms-346x260-thr{BIG_THRESHOLD_K}-{SECONDS}s", lambda: simulate(
        ArmsScene(arms=2, distance_m=0.5), rig=dense_rig(Rig(resolution=(346, 260), focal_px=446.0), BIG_THRESHOLD_K),
        seconds=SECONDS, seed=0))


def speed_section(quick: bool) -> str:
    from cvstereo.io.npz import read_recording_npz
    from cvstereo.simulate.presets import cached_preset

    lines = ["## Speed (one core, CPU time: runs until two agree within 10 %, cvstereo.benchmark.timing; "
             "load average of the machine's 2 cores before -> after beside; the 346x260 "
             f"recording: two arms at 50 cm, thresholds x {BIG_THRESHOLD_K})", "",
             "| recording | events/s of the recording | x real time on CPU time (wall) | runs, load |",
             "|---|---:|---:|---:|"]
    rec = read_recording_npz(cached_preset("2arms-50cm", seconds=SECONDS))
    big = dense_346x260()
    for name, r in (("2arms-50cm", rec), ("2 arms 346x260", big)):
        walls = []

        def one_run(r=r, walls=walls) -> float:
            wall, cpu = run_fused(r)[3]
            walls.append(wall)
            return cpu  # the figure: CPU time (the wall time counts other processes' turns on the core)

        timing = measure(one_run, max_runs=2 if quick else MAX_RUNS)
        cpu, wall = timing.seconds, min(walls)
        rate = (r.left.size + r.right.size) / r.duration_s
        lines.append(f"| {name} {r.resolution[0]}x{r.resolution[1]} | {rate:,.0f} | {r.duration_s / cpu:.1f}x "
                     f"(wall {r.duration_s / wall:.1f}x) | {timing.note()} |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--suite", action="store_true", help="the robustness suite v1 + motorcycle (issue 17)")
    ap.add_argument("--only", default=None, metavar="NAME,...", help="with --suite: only these recordings")
    ap.add_argument("-o", "--output", default=str(OUT.parent),
                    help="folder of fused.md / fused-suite.md (default bench/results)")
    ap.add_argument("--no-write", action="store_true", help="print only")
    ap.add_argument("--no-speed", action="store_true", help="skip the speed section")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a fused parameter for every run (repeatable), e.g. --set fill_radius=8")
    args = ap.parse_args(argv)
    FUSED_SET.update(parse_param_strings(FusedParams, args.set))  # typed and checked, as the CLI's --param
    cv2.setNumThreads(1)
    out = Path(args.output)
    peer_path = out / "fused-peers.json"
    peer_cache = None
    if args.suite:
        recs = suite_recordings(args.only.split(",") if args.only else None)
        peer_cache = json.loads(peer_path.read_text()) if peer_path.exists() else {}
    else:
        recs = recordings(args.quick)
    parts = ["# fused beside SGBM and dv-semidense", "",
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; peers: {', '.join(peers())}"
             + (f"; fused with {FUSED_SET}" if FUSED_SET else "") + ".", ""]
    clips = "robustness suite v1 (2.5 s) and the motorcycle (2 s)" if args.suite else "2 s clips"
    text, summary = accuracy_section(recs, peer_cache, clips)
    if peer_cache is not None and not args.no_write:
        out.mkdir(parents=True, exist_ok=True)
        peer_path.write_text(json.dumps(peer_cache, indent=1))
    parts += [text, "", verdict_section(summary), ""]
    print(parts[-2], flush=True)
    parts += [fan_section(), ""]
    print(parts[-2], flush=True)
    if not (args.quick or args.suite):
        parts += [ablation_section(recs, summary), ""]
    if not args.no_speed:
        parts += [speed_section(args.quick), ""]
    if not args.no_write:
        out.mkdir(parents=True, exist_ok=True)
        path = out / (SUITE_OUT_NAME if args.suite else OUT.name)
        path.write_text("\n".join(parts))
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
