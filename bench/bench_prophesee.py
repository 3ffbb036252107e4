"""Prophesee decoders compared on byte-exact files: correctness (event for event) and decoding speed.

Writes EVT 2.0 / 2.1 / 3.0 ``.raw`` and ``.dat`` files with the test writers (tests/_prophesee_files.py, packed
from the published bit layouts), decodes each with every candidate package that claims the format, and
prints a table: events per second (best of ``--repeat``) and whether the output equals the written events.

    python bench/bench_prophesee.py [--events 1000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests._prophesee_files import dat_file, raw_file, scene_events

WIDTH, HEIGHT = 1280, 720


def _faery(path, encoding):
    import faery

    arr = np.concatenate(list(faery.events_stream_from_file(path, dimensions_fallback=(WIDTH, HEIGHT))))
    return arr["t"], arr["x"], arr["y"], arr["on"]


def _evt3(path, encoding):
    import evt3

    r = evt3.decode_file(str(path))
    return r.t, r.x, r.y, r.p


def _expelliarmus(path, encoding):
    from expelliarmus import Wizard

    a = Wizard(encoding=encoding).read(path)
    return a["t"], a["x"], a["y"], a["p"]


def _ours(path, encoding):
    from cvstereo.io.prophesee import _evt21_columns, read_prophesee_header

    return tuple(np.concatenate(c) for c in zip(*_evt21_columns(path, read_prophesee_header(path)), strict=True))


CANDIDATES = {"faery": (_faery, ("evt2", "evt21", "evt3", "dat")), "evt3": (_evt3, ("evt3",)),
              "expelliarmus": (_expelliarmus, ("evt2", "evt3", "dat")),
              "cvstereo numpy": (_ours, ("evt21",))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    events = scene_events(args.events, WIDTH, HEIGHT)
    with tempfile.TemporaryDirectory() as folder:
        files = {}
        for enc in ("evt2", "evt21", "evt3"):
            files[enc] = Path(folder) / f"{enc}.raw"
            raw_file(files[enc], events, enc, WIDTH, HEIGHT)
        files["dat"] = Path(folder) / "cd.dat"
        dat_file(files["dat"], events, WIDTH, HEIGHT)
        print("| decoder | format | Mev/s | event for event |\n| --- | --- | --- | --- |")
        for name, (decode, formats) in CANDIDATES.items():
            for enc in formats:
                best, verdict = float("inf"), ""
                for _ in range(args.repeat):
                    start = time.perf_counter()
                    try:
                        t, x, y, p = decode(files[enc], enc)
                    except BaseException as exc:
                        verdict = f"fails: {str(exc).splitlines()[0][:70]}"
                        break
                    best = min(best, time.perf_counter() - start)
                    same = len(t) == len(events) and all(
                        np.array_equal(np.asarray(a).astype(np.int64), events[k].astype(np.int64))
                        for a, k in ((t, "t"), (x, "x"), (y, "y"), (p, "p")))
                    verdict = "yes" if same else f"no ({len(t)} events of {len(events)})"
                speed = f"{len(events) / best / 1e6:.1f}" if best < float("inf") else "-"
                print(f"| {name} | {enc} | {speed} | {verdict} |", flush=True)


if __name__ == "__main__":
    main()
