"""Baseline of the generalization suite v2: every method's default on both halves, per family; the border figure.

Run: ``python bench/bench_generalization.py [--workers 1] [-o bench/results]`` (``--seconds 0.2 --only A,B -o
/tmp/g`` for a quick look). Every cell (recording x method x parameter set) runs through ``cvstereo.sweep`` and
is kept in ``OUT/generalization-cells/``, so a second run only computes what changed (a changed package source
recomputes everything: the cell key hashes it). Writes ``generalization.md`` and ``generalization.json``:

- per recording: coverage / bad2 / false rate of the thesis' five matchers under ``thesis`` and ``adaptive``,
  StereoBM, SGBM, dv-semidense and fused (evaluation.md);
- per family and half: the medians (a recording without matches counts as bad2 = 1 against the method, as in
  ``bench_robustness.py``), and per half over all families;
- fused at each peer's coverage: fused run with ``max_uncertainty=1`` and cut to its most certain matches at the
  peer's coverage (``bench_fused.most_certain``, the mechanism of ``bench_fused.py --suite``), beside the peer;
- the border figure (issue 24): a fronto-parallel textured plane at disparity D filling the view (an ideal rig,
  the thesis' sensors): the share of each matcher's answers anchored where the true partner lies outside the
  other image (left x < D, right x > W - 1 - D), beside the share of the events there. On every suite
  recording the same share is reported from the truth (``outside``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from bench_fused import most_certain  # the mechanism of fused's bad2 at a peer's coverage

from cvstereo.evaluation.metrics import evaluate, match_truth
from cvstereo.matchers.registry import available_methods
from cvstereo.simulate import FamilyScene, Rig, load_suite, suite_recordings
from cvstereo.simulate.presets import default_cache_dir
from cvstereo.simulate.recipe import Recipe
from cvstereo.sweep import Grid, run_sweep

THESIS_METHODS = ("frame", "frame-area", "event-time", "event-area", "event-vector")
PEERS = ("stereobm", "sgbm", "dv-semidense", "fused")
#: The peers fused is compared with at their coverage (issue 17's pair).
COVERAGE_PEERS = ("sgbm", "dv-semidense")
SETS = ("thesis", "adaptive")
#: The border planes: sensor sizes of the issue's textured pan, the plane's disparity an eighth of the width.
BORDER_SENSORS = ((128, 128), (346, 260))
BORDER_FRACTION = 1 / 8


@dataclass(frozen=True)
class BorderRecording(Recipe):
    """The border figure's recording: one textured plane at ``disparity_px`` filling the view, ideal rig."""

    suite: str
    name: str
    scene: FamilyScene
    rig: Rig
    seconds: float
    seed: int
    render_hz: float

    def label(self) -> dict:
        return {"name": self.suite, "recording": self.name, "family": "border", "half": "none",
                "disparity_px": self.scene.disparity_px}


def border_recordings(seconds: float) -> list[BorderRecording]:
    out = []
    for w, h in BORDER_SENSORS:
        rig = Rig().for_sensor((w, h)).ideal()  # d = f*B/Z exactly: the strip x < D has no partner
        d = round(w * BORDER_FRACTION)
        scene = FamilyScene("border", 7, (w, h), rig.focal_px, seconds, disparity_px=float(d))
        out.append(BorderRecording("generalization-border", f"border-{w}x{h}-d{d}", scene, rig, seconds, 7,
                                   max(100.0, scene.plan.image_speed_px_s / 0.5)))
    return out


def _cached(recipe: Recipe) -> Path:
    from cvstereo.io.npz import write_recording_npz

    path = default_cache_dir() / recipe.cache_name()
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        write_recording_npz(path, recipe.simulate())
    return path


def edge_figures(cell, recording, result) -> dict:
    """Sweep score: the share of answers (with truth) whose true partner lies outside the other camera's image,
    and the share of all answers of 0 px (a matcher's answer where it has none)."""
    m = result.matches
    if not m.size:
        return {"outside": None, "zero": None}
    truth = match_truth(recording, m, anchor=result.meta["anchor"], window_us=result.meta["window_us"])
    width = recording.resolution[0]
    partner = np.where(m["camera"] == 0, m["x"] - truth, m["x"] + truth)
    has = np.isfinite(truth)
    outside = has & ((partner < -0.5) | (partner > width - 0.5))
    return {"outside": float(outside.sum() / max(int(has.sum()), 1)),
            "zero": float(np.mean(np.abs(m["disparity"]) < 0.5))}


