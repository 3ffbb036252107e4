"""How long reading a large AEDAT4 and DSEC file takes, beside an older commit.

Writes (once, cached under ``.cache/bench-read/``) a 10 M-event AEDAT4 file with dv-processing's writer and a
10 M-event DSEC ``events.h5`` with h5py, then reads each whole (``open_recording(...).read_camera``) in a
fresh process per run, alternating this tree and ``--baseline COMMIT`` (a temporary ``git worktree`` on
``PYTHONPATH``), and prints the minimum and median wall time of each with the machine's load average beside
them: on a shared machine the minimum is the figure least disturbed by other work.

Run: ``.venv/bin/python bench/bench_read.py [--baseline COMMIT] [--runs 7] [--events 10000000]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

from bench_speed import baseline_tree  # noqa: E402

#: Events per dv-processing packet when the AEDAT4 file is written (DV's recorder writes a few thousand).
PACKET_EVENTS = 10_000
RESOLUTION = (640, 480)
#: Microseconds covered by each packet on average (a 10 M-event file spans 1 s).
PACKET_US = 1_000

_READ = r"""
import json, sys, time
from cvstereo.io import open_recording
t0 = time.perf_counter()
stream = open_recording(sys.argv[1])
events, _ = stream.read_camera(stream.cameras[0])
print(json.dumps({"seconds": time.perf_counter() - t0, "events": int(events.size)}))
"""


def _events(n: int, seed: int = 0):
    import numpy as np

    rng = np.random.default_rng(seed)
    t = 1_700_000_000_000_000 + np.sort(rng.integers(0, -(-n // PACKET_EVENTS) * PACKET_US, n))
    return t, rng.integers(0, RESOLUTION[0], n), rng.integers(0, RESOLUTION[1], n), rng.integers(0, 2, n)


def write_aedat4(path: Path, n: int) -> None:
    import dv_processing as dv

    t, x, y, p = (a.tolist() for a in _events(n))
    writer = dv.io.MonoCameraWriter(str(path), dv.io.MonoCameraWriter.EventOnlyConfig("camera", RESOLUTION))
    for lo in range(0, n, PACKET_EVENTS):
        store = dv.EventStore()
        for i in range(lo, min(n, lo + PACKET_EVENTS)):
            store.push_back(t[i], x[i], y[i], bool(p[i]))
        writer.writeEvents(store)
    del writer  # closes the file


def write_dsec(path: Path, n: int) -> None:
    import h5py
    import hdf5plugin
    import numpy as np

    t, x, y, p = _events(n)
    t_offset = int(t[0])
    rel = t - t_offset
    ms_to_idx = np.searchsorted(rel, np.arange(int(rel[-1]) // 1000 + 2) * 1000, side="left").astype(np.uint64)
    with h5py.File(path, "w") as f:
        kw = hdf5plugin.Blosc(cname="zstd")
        for name, values, dtype in (("x", x, np.uint16), ("y", y, np.uint16), ("t", rel, np.uint32),
                                    ("p", p, np.uint8)):
            f.create_dataset(f"events/{name}", data=values.astype(dtype), **kw)
        f.create_dataset("t_offset", data=np.int64(t_offset))
        f.create_dataset("ms_to_idx", data=ms_to_idx)


def _read_once(code_dir: Path, path: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(code_dir), os.environ.get("PYTHONPATH", "")])}
    # cwd outside any tree, so that only PYTHONPATH decides which code is imported.
    out = subprocess.run([sys.executable, "-c", _READ, str(path)], env=env, cwd=tempfile.gettempdir(),
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", metavar="COMMIT", help="also read with this commit, alternating")
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--events", type=int, default=10_000_000)
    args = parser.parse_args()
    cache = ROOT / ".cache" / "bench-read"
    cache.mkdir(parents=True, exist_ok=True)
    files = {"aedat4": cache / f"bench-{args.events}.aedat4", "dsec": cache / f"bench-{args.events}.h5"}
    for name, path in files.items():
        if not path.exists():
            print(f"writing {path} ...", flush=True)
            (write_aedat4 if name == "aedat4" else write_dsec)(path, args.events)
    with baseline_tree(args.baseline) as base:
        trees = {"this tree": ROOT, **({args.baseline: base} if base else {})}
        print("| file | code | min s | median s | runs | load average before, after |\n|---|---|---|---|---|---|")
        for name, path in files.items():
            times = {label: [] for label in trees}
            load_before = os.getloadavg()[0]
            for _ in range(args.runs):
                for label, tree in trees.items():
                    got = _read_once(tree, path)
                    assert got["events"] == args.events, got
                    times[label].append(got["seconds"])
            load_after = os.getloadavg()[0]
            for label, values in times.items():
                print(f"| {name} | {label} | {min(values):.3f} | {statistics.median(values):.3f} | {len(values)} | "
                      f"{load_before:.1f}, {load_after:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
