"""fused against SGBM and dv-semidense on one half of the generalization suite v2 (issue 24 item 2's criteria).

Run::

    .venv/bin/python bench/bench_fusedgen.py --half tune --sizes 128x128,240x180 --tag try1 --set p1=2
    .venv/bin/python bench/bench_fusedgen.py --half tune --extra --tag extra   # 48 more tuning draws
    .venv/bin/python bench/bench_fusedgen.py --half eval --tag final      # once per candidate, at the end
    .venv/bin/python bench/bench_fusedgen.py --table "eval=OUT/fusedgen-eval-final.json"   # markdown tables

The tuning half goes through :func:`cvstereo.simulate.tuning_recordings` and every recording through
:func:`cvstereo.simulate.require_tuning`: what is tried here never sees the evaluation half unless ``--half eval``
is given. Fused runs once per recording with ``max_uncertainty=1``: its default output is the answers of
uncertainty at most 0.5 of that run (the prior and the occlusion test use the consistent answers only, so the two
are the same matches), and at a peer's coverage it keeps its most certain answers (``bench_fused.most_certain``).
The peers' figures do not depend on fused: they are kept in ``OUT/fusedgen-peers.json`` (by recording, event
counts and the peer's disparity range) and reused. Writes ``OUT/fusedgen-HALF-TAG.json`` and prints the table:
per recording and per family, fused's bad2 at each peer's coverage beside the peer's, and the issue's criteria:
the share of recordings where fused at parity beats both peers, the medians, the worst margin over the better
peer, and fused's default output (median bad2 and coverage) beside the peers'.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from bench_fused import most_certain

from cvstereo.evaluation.metrics import evaluate
from cvstereo.io.npz import read_recording_npz
from cvstereo.matchers.fused.params import FusedParams
from cvstereo.matchers.registry import matcher_class, parse_param_strings
from cvstereo.run import match
from cvstereo.simulate import load_suite, require_tuning, suite_recordings, tuning_recordings

PEERS = ("sgbm", "dv-semidense")
#: Fused's default cut of its ranked run (FusedParams.max_uncertainty's default: the consistent answers).
DEFAULT_CUT = 0.5
#: How much worse than the better peer fused may be on any recording (issue 24).
MARGIN = 0.02


def _bad2(f: dict) -> float:
    """bad2 with silence counted against the method (bench_robustness's rule)."""
    return f["bad2"] if f["coverage"] and f["bad2"] is not None else 1.0


def _figures(f: dict) -> dict:
    return {k: (None if f[k] is None else float(f[k])) for k in ("coverage", "bad2", "false_rate", "matches")}


def peer_figures(name: str, rec, cache: dict) -> dict:
    """Each peer's figures on ``rec`` (from ``cache`` when it has them for this recording and range)."""
    out = {}
    for peer in PEERS:
        rng = matcher_class(peer).params_for(resolution=rec.resolution).max_disparity
        key = f"{name} {rec.left.size} {rec.right.size} {peer} d{rng}"
        if key not in cache:
            cache[key] = _figures(evaluate(rec, match(rec, method=peer)))
        out[peer] = cache[key]
    return out


def fused_figures(rec, params: dict) -> dict:
    """Fused's default output and its bad2 at each peer's coverage (filled in by the caller)."""
    start = time.process_time()
    result = match(rec, method="fused", **{**params, "max_uncertainty": 1.0})
    cpu = time.process_time() - start
    unc = result.arrays["uncertainty"]
    default = result.matches[unc <= DEFAULT_CUT]
    return {"result": result, "default": _figures(evaluate(rec, default, result.meta)), "cpu_s": cpu}


def criteria(rows: list[dict]) -> dict:
    """The issue's criteria over ``rows`` (one per recording)."""
    beats = [all(r[f"at_{p}"] < _bad2(r[p]) for p in PEERS) for r in rows]
    margin = [max(r[f"at_{p}"] - _bad2(r[p]) for p in PEERS) for r in rows]
    med = {p: statistics.median(_bad2(r[p]) for r in rows) for p in PEERS}
    return {"recordings": len(rows), "beats_both": sum(beats),
            "worst_margin": max(margin), "over_margin": sum(m > MARGIN for m in margin),
            **{f"median_at_{p}": statistics.median(r[f"at_{p}"] for r in rows) for p in PEERS},
            **{f"median_{p}": med[p] for p in PEERS},
            **{f"median_coverage_{p}": statistics.median(r[p]["coverage"] or 0.0 for r in rows) for p in PEERS},
            "median_default_bad2": statistics.median(_bad2(r["default"]) for r in rows),
            "median_default_coverage": statistics.median(r["default"]["coverage"] or 0.0 for r in rows)}


def summary_lines(title: str, summary: dict) -> list[str]:
    """A run's criteria per family (and all) as a markdown table."""
    lines = [f"### {title}", "",
             "| family | recordings | fused better than both at parity | worst margin over the better peer | "
             "fused @ sgbm | sgbm | fused @ dv-semidense | dv-semidense | fused default bad2 (coverage) | "
             "dv-semidense coverage |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for fam, c in summary.items():
        lines.append(f"| {fam} | {c['recordings']} | {c['beats_both']} | {c['worst_margin']:+.3f} | "
                     f"{c['median_at_sgbm']:.3f} | {c['median_sgbm']:.3f} | {c['median_at_dv-semidense']:.3f} | "
                     f"{c['median_dv-semidense']:.3f} | {c['median_default_bad2']:.3f} "
                     f"({c['median_default_coverage']:.2f}) | {c['median_coverage_dv-semidense']:.2f} |")
    return lines


def recording_lines(rows: list[dict]) -> list[str]:
    """Per recording: fused's default output, its bad2 at each peer's coverage beside the peer's."""
    lines = ["| recording | fused coverage / bad2 | fused @ sgbm | sgbm coverage / bad2 | fused @ dv-semidense | "
             "dv-semidense coverage / bad2 | better than both |", "|---|---:|---:|---:|---:|---:|:---:|"]
    for r in rows:
        beats = all(r[f"at_{p}"] < _bad2(r[p]) for p in PEERS)
        lines.append(f"| {r['name']} | {r['default']['coverage']:.2f} / {_bad2(r['default']):.3f} | "
                     + " | ".join(f"{r[f'at_{p}']:.3f} | {r[p]['coverage']:.2f} / {_bad2(r[p]):.3f}" for p in PEERS)
                     + f" | {'yes' if beats else 'no'} |")
    return lines


def merge(paths: list[Path]) -> dict:
    """One run from the JSON files of runs over parts of a half (same parameters), criteria recomputed."""
    runs = [json.loads(p.read_text()) for p in paths]
    rows = [r for run in runs for r in run["rows"]]
    families = sorted({r["family"] for r in rows})
    summary = {fam: criteria([r for r in rows if r["family"] == fam]) for fam in families}
    summary["all"] = criteria(rows)
    return {"params": runs[0]["params"], "load": max(run["load"] for run in runs), "rows": rows, "summary": summary,
            "date": max(run["date"] for run in runs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--half", choices=("tune", "eval"), default="tune")
    parser.add_argument("--sizes", default=None, metavar="WxH,...", help="only these sensor sizes")
    parser.add_argument("--only", default=None, metavar="NAME,...", help="only these recordings")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="fused parameter")
    parser.add_argument("--extra", action="store_true",
                        help="the extra tuning draws of bench_row_field.py (48 more tuning recordings) instead of "
                             "the suite's tuning half")
    parser.add_argument("--tag", default="run")
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--table", nargs="+", metavar="TITLE=RUN.json[+RUN.json]", default=None,
                        help="print the markdown tables of earlier runs (parts of a half joined by +) and exit")
    args = parser.parse_args()
    if args.table:
        for item in args.table:
            title, _, files = item.partition("=")
            run = merge([Path(f) for f in files.split("+")])
            head = f"{title} ({run['date']}, load {run['load']:.1f}, fused {json.dumps(run['params'])})"
            print("\n".join([*summary_lines(head, run["summary"]), "", "Per recording:", "",
                             *recording_lines(run["rows"])]) + "\n")
        return
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    params = parse_param_strings(FusedParams, args.set)
    if args.extra and args.half != "tune":
        parser.error("--extra draws are tuning recordings: --half tune")
    if args.extra:
        from bench_row_field import extra_tuning_recordings

        paths = dict(extra_tuning_recordings())
        family = {n: n.split("-")[0] for n in paths}
    else:
        family = {r.name: r.family for r in load_suite("generalization").recordings if r.half == args.half}
    wanted = [n for n in family if (args.sizes is None or n.rsplit("-", 1)[1] in args.sizes.split(","))
              and (args.only is None or n in args.only.split(","))]
    if not args.extra:
        source = tuning_recordings if args.half == "tune" else suite_recordings
        paths = dict(source("generalization", only=wanted) if args.half == "tune"
                     else source("generalization", half="eval", only=wanted))
    peers_path = out / "fusedgen-peers.json"
    cache = json.loads(peers_path.read_text()) if peers_path.exists() else {}
    rows = []
    load = os.getloadavg()[0]
    for name in wanted:
        if args.half == "tune":
            require_tuning(paths[name])
        rec = read_recording_npz(paths[name])
        row = {"name": name, "family": family[name], **peer_figures(name, rec, cache)}
        peers_path.write_text(json.dumps(cache, indent=1))
        f = fused_figures(rec, params)
        res = f.pop("result")
        for p in PEERS:
            kept = most_certain(res.matches, res.arrays["uncertainty"], rec, res.meta, row[p]["coverage"] or 0.0)
            g = evaluate(rec, kept, res.meta)
            row[f"at_{p}"] = g["bad2"] if g["matches"] and g["bad2"] is not None else 1.0
        row.update(f)
        rows.append(row)
        print(f"{name:26s} fused {row['default']['coverage']:.2f}/{_bad2(row['default']):.3f}  "
              + "  ".join(f"@{p} {row[f'at_{p}']:.3f} vs {_bad2(row[p]):.3f} ({row[p]['coverage']:.2f})"
                          for p in PEERS) + f"  cpu {f['cpu_s']:.1f}s", flush=True)
    families = sorted({r["family"] for r in rows})
    summary = {fam: criteria([r for r in rows if r["family"] == fam]) for fam in families}
    summary["all"] = criteria(rows)
    print("\n".join(summary_lines(f"{args.half} {args.tag} {json.dumps(params)} load {load:.2f} -> "
                                  f"{os.getloadavg()[0]:.2f}", summary)))
    (out / f"fusedgen-{args.half}-{args.tag}.json").write_text(json.dumps(
        {"params": params, "load": load, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
         "rows": rows, "summary": summary}, indent=1, default=lambda v: float(v) if np.isscalar(v) else str(v)))


if __name__ == "__main__":
    main()
