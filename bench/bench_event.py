"""Benchmark of the event matchers (event-time, event-area, event-vector): speed, compile time, memory.

Runs on one core (NUMBA_NUM_THREADS=1, CPU affinity pinned to one CPU where the OS allows):

* throughput: input events per second of every matcher and variant over the simulator's ``2arms-50cm``
  preset (``cvstereo.simulate.cached_preset``) if it can be imported, else over a synthetic stream of moving
  textured edges with a similar rate (about 1.2 M events in 11 s), streamed in 10 ms packets;
* compile time: in a fresh subprocess, the first call minus the second call on a small input, once with an
  empty numba cache (compiling) and once with that cache filled (loading);
* peak memory: maximum resident set size of a subprocess that streams a 10-minute synthetic stream,
  generated packet by packet and never stored whole, through one matcher (beside a subprocess that only
  generates the stream, for the baseline).

Run: ``.venv/bin/python bench/bench_event.py [--quick] [--memory-minutes 10]``. Writes
``bench/results/event.json`` and ``bench/results/event.md``; prints the table.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))

from cvstereo.benchmark.timing import Agreement  # noqa: E402
from cvstereo.matchers.registry import create_matcher, matcher_class  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402

METHODS = ("event-time", "event-area", "event-vector")
#: Targets of issue 5, input events per second on one core.
TARGETS = {"event-time": 2_000_000, "event-vector": 1_000_000, "event-area": 300_000}
MEMORY_LIMIT_MB = 500
PACKET_US = 10_000


# ------------------------------------------------------------------------------------------------ input

#: Synthetic scene: (start px, speed px/s, first row, rows, events per pixel crossing, polarity, disparity).
#: Six edges of two "arms" (near, disparity 28) and of the background (far, disparity 8), sweeping right
#: and wrapping around; about 55 k events/s per camera, like the thesis' busiest recording.
_EDGES = (
    (5.0, 160.0, 20, 50, 2, 1, 28), (12.0, 160.0, 20, 50, 2, 0, 28),
    (60.0, 140.0, 60, 45, 2, 1, 28), (70.0, 140.0, 60, 45, 2, 0, 28),
    (30.0, 90.0, 0, 30, 2, 1, 8), (100.0, 120.0, 90, 30, 2, 0, 8),
)
_NOISE_PER_S = 3_000
_DELAY_US = 50
_WIDTH = 128
_MARGIN = 40  # edges wrap over W + 2 * margin so that they leave and re-enter the view


def _camera_packet(t0: int, t1: int, cam: int, seed: int) -> np.ndarray:
    """Events of camera ``cam`` with t0 <= t < t1; each pixel crossing draws from its own seeded generator,
    so events are the same whichever packet asks for them."""
    shift = 0 if cam == 0 else 1
    delay = 0 if cam == 0 else _DELAY_US
    period = _WIDTH + 2 * _MARGIN
    parts = []
    for e, (x0, v, row0, rows, m, pol, disp) in enumerate(_EDGES):
        dt_px = 1e6 / v
        # unwrapped crossing index n: the edge enters column n (mod period) at (n - x0) / v
        n_lo = int(np.floor(x0 + v * (t0 - delay - dt_px) / 1e6))
        n_hi = int(np.floor(x0 + v * (t1 - delay) / 1e6)) + 1
        for n in range(n_lo, n_hi + 1):
            col = n % period - _MARGIN - shift * disp
            if not 0 <= col < _WIDTH:
                continue
            rng = np.random.default_rng((seed, e, n))
            count = rows * m
            t_cross = (n - x0) / v * 1e6 + delay
            t = (t_cross + rng.random(count) * dt_px).astype(np.int64)
            y = row0 + rng.integers(0, rows, count)
            keep = (t >= t0) & (t < t1)
            parts.append(make_events(t[keep], np.full(keep.sum(), col), y[keep], np.full(keep.sum(), pol)))
    rng = np.random.default_rng((seed, 1000 + cam, t0))
    k = rng.poisson(_NOISE_PER_S * (t1 - t0) / 1e6)
    parts.append(make_events(rng.integers(t0, t1, k), rng.integers(0, 128, k), rng.integers(0, 128, k),
                             rng.integers(0, 2, k)))
    ev = np.concatenate(parts)
    return ev[np.argsort(ev["t"], kind="stable")]


def synthetic_packets(duration_s: float, *, seed: int = 0, packet_us: int = PACKET_US):
    """Yield ``(left, right, until)`` packets of the synthetic stream, generated one at a time."""
    for k in range(int(duration_s * 1e6 // packet_us)):
        t0, t1 = k * packet_us, (k + 1) * packet_us
        yield _camera_packet(t0, t1, 0, seed), _camera_packet(t0, t1, 1, seed), t1


def load_input(quick: bool):
    """The packets of the benchmark input, and a description of it."""
    try:
        from cvstereo.simulate import cached_preset
    except ImportError:
        cached_preset = None
    if cached_preset is not None:
        try:
            from cvstereo.io.npz import read_recording_npz

            seconds = 2.0 if quick else None
            rec = read_recording_npz(cached_preset("2arms-50cm", seconds=seconds))
            packets = [(p.left, p.right, p.until) for p in rec.packets(PACKET_US)]
            return packets, {"input": "simulator preset 2arms-50cm", "duration_s": rec.duration_s}
        except Exception as exc:  # the simulator is young: fall back rather than fail the benchmark
            print(f"cached_preset('2arms-50cm') failed ({exc!r}); using the synthetic stream", file=sys.stderr)
    duration = 2.0 if quick else 11.0
    packets = list(synthetic_packets(duration))
    return packets, {"input": "synthetic moving textured edges", "duration_s": duration}


# ------------------------------------------------------------------------------------------ measurements

def variants():
    for method in METHODS:
        for variant in matcher_class(method).variants:
            yield method, variant


def throughput(method: str, variant: str, packets) -> dict:
    """Input events per second over the packets, after a warm-up that compiles or loads the kernels: runs
    repeated until two agree within 10 % in CPU time (:mod:`cvstereo.benchmark.timing`), with the load before and
    after."""
    warm = create_matcher(method, variant)
    for left, right, until in packets[:3]:
        warm.feed(left, right, until=until)
    warm.flush()
    n_in = sum(left.size + right.size for left, right, _ in packets)
    agreement, walls = Agreement(), []
    agreement.start()
    while not agreement.done:
        matcher = create_matcher(method, variant)
        n_out = 0
        wall, cpu = time.perf_counter(), time.process_time()
        for left, right, until in packets:
            n_out += matcher.feed(left, right, until=until).size
        n_out += matcher.flush().size
        walls.append(time.perf_counter() - wall)
        agreement.add(time.process_time() - cpu)
    # CPU time of this process: the machine is shared, and wall-clock time counts other people's work too.
    timing = agreement.result()
    cpu, wall = timing.seconds, min(walls)
    return {"events": int(n_in), "matches": int(n_out), "cpu_seconds": cpu, "wall_seconds": wall,
            "events_per_s": n_in / cpu, "events_per_s_wall": n_in / wall, "runs": timing.runs,
            "agreed": timing.agreed, "load_before": timing.load_before, "load_after": timing.load_after}


_COMPILE_CHILD = """
import os, sys, time
sys.path.insert(0, {repo!r})
t0 = time.perf_counter()
from cvstereo.matchers.registry import create_matcher
from bench.bench_event import synthetic_packets
packets = list(synthetic_packets(0.05))
t_import = time.perf_counter() - t0
times = []
for _ in range(2):
    m = create_matcher({method!r}, {variant!r})
    t = time.perf_counter()
    for left, right, until in packets:
        m.feed(left, right, until=until)
    m.flush()
    times.append(time.perf_counter() - t)
