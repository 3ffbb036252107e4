"""``cvstereo live --dv`` against two of dv-processing's own network writers on this host (issue 26 item 3).

A stereo recording at ``--rate`` events/s per camera for ``--seconds`` (a simulated 2-arm scene, copies of it
laid over each other a few hundred microseconds apart until the rate is reached, tiled in time) is written to a
file; two writers (``python -m cvstereo.sensors.dvserve``, one process per camera) stream it in real time and
``cvstereo live --dv`` matches it, once per method (the default and ``fused``). Reported per method: events sent
and received per camera, dropped (sent - received), late events (received, not matched), the lag per packet
(delivery -> matches out),
and whether the live matches' sha256 equals that of matching the file (``cvstereo.match``). The machine's load
is written beside the figures: on a loaded machine the lag is the machine's as much as the code's.

    python bench/bench_dv_live.py                      # 1 M events/s per camera, 10 s -> bench/results/dv-live.md
    python bench/bench_dv_live.py --rate 200000 --seconds 2 -o /tmp/dv-live.md
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from tests._dv_serve import served  # noqa: E402  (the writers the tests use)

#: Time between two copies of the scene laid over each other, us.
COPY_SHIFT_US = 250


def dense_recording(rate: float, seconds: float, seed: int = 0):
    """A stereo recording of about ``rate`` events/s per camera for ``seconds``: a 1 s simulated clip, copies
    of it laid over each other :data:`COPY_SHIFT_US` apart until the rate is reached, tiled in time."""
    from cvstereo.model.recording import Recording
    from cvstereo.simulate import simulate_preset

    clip = simulate_preset("2arms-50cm", seconds=1.0, seed=seed)
    cams = []
    for ev in (clip.left, clip.right):
        copies = max(1, round(rate / max(ev.size, 1)))
        parts = []
        for tile in range(int(np.ceil(seconds))):
            for k in range(copies):
                part = ev.copy()
                part["t"] += tile * 1_000_000 + k * COPY_SHIFT_US
                parts.append(part)
        out = np.concatenate(parts)
        out = out[np.argsort(out["t"], kind="stable")]
        cams.append(out[out["t"] < clip.t_start + seconds * 1e6])
    return Recording(cams[0], cams[1], resolution=clip.resolution)


def run_method(path: Path, method: str, speed: float) -> dict:
    """One live run against two writers; its summary, status and the writers' counts."""
    with served(path, speed=speed) as (left, right):
        proc = subprocess.run([sys.executable, "-m", "cvstereo", "live", "--dv", left, right, "-m", method],
                              capture_output=True, text=True, cwd=REPO, check=False)
    if proc.returncode != 0:
        raise SystemExit(f"live --dv -m {method} failed: {proc.stderr.strip().splitlines()[-1:]}")
    return json.loads(proc.stderr.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1_000_000, help="events/s per camera (default 1 M)")
    parser.add_argument("--seconds", type=float, default=10.0, help="stream length (default 10 s)")
    parser.add_argument("--methods", nargs="+", default=None, help="default: the CLI's default method and fused")
    parser.add_argument("-o", "--output", default=str(REPO / "bench" / "results" / "dv-live.md"))
    args = parser.parse_args(argv)
    import cvstereo as cvs
    from cvstereo.io.npz import write_recording_npz
    from cvstereo.matchers.registry import DEFAULT_METHOD

    methods = args.methods or [DEFAULT_METHOD, "fused"]
    load_before = os.getloadavg()
    rec = dense_recording(args.rate, args.seconds)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "dense.npz"
        write_recording_npz(path, rec)
        for method in methods:
            t0 = time.monotonic()
            report = run_method(path, method, speed=1.0)
            wall = time.monotonic() - t0
            expected = cvs.match(rec, method=method, rig_check=False).matches  # as live: no rig check
            s, st = report["summary"], report["status"]
            lag = s["lag_per_packet"]
            received = (st["left"]["events"], st["right"]["events"])
            rows.append({
                "method": method, "sent": (rec.left.size, rec.right.size), "received": received,
                "dropped": (rec.left.size - received[0], rec.right.size - received[1]),
                "matched": (s["events_left"], s["events_right"]), "late": tuple(st["late_events_by_camera"]),
                "lag": lag, "matches": s["matches"],
                "hash_equal": s["matches_sha256"] == hashlib.sha256(expected.tobytes()).hexdigest(),
                "wall_s": wall})
            print(rows[-1], flush=True)
    load_after = os.getloadavg()
    lines = [
        "# live --dv against two dv-processing network writers",
        "",
        f"`python bench/bench_dv_live.py --rate {args.rate:g} --seconds {args.seconds:g}`: "
        f"{rec.left.size} + {rec.right.size} events ({rec.left.size / args.seconds:,.0f} and "
        f"{rec.right.size / args.seconds:,.0f} events/s), streamed in real time on 127.0.0.1, one writer "
        "process per camera.",
        "",
        f"Load: {os.cpu_count()} cores; 1/5/15-min load average {', '.join(f'{v:.2f}' for v in load_before)} "
        f"before, {', '.join(f'{v:.2f}' for v in load_after)} after.",
        "",
        "Received: events the DV sources read; dropped: sent - received (lost before cvstereo saw them); late: "
        "received, but behind the watermark once a camera counted as silent, so not matched (docs/guide/live.md); "
        "matched: events fed to the matcher.",
        "",
        "| method | sent L / R | received L / R | dropped L / R | late L / R | matched L / R | "
        "lag p50 / p90 / p99 / max ms | matches | sha256 = file's |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lag = r["lag"]
        figures = " / ".join("n/a" if lag[k] is None else f"{lag[k]:.1f}" for k in ("p50_ms", "p90_ms", "p99_ms",
                                                                                    "max_ms"))
        pairs = " | ".join(f"{r[k][0]} / {r[k][1]}" for k in ("sent", "received", "dropped", "late", "matched"))
        lines.append(f"| {r['method']} | {pairs} | {figures} | {r['matches']} | {'yes' if r['hash_equal'] else 'NO'} |")
    Path(args.output).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0 if all(r["hash_equal"] and r["dropped"] == (0, 0) and r["late"] == (0, 0) for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
