"""ROS bags of ``dvs_msgs/EventArray``: read speed with the messages decoded from their bytes (numpy, the default)
and through rosbags' message objects (the path before), in the same run, on the same bags.

The bags are written as the reader's tests write them (tests/_rosbag_files.py: messages packed by hand, containers
from rosbags' writers): two topics of ``--events`` events each at 346x260, ``--per-message`` events a message.
Prints a table (events per second, best of ``--repeat``, the load beside it) and writes bench/results/rosbag.md.

    python bench/bench_rosbag.py [--events 300000] [--per-message 2000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from cvstereo.io import read_recording  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from tests._rosbag_files import ARRAY, event_array, split, write_bag  # noqa: E402

CONTAINERS = {"ROS 1 .bag": {"ros2": False}, "ROS 2 sqlite3": {"ros2": True, "storage": "sqlite3"},
              "ROS 2 mcap": {"ros2": True, "storage": "mcap"}}


def _events(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = 1_700_000_000 * 10**6 + np.sort(rng.integers(0, 10_000_000, n))
    return make_events(t, rng.integers(0, 346, n), rng.integers(0, 260, n), rng.integers(0, 2, n))


def _best_rate(path: Path, repeat: int, n: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        rec = read_recording(path)
        best = min(best, time.perf_counter() - t0)
        assert rec.left.size + rec.right.size == n
    return n / best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=300_000, help="events per camera")
    ap.add_argument("--per-message", type=int, default=2_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "rosbag.md"))
    args = ap.parse_args(argv)
    left, right = _events(args.events, 1), _events(args.events, 2)
    parts = max(1, args.events // args.per_message)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, how in CONTAINERS.items():
            cdr = how["ros2"]
            topics = {topic: (ARRAY, [event_array(p, 346, 260, cdr=cdr, seq=i) for i, p in enumerate(split(ev, parts))])
                      for topic, ev in (("/dvs/left/events", left), ("/dvs/right/events", right))}
            path = write_bag(Path(tmp) / ("b.bag" if not cdr else f"b-{how['storage']}"), topics, **how)
            read_recording(path)  # imports and rosbags' type store, outside the clock
            load = os.getloadavg()[0]
            fast = _best_rate(path, args.repeat, 2 * args.events)
            with mock.patch("cvstereo.io.rosbag.parse_event_array", lambda raw, ros2: None):
                objects = _best_rate(path, args.repeat, 2 * args.events)
            rows.append((name, fast, objects, load, os.getloadavg()[0]))
            print(f"{name}: bytes {fast / 1e6:.2f} M ev/s, objects {objects / 1e6:.3f} M ev/s, "
                  f"{fast / objects:.1f}x (load {load:.1f}-{rows[-1][4]:.1f})", flush=True)
    lines = ["# ROS bags of dvs_msgs/EventArray: read speed", "",
             f"`python bench/bench_rosbag.py --events {args.events} --per-message {args.per_message} --repeat "
             f"{args.repeat}`: two topics of {args.events:,} events (346x260), {args.per_message:,} a message; "
             "`read_recording` of the whole bag, best of the repeats, wall clock, one process. \"bytes\": each "
             "message decoded from its serialised bytes by numpy (the default); \"objects\": through rosbags' "
             "message objects, one per event (the reader before; forced here by turning the byte decoder off).", "",
             "| container | bytes, M ev/s | objects, M ev/s | ratio | load (1 min) |", "|---|---|---|---|---|"]
    lines += [f"| {n} | {f / 1e6:.2f} | {o / 1e6:.3f} | {f / o:.1f}x | {a:.1f}-{b:.1f} |" for n, f, o, a, b in rows]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