print(times[0], times[1], t_import)
"""


def compile_times(method: str, variant: str, cache_dir: str) -> dict:
    """First-call minus second-call time in fresh subprocesses: cold (empty cache), then warm (cache filled)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir, "NUMBA_NUM_THREADS": "1"}
    out = {}
    for label in ("cold", "cached"):
        code = _COMPILE_CHILD.format(repo=str(REPO), method=method, variant=variant)
        res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True,
                             cwd=REPO)
        first, second, _ = map(float, res.stdout.split())
        out[f"{label}_first_call_s"] = first
        out[f"{label}_compile_s"] = max(0.0, first - second)
    return out


_MEMORY_CHILD = """
import resource, sys, time
sys.path.insert(0, {repo!r})
from cvstereo.matchers.registry import create_matcher
from bench.bench_event import synthetic_packets
method = {method!r}
m = create_matcher(method, {variant!r}) if method else None
n = 0
t = time.perf_counter()
for left, right, until in synthetic_packets({minutes} * 60):
    n += left.size + right.size
    if m is not None:
        m.feed(left, right, until=until)
if m is not None:
    m.flush()
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, n, time.perf_counter() - t)
"""


def peak_memory(method: str | None, variant: str | None, minutes: float) -> dict:
    """Max RSS (MB) of a subprocess streaming ``minutes`` of the synthetic stream through one matcher
    (or through none, for the baseline)."""
    code = _MEMORY_CHILD.format(repo=str(REPO), method=method, variant=variant, minutes=minutes)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO,
                         env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    rss_kb, n, seconds = res.stdout.split()
    return {"peak_rss_mb": int(rss_kb) / 1024, "events": int(n), "seconds": float(seconds), "minutes": minutes}


