"""Benchmark of the live eDVS path: decoder throughput per format against the link's maximum event rate at
4 Mbaud, decode speed on pure garbage per format (bytes/s; the link brings at most 400,000 bytes/s), and the
end-to-end latency of `live` (event arrival -> its disparity shown) with virtual boards.

Run: .venv/bin/python bench/bench_sensors.py   (writes bench/results/sensors.json and .md)
"""

from __future__ import annotations

import io
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from cvstereo.matchers.protocol import StreamMatcher
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches
from cvstereo.sensors import StereoEDVS, VirtualEDVS
from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.live import run_live
from cvstereo.sensors.protocol import FORMATS, ProtocolSettings, encode_events, link_event_rate

OUT = Path(__file__).parent / "results"
N_EVENTS = 1_000_000
PIECE = 4096  # bytes per read, about what a 4 Mbaud port delivers per 10 ms


def decoder_throughput() -> dict:
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.integers(0, 60, N_EVENTS))
    ev = make_events(t, rng.integers(0, 128, N_EVENTS), rng.integers(0, 128, N_EVENTS), rng.integers(0, 2, N_EVENTS))
    rows = {}
    for name in FORMATS:
        s = ProtocolSettings(event_format=name)
        data = encode_events(ev, s)
        StreamDecoder(s).decode(data[:PIECE])  # compile (E1 uses numba) before timing
        dec = StreamDecoder(s)
        t0 = time.perf_counter()
        n = sum(dec.decode(data[i:i + PIECE]).size for i in range(0, len(data), PIECE)) + dec.flush().size
        dt = time.perf_counter() - t0
        rate = n / dt
        link = link_event_rate(name)
        rows[name] = {"events_per_s": rate, "link_max_events_per_s": link, "x_link": rate / link,
                      "bytes_per_event": len(data) / N_EVENTS}
        print(f"{name}: {rate / 1e6:6.2f} M events/s, link max {link / 1e3:6.1f} k events/s -> {rate / link:6.1f}x")
    return rows


GARBAGE_BYTES = 256 * 1024
LINK_BYTES_PER_S = 400_000  # 4 Mbaud, 8N1


def garbage_throughput() -> dict:
    """Bytes/s decoded when every byte is line noise (the load average is recorded beside each figure)."""
    garbage = np.random.default_rng(2).integers(0, 256, GARBAGE_BYTES, dtype=np.uint8).tobytes()
    rows = {}
    for name in FORMATS:
        s = ProtocolSettings(event_format=name)
        StreamDecoder(s).decode(garbage[:PIECE])  # load the compiled scanners before timing
        dec = StreamDecoder(s)
        t0 = time.perf_counter()
        for i in range(0, len(garbage), PIECE):
            dec.decode(garbage[i:i + PIECE])
        dec.flush()
        dt = time.perf_counter() - t0
        load = os.getloadavg()[0]
        rows[name] = {"bytes_per_s": len(garbage) / dt, "x_link": len(garbage) / dt / LINK_BYTES_PER_S,
                      "corrupt_share": dec.corrupt_bytes / len(garbage), "load_avg_1min": load}
        print(f"{name} garbage: {len(garbage) / dt:14,.0f} bytes/s ({len(garbage) / dt / LINK_BYTES_PER_S:.0f}x "
              f"the link), {dec.corrupt_bytes / len(garbage):.1%} counted corrupt, load average {load:.2f}")
    return rows


@dataclass(frozen=True)
class _P:
    pass


class _Trivial(StreamMatcher):
    """Stand-in matcher (one match per packet) so the latency measured is the pipeline's own."""

    Params = _P
    variants: ClassVar[dict] = {"default": {}}

    def _feed(self, left, right):
        if not (left.size and right.size):
            return make_matches([], [], [], [], [], [])
        return make_matches([int(left["t"][-1])], [0], [0], [1], [0], [float(left["x"].mean() - right["x"].mean())])


def live_latency(seconds: float = 5.0, rate: int = 20_000, method: str | None = "frame") -> dict:
    rng = np.random.default_rng(1)
    n = int(seconds * rate)
    cams = [make_events(np.sort(rng.integers(0, int(seconds * 1e6), n)), rng.integers(0, 128, n),
                        rng.integers(0, 128, n), rng.integers(0, 2, n)) for _ in range(2)]
    results = {}
    matchers = {"trivial": _Trivial}
    if method:
        try:
            from cvstereo.matchers.registry import create_matcher

            create_matcher(method)
            matchers[method] = lambda: create_matcher(method)
        except (ImportError, ValueError):
            pass
    for name, make in matchers.items():
        with VirtualEDVS(cams[0]) as lp, VirtualEDVS(cams[1]) as rp, StereoEDVS(lp, rp) as rig:
            rig.start()
            stats = run_live(rig, make(), seconds=seconds - 0.5, out=io.StringIO())
            rig.stop()
        s = stats.summary()
        results[name] = s
        print(f"live ({name}): latency median {s['latency_ms_median']} ms, p95 {s['latency_ms_p95']} ms; "
              f"lag mean {s['lag_ms_mean']:.1f} ms, max {s['lag_ms_max']:.1f} ms")
    return results


def main() -> None:
    res = {"decoder": decoder_throughput(), "garbage": garbage_throughput(), "live": live_latency()}
    OUT.mkdir(exist_ok=True)
    (OUT / "sensors.json").write_text(json.dumps(res, indent=2))
    lines = ["# eDVS sensors benchmark", "", "Decoder throughput (1 M events, 4 kB reads) vs the 4 Mbaud link maximum:",
             "", "| format | bytes/event | decoder events/s | link max events/s | x link |", "|---|---|---|---|---|"]
    for k, r in res["decoder"].items():
        lines.append(f"| {k} | {r['bytes_per_event']:.2f} | {r['events_per_s']:,.0f} "
                     f"| {r['link_max_events_per_s']:,.0f} | {r['x_link']:.1f} |")
    lines += ["", f"Decoding pure garbage ({GARBAGE_BYTES // 1024} KB of random bytes, 4 kB reads); the 4 Mbaud link "
              f"brings at most {LINK_BYTES_PER_S:,} bytes/s:", "",
              "| format | bytes/s | x link | counted corrupt | load average (1 min) |", "|---|---|---|---|---|"]
    for k, r in res["garbage"].items():
        lines.append(f"| {k} | {r['bytes_per_s']:,.0f} | {r['x_link']:.0f} | {r['corrupt_share']:.1%} "
                     f"| {r['load_avg_1min']:.2f} |")
    lines += ["", "Live latency (event arrival -> status line showing its disparity), two virtual eDVS, 20k ev/s each:",
              "", "| matcher | latency median ms | p95 ms | lag mean ms | lag max ms |", "|---|---|---|---|---|"]
    for k, s in res["live"].items():
        lines.append(f"| {k} | {s['latency_ms_median']} | {s['latency_ms_p95']} | {s['lag_ms_mean']:.1f} | "
                     f"{s['lag_ms_max']:.1f} |")
    (OUT / "sensors.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