def fused_at_peers(cell, recording, result) -> dict:
    """Sweep score of the fused cell run with ``max_uncertainty=1``: for each peer, the peer's coverage (the peer
    run here) and fused's bad2 and coverage when cut to its most certain matches at that coverage."""
    from cvstereo.run import match

    out = {}
    for peer in (p for p in COVERAGE_PEERS if p in available_methods()):
        coverage = evaluate(recording, match(recording, method=peer))["coverage"]
        kept = most_certain(result.matches, result.arrays["uncertainty"], recording, result.meta, coverage)
        f = evaluate(recording, kept, result.meta)
        out.update({f"{peer}_coverage": coverage, f"fused_bad2_at_{peer}": f["bad2"] if f["matches"] else None,
                    f"fused_coverage_at_{peer}": f["coverage"]})
    return out


def _bad2(row: dict | None) -> float:
    """bad2 with silence counted against the method (bench_robustness's rule)."""
    if row is None or row["error"] is not None or not row["coverage"] or row["bad2"] is None:
        return 1.0
    return row["bad2"]


def _median(values) -> float:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else math.nan


def _cell(row: dict | None) -> str:
    if row is None:
        return "-"
    if row["error"] is not None:
        return "error"
    if not row["coverage"]:
        return "0"
    return f"{row['coverage']:.2f} / {row['bad2']:.2f} / {row['false_rate']:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--workers", type=int, default=1, help="local Dask workers (default 1: the machine is shared)")
    parser.add_argument("--only", default=None, metavar="NAME,...", help="only these suite recordings")
    parser.add_argument("--seconds", type=float, default=None, help="shorter clips (a quick look; not the baseline)")
    args = parser.parse_args()
    out = Path(args.output)
    suite = load_suite("generalization", seconds=args.seconds)
    paths = dict(suite_recordings("generalization", seconds=args.seconds, progress=True,
                                  only=args.only.split(",") if args.only else None))
    specs = {r.name: r for r in suite.recordings if r.name in paths}
    borders = border_recordings(args.seconds or suite.seconds)
    for b in borders:
        paths[b.name] = _cached(b)
    name_of = {os.fspath(p): n for n, p in paths.items()}
    recordings = list(name_of)
    installed = set(available_methods())
    peers = tuple(m for m in PEERS if m in installed)
    cells = [c for g in (Grid(THESIS_METHODS, (), (), SETS), Grid(peers)) for c in g.cells(recordings)]
    ranked = Grid(("fused",), (), (("max_uncertainty", (1.0,)),)).cells(
        [os.fspath(paths[n]) for n in specs]) if "fused" in installed else []
    load = os.getloadavg()[0]
    start = time.perf_counter()
    main_run = run_sweep(cells, out / "generalization-cells", workers=args.workers, progress=True,
                         score=edge_figures)
    fused_run = run_sweep(ranked, out / "generalization-cells", workers=args.workers, progress=True,
                          score=fused_at_peers)
    wall = time.perf_counter() - start
    by = {(name_of[r["recording"]], r["method"], r["param_set"]): r for r in main_run.rows}
    ranked_by = {name_of[r["recording"]]: r for r in fused_run.rows}
    columns = [(m, s) for m in THESIS_METHODS for s in SETS] + [(m, "default") for m in peers]
    heads = [f"{m} ({s})" if s != "default" else m for m, s in columns]
    lines = ["# Generalization suite v2: every method's default on both halves", "",
             f"{len(specs)} recordings of `cvstereo simulate --suite generalization` ({suite.seconds:g} s each; six "
             "scene families, sensors and rigs drawn per recording, a tuning and an evaluation half: "
             "cvstereo/simulate/suites/generalization_v2.toml) and the border planes. Each cell: coverage / bad2 / "
             "false rate (evaluation.md); `0`: no match. Method = its default variant under that set. "
             f"{len(cells) + len(ranked)} cells on {args.workers} Dask worker(s) in {wall:.0f} s (load {load:.2f} "
             f"before; {main_run.reused + fused_run.reused} cells from an earlier run, "
             f"{main_run.failed + fused_run.failed} failed). "
             f"Date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
             "", "## Per recording", "", "| recording | family | half | " + " | ".join(heads) + " |",
             "|---|---|---|" + "---|" * len(columns)]
    for name, spec in specs.items():
        lines.append(f"| {name} | {spec.family} | {spec.half} | "
                     + " | ".join(_cell(by.get((name, m, s))) for m, s in columns) + " |")
    summary = {}
    lines += ["", "## Per family and half: median bad2 (median coverage)", "",
              "A recording where a method answers nothing counts as bad2 = 1 against it.", "",
              "| family | half | " + " | ".join(heads) + " |", "|---|---|" + "---|" * len(columns)]
    groups = [(f, h) for f in suite.families for h in ("tune", "eval")] + [("all", "tune"), ("all", "eval")]
    for family, half in groups:
        names = [n for n, s in specs.items() if s.half == half and family in ("all", s.family)]
        if not names:
            continue
        cells_text = []
        for m, s in columns:
            rows = [by.get((n, m, s)) for n in names]
            fig = {"median_bad2": _median([_bad2(r) for r in rows]),
                   "median_coverage": _median([(r or {}).get("coverage") or 0.0 for r in rows]),
                   "median_false_rate": _median([(r or {}).get("false_rate") for r in rows]),
                   "median_outside": _median([(r or {}).get("outside") for r in rows]),
                   "recordings": len(names)}
            summary[f"{family}/{half}/{m}/{s}"] = fig
            cells_text.append(f"{fig['median_bad2']:.3f} ({fig['median_coverage']:.2f})")
        lines.append(f"| {family} | {half} | " + " | ".join(cells_text) + " |")
    lines += ["", "## fused at each peer's coverage (median bad2 per family and half)", "",
              "fused with `max_uncertainty=1`, its most certain matches kept down to the peer's coverage "
              "(bench_fused.py's `most_certain`), against the peer's own bad2.", "",
              "| family | half | " + " | ".join(f"fused @ {p} | {p}" for p in COVERAGE_PEERS)
              + " | recordings fused better than both |",
              "|---|---|" + "---:|---:|" * len(COVERAGE_PEERS) + "---:|"]
    for family, half in groups:
        names = [n for n, s in specs.items() if s.half == half and family in ("all", s.family) and n in ranked_by]
        if not names:
            continue
        cells_text, better = [], 0
        for n in names:
            r = ranked_by[n]
            better += all((r.get(f"fused_bad2_at_{p}") if r.get(f"fused_bad2_at_{p}") is not None else 1.0)
                          < _bad2(by.get((n, p, "default"))) for p in COVERAGE_PEERS)
        for p in COVERAGE_PEERS:
            at = _median([ranked_by[n].get(f"fused_bad2_at_{p}") for n in names])
            own = _median([_bad2(by.get((n, p, "default"))) for n in names])
            summary[f"{family}/{half}/fused@{p}"] = {"fused_median_bad2": at, "peer_median_bad2": own}
            cells_text += [f"{at:.3f}", f"{own:.3f}"]
        lines.append(f"| {family} | {half} | " + " | ".join(cells_text) + f" | {better}/{len(names)} |")
    lines += ["", "## The border figure", "",
              "A textured plane at disparity D filling the view (ideal rig, the thesis' sensors, the rig moving "
              "sideways): each matcher's share of answers anchored where the true partner lies outside the other "
              "image (left x < D or right x > W - 1 - D), beside the share of the events there; then the share of "
              "its answers that are 0 px.", "",
              "| recording | events in the strip | " + " | ".join(heads) + " |", "|---|---:|" + "---:|" * len(columns)]
    from cvstereo.io.npz import read_recording_npz

    border = {}
    for b in borders:
        rec = read_recording_npz(paths[b.name])
        w, d = rec.resolution[0], b.scene.disparity_px
        strip = (np.sum(rec.left["x"] < d) + np.sum(rec.right["x"] > w - 1 - d)) / (rec.left.size + rec.right.size)
        rows = {f"{m}/{s}": by.get((b.name, m, s)) for m, s in columns}
        border[b.name] = {"strip_event_share": float(strip),
                          **{k: {"outside": (r or {}).get("outside"), "zero": (r or {}).get("zero")}
                             for k, r in rows.items()}}
        shares = [(by.get((b.name, m, s)) or {}).get("outside") for m, s in columns]
        zeros = [(by.get((b.name, m, s)) or {}).get("zero") for m, s in columns]
        lines.append(f"| {b.name} | {strip:.1%} | " + " | ".join(
            "-" if v is None else f"{v:.1%} ({z:.1%} 0 px)" for v, z in zip(shares, zeros, strict=True)) + " |")
    out.mkdir(parents=True, exist_ok=True)
    (out / "generalization.md").write_text("\n".join(lines) + "\n")
    (out / "generalization.json").write_text(json.dumps(
        {"summary": summary, "border": border, "recordings": {n: s.label() for n, s in specs.items()},
         "rows": main_run.rows, "fused_at_peers": fused_run.rows}, indent=1, default=str))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