# ----------------------------------------------------------------------------------------------- report

def write_report(results: dict, out_dir: Path) -> str:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "event.json").write_text(json.dumps(results, indent=2) + "\n")
    lines = [
        "# Event matchers: speed, compile time, memory",
        "",
        f"Input: {results['input']['input']} ({results['input']['duration_s']:.1f} s, "
        f"{results['input']['events']:,} events, {results['input']['events_per_s']:,.0f} events/s); "
        f"one core; {results['machine']}.",
        "",
        "| method | variant | events/s (CPU) | events/s (wall) | x real time | target | matches "
        "| compile (cold) s | first call (cached) s | peak RSS MB (10 min) | runs, load |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for row in results["rows"]:
        mem = row.get("memory", {}).get("peak_rss_mb")
        comp = row.get("compile", {})
        lines.append(
            f"| {row['method']} | {row['variant']} | {row['events_per_s']:,.0f} | {row['events_per_s_wall']:,.0f} | "
            f"{row['events_per_s'] / results['input']['events_per_s']:.1f} | {TARGETS[row['method']]:,} "
            f"{'ok' if row['events_per_s'] >= TARGETS[row['method']] else 'MISSED'} | {row['matches']:,} | "
            f"{comp.get('cold_compile_s', float('nan')):.2f} | {comp.get('cached_first_call_s', float('nan')):.2f} | "
            f"{'' if mem is None else f'{mem:.0f}'} | {_runs_load(row)} |"
        )
    base = results.get("memory_baseline")
    if base:
        lines += ["", f"Memory baseline (generating the {base['minutes']:.0f}-minute stream, no matcher): "
                      f"{base['peak_rss_mb']:.0f} MB; the stream holds {base['events']:,} events "
                      f"({base['events'] * 16 / 2**20:,.0f} MB if it were stored whole). Limit: "
                      f"{MEMORY_LIMIT_MB} MB."]
    text = "\n".join(lines) + "\n"
    (out_dir / "event.md").write_text(text)
    return text


def _runs_load(row: dict) -> str:
    """Runs until two agreed (``*``: none did) and the load average before -> after; '-' in older results."""
    if "runs" not in row:
        return "-"
    return f"{row['runs']}{'' if row['agreed'] else ' *'}, {row['load_before']:.1f} -> {row['load_after']:.1f}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s of input, 1-minute memory run")
    parser.add_argument("--memory-minutes", type=float, default=None, help="length of the memory run (10)")
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--memory-all", action="store_true", help="memory run for every variant, not one per method")
    parser.add_argument("--no-compile", action="store_true")
    parser.add_argument("--out", type=Path, default=HERE / "results")
    args = parser.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    minutes = args.memory_minutes if args.memory_minutes is not None else (1.0 if args.quick else 10.0)

    packets, info = load_input(args.quick)
    n_in = sum(left.size + right.size for left, right, _ in packets)
    info.update(events=int(n_in), events_per_s=n_in / info["duration_s"])
    print(f"input: {info['input']}, {n_in:,} events in {info['duration_s']:.1f} s", flush=True)
    results = {"input": info, "machine": f"{platform.processor() or platform.machine()}, "
                                         f"Python {platform.python_version()}", "rows": []}
    with tempfile.TemporaryDirectory() as cache_root:
        for method, variant in variants():
            row = {"method": method, "variant": variant, **throughput(method, variant, packets)}
            if not args.no_compile and variant == next(iter(matcher_class(method).variants)):
                # Variants of a method share its kernels: compile time is measured once per method, with a
                # cache of its own (so that shared kernels, the dynamic frames', count for every method).
                row["compile"] = compile_times(method, variant, os.path.join(cache_root, method))
            if not args.no_memory and (args.memory_all or variant == next(iter(matcher_class(method).variants))):
                # Memory depends on the method's buffers, not on the variant: by default one run per method.
                row["memory"] = peak_memory(method, variant, minutes)
            print(json.dumps(row), flush=True)
            results["rows"].append(row)
    if not args.no_memory:
        results["memory_baseline"] = peak_memory(None, None, minutes)
    results["self_maxrss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(write_report(results, args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
