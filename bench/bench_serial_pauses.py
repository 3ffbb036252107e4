"""Correctness bench of the E2 decoder around timestamp wraps, paced in real time.

A virtual eDVS board (``cvstereo.sensors.VirtualEDVS`` on a pseudo-terminal) streams E2 events in real time:
bursts of events with pauses between them drawn from 1 ms to 2 s, including 65.0, 65.535, 65.536 and 65.537 ms
(around one 16-bit wrap) and whole wraps +-1 us. The host reads them through ``cvstereo.sensors.EDVS`` (its
reader thread, arrival times from the host clock), and every event is checked against the events sent:
none dropped or invented, exact x, y and polarity, exact times between events, no clean byte counted corrupt.
Timing matters (a loaded machine delays the reader), so the load average is recorded beside each run.

Run: .venv/bin/python bench/bench_serial_pauses.py [--runs 10] [--seconds 6]
     (writes bench/results/serial-pauses.md)

With ``--speed-against REV`` it also times the decoder of commit REV and this one on a long clean E2 stream
(1 M events in 4 kB reads, with and without arrival times), alternating, best of ``--repeats`` in CPU time.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np

from cvstereo.model.events import make_events
from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.protocol import ProtocolSettings, encode_events
from cvstereo.sensors.virtual import read_back

OUT = Path(__file__).parent / "results" / "serial-pauses.md"
REPO = Path(__file__).resolve().parent.parent
WRAP = 1 << 16
#: Pauses every run contains (us): around one wrap, and whole wraps +-1 us.
FIXED_PAUSES = [1_000, 65_000, 65_535, 65_536, 65_537, 2 * WRAP - 1, 2 * WRAP + 1, 3 * WRAP, 2_000_000]
#: Shortest and longest random pause (us), drawn log-uniformly.
RANDOM_PAUSES_US = (1_000, 2_000_000)
E2 = ProtocolSettings(event_format="E2")


def paced_stream(rng: np.random.Generator, seconds: float) -> tuple[np.ndarray, list[int]]:
    """Bursts of 1-30 events (steps of 0-2 ms) with the fixed pauses and random ones between them, about
    ``seconds`` long; every event has its own (x, y), so a dropped or invented one is found by address."""
    pauses = list(FIXED_PAUSES)
    lo, hi = np.log(RANDOM_PAUSES_US[0]), np.log(RANDOM_PAUSES_US[1])
    while sum(pauses) < seconds * 1e6:
        pauses.append(int(np.exp(rng.uniform(lo, hi))))
    pauses = [int(p) for p in rng.permutation(pauses)]
    t, now = [], 0
    for k in range(len(pauses) + 1):
        now += pauses[k - 1] if k else 0
        steps = rng.integers(0, 2001, int(rng.integers(1, 31)))
        steps[0] = 0
        burst = now + np.cumsum(steps)
        t.extend(burst.tolist())
        now = int(burst[-1])
    t = np.array(t, np.int64)
    cell = rng.permutation(128 * 128)[:t.size]
    return make_events(t, cell % 128, cell // 128, rng.integers(0, 2, t.size)), pauses


def check(got: np.ndarray, want: np.ndarray) -> dict:
    """Dropped and invented events, wrong x/y/p, and wrong times between consecutive events."""
    index = np.full(128 * 128, -1, np.int64)
    index[want["x"].astype(np.int64) * 128 + want["y"]] = np.arange(want.size)
    found = index[got["x"].astype(np.int64) * 128 + got["y"]]
    invented = int((found < 0).sum())
    dropped = int(want.size - np.unique(found[found >= 0]).size)
    same = got.size == want.size and invented == 0 and (found == np.arange(want.size)).all()
    wrong_p = int((got["p"] != want["p"]).sum()) if same else -1
    wrong_dt = int((np.diff(got["t"]) != np.diff(want["t"])).sum()) if same else -1
    return {"dropped": dropped, "invented": invented, "wrong_p": wrong_p, "wrong_dt": wrong_dt,
            "exact": same and wrong_p == 0 and wrong_dt == 0}


def correctness(runs: int, seconds: float) -> list[dict]:
    rows = []
    for run in range(runs):
        rng = np.random.default_rng(run)
        ev, pauses = paced_stream(rng, seconds)
        load_before = os.getloadavg()[0]
        t0 = time.monotonic()
        got, reader, board = read_back(ev)
        status = {**reader.status(), "ambiguous": list(reader.decoder.ambiguous)}
        row = {"run": run + 1, "events": int(ev.size), "pauses": len(pauses), "seconds": time.monotonic() - t0,
               **check(got, ev), "corrupt_bytes": status["corrupt_bytes"], "ambiguous": len(status["ambiguous"]),
               "load_before": load_before, "load_after": os.getloadavg()[0], "board_late_ms": board.late_us / 1000}
        row["exact"] = row["exact"] and row["corrupt_bytes"] == 0
        rows.append(row)
        print(f"run {row['run']:2d}: {row['events']} events, {row['pauses']} pauses, {row['seconds']:.1f} s: "
              f"{'exact' if row['exact'] else 'NOT EXACT'} (dropped {row['dropped']}, invented {row['invented']}, "
              f"wrong p {row['wrong_p']}, wrong dt {row['wrong_dt']}, corrupt bytes {row['corrupt_bytes']}, "
              f"ambiguous {row['ambiguous']}), board up to {row['board_late_ms']:.1f} ms late, "
              f"load {row['load_before']:.2f} -> {row['load_after']:.2f}")
    return rows


def decoder_of(rev: str) -> type:
    """``StreamDecoder`` as of commit ``rev`` (its module run against today's compiled scanners, which it
    shares)."""
    src = subprocess.run(["git", "show", f"{rev}:cvstereo/sensors/decoder.py"], cwd=REPO, check=True,
                         capture_output=True, text=True).stdout
    mod = types.ModuleType(f"decoder_{rev}")
    sys.modules[mod.__name__] = mod  # dataclasses look their module up there
    exec(compile(src, f"{rev}:cvstereo/sensors/decoder.py", "exec"), mod.__dict__)
    return mod.StreamDecoder


def speed(rev: str, repeats: int) -> list[dict]:
    rng = np.random.default_rng(0)
    n = 1_000_000
    ev = make_events(np.cumsum(rng.integers(0, 60, n)), rng.integers(0, 128, n), rng.integers(0, 128, n),
                     rng.integers(0, 2, n))
    data = encode_events(ev, E2)
    piece = 4096
    arrive = 5_000_000 + ev["t"][np.minimum(np.arange(piece, len(data) + piece, piece), len(data)) // 4 - 1]
    decoders = {rev: decoder_of(rev), "this tree": StreamDecoder}
    rows = []
    for timed_host in (False, True):
        best = dict.fromkeys(decoders, float("inf"))
        for _ in range(repeats):
            for name, cls in decoders.items():
                dec = cls(E2)
                dec.reset_time(5_000_000 if timed_host else None)
                t0 = time.process_time()  # CPU time: what a loaded machine's other work leaves unaffected
                out = 0
                for k, i in enumerate(range(0, len(data), piece)):
                    host = int(arrive[k]) if timed_host else None
                    out += dec.decode(data[i:i + piece], host_t=host, after_t=None).size
                out += dec.flush().size
                best[name] = min(best[name], time.process_time() - t0)
                assert out == n, f"{name} decoded {out} of {n} events"
        load = os.getloadavg()[0]
        for name, dt in best.items():
            rows.append({"decoder": name, "arrival times": timed_host, "events_per_s": n / dt, "load": load})
            print(f"{name:>10} {'with' if timed_host else 'without'} arrival times: {n / dt / 1e6:.2f} M events/s "
                  f"(best of {repeats}), load {load:.2f}")
    return rows


def write(rows: list[dict], speed_rows: list[dict], seconds: float) -> None:
    exact = sum(r["exact"] for r in rows)
    lines = ["# E2 decoder around timestamp wraps, paced in real time", "",
             f"A virtual eDVS board streams E2 events in real time (about {seconds:g} s per run): bursts of 1-30 "
             f"events with pauses from {RANDOM_PAUSES_US[0] / 1000:g} ms to {RANDOM_PAUSES_US[1] / 1e6:g} s "
             "between them, every run including "
             + ", ".join(f"{p / 1000:g} ms" for p in FIXED_PAUSES) + ". Read by `EDVS` (its reader thread, host "
             "clock), every event checked against the events sent: x, y, p and the time since the event before.",
             "", f"**{exact} of {len(rows)} runs exact.**", "",
             "`board late`: the longest an event waited past its time before the virtual board's thread sent it (a "
             "loaded machine delays that thread; beyond 20 ms the arrival times no longer tell the wraps, which the "
             "decoder promises only within 20 ms).", "",
             "| run | events | pauses | dropped | invented | wrong p | wrong dt | corrupt bytes | ambiguous "
             "| board late ms | exact | load before | load after |", "|---" * 13 + "|"]
    for r in rows:
        lines.append(f"| {r['run']} | {r['events']} | {r['pauses']} | {r['dropped']} | {r['invented']} | "
                     f"{r['wrong_p']} | {r['wrong_dt']} | {r['corrupt_bytes']} | {r['ambiguous']} | "
                     f"{r['board_late_ms']:.1f} | {'yes' if r['exact'] else 'NO'} | {r['load_before']:.2f} | "
                     f"{r['load_after']:.2f} |")
    if speed_rows:
        lines += ["", "Decoder speed on a long clean E2 stream (1 M events, 4 kB reads), old and new decoder "
                  "alternating in one run, best of the repeats in CPU time (events per CPU second):", "",
                  "| decoder | arrival times | events/s | load |", "|---|---|---|---|"]
        for r in speed_rows:
            lines.append(f"| {r['decoder']} | {'yes' if r['arrival times'] else 'no'} | {r['events_per_s']:,.0f} "
                         f"| {r['load']:.2f} |")
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text("\n".join(lines) + "\n")
    print(f"{exact}/{len(rows)} runs exact; written to {OUT}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--seconds", type=float, default=6.0, help="stream length per run (real time)")
    ap.add_argument("--speed-against", metavar="REV", help="also time the decoder of commit REV against this one")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    rows = correctness(args.runs, args.seconds)
    speed_rows = speed(args.speed_against, args.repeats) if args.speed_against else []
    write(rows, speed_rows, args.seconds)
    return 0 if all(r["exact"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
