"""Speed of the frame matchers on one core: frame-based (every variant), frame-area (both), OpenCV baselines.

Runs each matcher through ``calibration_free.match`` (the streaming path a user takes, its default 40 ms
packets) over the simulator's ``2arms-50cm`` preset when the simulator provides it, otherwise over a
synthetic stream of moving textured edges with a similar event rate (about 1.2 M events in 11 s, the
thesis' busiest recording).
Prints a table and writes ``bench/results/frame.json`` and ``frame.md``.

Targets (issue 4): frame-based >= 50x real time, frame-area >= 20x real time. The thesis' Matlab needed
8.23 s (frame-based) and 32.98 s (frame-area) for the 11 s recording.

Run::

    .venv/bin/python bench/bench_frame.py            # runs until two agree within 10 % (at most 6) per matcher
    .venv/bin/python bench/bench_frame.py --repeats 5 --synthetic
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

# The repository first: the editable install may list calibration_free as a namespace package, which a script
# run from bench/ would then import without its __init__.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

# One core: set before numba / OpenCV are imported.
os.environ["NUMBA_NUM_THREADS"] = "1"
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import cvstereo  # noqa: E402
from calibration_free import match  # noqa: E402
from cvstereo.benchmark.timing import Agreement  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from cvstereo.model.recording import Recording  # noqa: E402

PRESET = "2arms-50cm"
#: (method, variant, target x real time or None)
CASES = [
    ("frame", "shared", 50), ("frame", "separate", 50), ("frame", "on", 50), ("frame", "off", 50),
    ("frame-area", "gaussian", 20), ("frame-area", "no-gaussian", 20),
    ("stereobm", "default", None), ("sgbm", "default", None),
]
#: The thesis' Matlab run times on the 11 s 2-arms-50-cm recording (s), for the table.
THESIS_S = {("frame", "shared"): 8.23, ("frame", "separate"): 14.21, ("frame-area", "gaussian"): 32.98}


def synthetic_arms(seconds: float = 11.0, *, seed: int = 0) -> Recording:
    """Two textured bars ("arms") swinging sideways in front of the rig, as events of both cameras.

    Each bar has four vertical stripe edges; every pixel an edge crosses emits a few events per row (a random
    texture per row), ON or OFF by the edge's contrast and direction. The right camera sees the bars 28 and 26 px
    further left (about 50 cm), gets about 10 % more events, and both get background noise.

    Returns
    -------
    Recording
        About 1.2 M events in 11 s.
    """
    rng = np.random.default_rng(seed)
    dt_us = 1000
    steps = int(seconds * 1e6 // dt_us)
    t_step = np.arange(steps + 1) * dt_us
    bars = [  # centre x, amplitude, frequency (Hz), phase, rows, disparity
        (60.0, 30.0, 0.5, 0.0, (20, 110), 28),
        (80.0, 26.0, 0.45, 2.0, (10, 95), 26),
    ]
    offsets = np.array([0.0, 3.0, 7.0, 12.0])
    contrast = np.array([1, -1, 1, -1])
    cams = [[], []]
    for cx, amp, freq, phase, (y0, y1), disp in bars:
        rows = np.arange(y0, y1)
        texture = rng.uniform(0.6, 2.4, rows.size)  # mean events per crossing, per row
        pos = cx + amp * np.sin(2 * np.pi * freq * t_step / 1e6 + phase)
        for off, c in zip(offsets, contrast, strict=True):
            edge = pos + off
            lo, hi = np.floor(np.minimum(edge[:-1], edge[1:])), np.floor(np.maximum(edge[:-1], edge[1:]))
            moving_right = edge[1:] > edge[:-1]
            for step in np.flatnonzero(hi > lo):  # steps in which the edge crosses a pixel boundary
                cols = np.arange(lo[step] + 1, hi[step] + 1).astype(int)
                n = rng.poisson(np.tile(texture, cols.size))
                x = np.repeat(np.repeat(cols, rows.size), n)
                y = np.repeat(np.tile(rows, cols.size), n)
                t = t_step[step] + rng.integers(0, dt_us, x.size)
                p = np.full(x.size, int((c > 0) == moving_right[step]))
                for cam, shift in ((0, 0), (1, disp)):
                    keep = rng.random(x.size) < (0.91 if cam == 0 else 1.0)
                    cams[cam].append((t[keep], x[keep] - shift, y[keep], p[keep]))
    out = []
    for parts in cams:
        noise = int(seconds * 1500)
        parts.append((rng.integers(0, int(seconds * 1e6), noise), rng.integers(0, 128, noise),
                      rng.integers(0, 128, noise), rng.integers(0, 2, noise)))
        t, x, y, p = (np.concatenate([q[i] for q in parts]) for i in range(4))
        ok = (x >= 0) & (x < 128)
        order = np.argsort(t[ok], kind="stable")
        out.append(make_events(t[ok][order], x[ok][order], y[ok][order], p[ok][order]))
    return Recording(out[0], out[1], meta={"source": f"synthetic arms, {seconds:g} s, seed {seed}"})


def load_input(*, synthetic: bool, seconds: float) -> tuple[Recording, str]:
    """The 2arms-50cm preset if the simulator provides it, else the synthetic stream."""
    if not synthetic:
        try:
            from cvstereo.simulate import cached_preset
        except ImportError:
            pass
        else:
            from cvstereo.io.npz import read_recording_npz

            return read_recording_npz(cached_preset(PRESET, progress=True)), f"simulator preset {PRESET}"
    return synthetic_arms(seconds), "synthetic moving textured edges (simulator preset not available)"


def bench_case(rec: Recording, method: str, variant: str, repeats: int) -> dict:
    """Timed runs until two agree within 10 % (at most ``repeats``, :mod:`cvstereo.benchmark.timing`), after one warm-up
    run on the first second (numba, OpenCV); the faster of the agreeing pair, the median, the load."""
    match(rec.slice_time(None, rec.t_start + 1_000_000), method=method, variant=variant)
    agreement, cpu, n_matches = Agreement(max_runs=repeats), [], 0
    agreement.start()
    while not agreement.done:
        start, start_cpu = time.perf_counter(), time.process_time()
        result = match(rec, method=method, variant=variant)
        agreement.add(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        n_matches = len(result)
    timing = agreement.result()
    times, best = timing.all_seconds, timing.seconds
    events = rec.left.size + rec.right.size
    # CPU time of the (single-threaded) process as well: on a shared machine wall time also counts the waits.
    return {
        "method": method, "variant": variant, "best_s": best, "median_s": float(np.median(times)),
        "best_cpu_s": min(cpu), "x_realtime_cpu": rec.duration_s / min(cpu),
        "events_per_s": events / best, "x_realtime": rec.duration_s / best, "matches": n_matches,
        "mean_disparity": float(result.disparity.mean()) if n_matches else None,
        "runs": timing.runs, "agreed": timing.agreed, "load_before": timing.load_before,
        "load_after": timing.load_after,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=6, help="runs at most, until two agree within 10 %%")
    parser.add_argument("--synthetic", action="store_true", help="use the synthetic stream even if a preset exists")
    parser.add_argument("--seconds", type=float, default=11.0, help="length of the synthetic stream")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)

    rec, source = load_input(synthetic=args.synthetic, seconds=args.seconds)
    events = rec.left.size + rec.right.size
    print(f"input: {source}: {events} events in {rec.duration_s:.2f} s "
          f"({rec.left.size} left, {rec.right.size} right); one core; until two of at most {args.repeats} runs agree")
    rows = []
    for method, variant, target in CASES:
        row = bench_case(rec, method, variant, args.repeats)
        row["target_x"] = target
        row["thesis_s"] = THESIS_S.get((method, variant))
        rows.append(row)
        print(f"  {method:>10} {variant:<12} {row['best_s']:7.3f} s  {row['events_per_s'] / 1e6:6.2f} Mev/s  "
              f"{row['x_realtime']:6.1f}x real time (CPU {row['best_cpu_s']:.3f} s, {row['x_realtime_cpu']:.1f}x)"
              + (f"  target {target}x" if target else "")
              + f"  ({row['runs']} runs, load {row['load_before']:.1f} -> {row['load_after']:.1f})")

    report = {
        "input": source, "events": int(events), "duration_s": rec.duration_s, "repeats": args.repeats,
        "cores": 1, "machine": platform.processor() or platform.machine(), "python": platform.python_version(),
        "opencv": cv2.__version__, "numpy": np.__version__, "cvstereo": cvstereo.__version__,
        "date": time.strftime("%Y-%m-%d %H:%M"), "load_average": os.getloadavg(), "results": rows,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "frame.json").write_text(json.dumps(report, indent=2) + "\n")
    (args.out / "frame.md").write_text(markdown(report))
    print(f"wrote {args.out / 'frame.json'} and {args.out / 'frame.md'}")
    return 0


def markdown(report: dict) -> str:
    """The results as a Markdown table."""
    lines = [
        "# Frame matchers: speed on one core",
        "",
        f"Input: {report['input']}, {report['events']} events, {report['duration_s']:.2f} s. "
        f"The faster of the first two runs within 10 % (at most {report['repeats']} runs) through "
        "`calibration_free.match` (40 ms packets), after a warm-up; "
        f"OpenCV {report['opencv']}, numpy {report['numpy']}, {report['date']}, load average "
        f"{report['load_average'][0]:.1f} (wall time counts waits for a busy machine; CPU time does not).",
        "",
        "| method | variant | wall (s) | events/s | x real time | CPU (s) | x real time (CPU) | target "
        "| thesis Matlab (s) | runs, load |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in report["results"]:
        lines.append(f"| {r['method']} | {r['variant']} | {r['best_s']:.3f} | {r['events_per_s']:.3g} | "
                     f"{r['x_realtime']:.1f} | {r['best_cpu_s']:.3f} | {r['x_realtime_cpu']:.1f} | "
                     f"{str(r['target_x']) + 'x' if r['target_x'] else '-'} | "
                     f"{r['thesis_s'] if r['thesis_s'] else '-'} | "
                     + (f"{r['runs']}{'' if r['agreed'] else ' *'}, {r['load_before']:.1f} -> {r['load_after']:.1f} |"
                        if "runs" in r else "- |"))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
