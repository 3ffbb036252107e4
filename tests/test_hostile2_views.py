"""Hostile views (issue 26, items 4 and 6): time options on clocks far from 0, a recording's stored origin gone
bad, colour-map names, video sizes and the ``--rerun`` output (also ``live``'s), each refused in one line naming
the option or file, with no output left behind.

Cases run ``cvstereo.cli.main`` in-process (``tests/_hostile.py``); every failure message starts with its kind.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cvstereo.io import write_matches, write_recording
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches
from cvstereo.model.recording import Recording
from tests._hostile import Case, case, check_case

pytest.importorskip("matplotlib")
pytestmark = pytest.mark.timeout(120)

#: A DV camera's clock: microseconds since 1970.
T0 = 1_700_000_000_123_456


def _bar(t0: int, n: int = 3000, span_us: int = 2_200_000):
    rng = np.random.default_rng(2)
    t = np.sort(rng.integers(0, span_us, n)) + t0
    x, y, p = rng.integers(40, 80, n), rng.integers(20, 100, n), rng.integers(0, 2, n)
    rec = Recording(make_events(t, x, y, p), make_events(t, x - 5, y, p))
    keep = rng.random(n) < 0.5
    return rec, make_matches(t[keep], x[keep], y[keep], p[keep], 0, np.full(keep.sum(), 5.0))


def _with_meta(src: Path, dst: Path, meta: str) -> None:
    """A copy of the recording ``src`` whose meta is the JSON text ``meta``, written as a foreign tool would."""
    data = dict(np.load(src))
    data["meta"] = np.array(meta)
    np.savez(dst, **data)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("views-base")
    rec, m = _bar(T0)
    write_recording(d / "rec.npz", rec)
    write_matches(d / "m.npz", m, {"method": "event-time", "variant": "shared", "params": {}, "anchor": "event",
                                   "window_us": 0})
    for name, value in {"float": 1.5, "text": "soon", "bool": True, "huge": 2**63, "list": [1]}.items():
        _with_meta(d / "rec.npz", d / f"origin-{name}.npz", json.dumps({"origin_us": value}))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    shutil.copytree(base, tmp_path, dirs_exist_ok=True)
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


CASES = {
    # --- time options on a clock far from 0 -------------------------------------------------------------------
    "plot-start-2000-on-dv-clock": case("plot events rec.npz -o p.png --t-start-ms 2000", 0, writes="p.png"),
    "plot-map-start-2000-on-dv-clock": case("plot disparity-map rec.npz m.npz -o p.png --t-start-ms 2000 --windows 1",
                                            0, writes="p.png"),
    "plot-start-past-end-says-span-from-origin": case("plot events rec.npz -o p.png --t-start-ms 5000", 1,
                                                      ("--t-start-ms 5000", "after its origin"), absent="p.png"),
    # --- a stored origin gone bad -----------------------------------------------------------------------------
    **{f"plot-origin-{name}": case(f"plot events origin-{name}.npz -o p.png", 1, (f"origin-{name}.npz", "origin_us"),
                                   absent="p.png")
       for name in ("float", "text", "bool", "huge", "list")},
    "video-origin-float": case("video origin-float.npz -o v.mp4", 1, ("origin-float.npz", "origin_us"),
                               absent="v.mp4"),
    # --- colour maps ------------------------------------------------------------------------------------------
    "plot-cmap-unknown": case("plot disparity-map rec.npz m.npz -o p.png --cmap nope", 1, ("--cmap", "viridis"),
                              absent="p.png"),
    "plot-cmap-empty": case(["plot", "disparity-map", "rec.npz", "m.npz", "-o", "p.png", "--cmap", ""], 1,
                            "--cmap", absent="p.png"),
    "video-cmap-unknown": case("video rec.npz m.npz -o v.mp4 --cmap nope", 1, "--cmap", absent="v.mp4"),
    "match-rerun-cmap-unknown": case("match rec.npz -o m2.npz --rerun=r.rrd --cmap nope", 1, "--cmap",
                                     absent=("m2.npz", "r.rrd")),
    # --- video size -------------------------------------------------------------------------------------------
    "video-scale-below-one": case("video rec.npz -o v.mp4 --scale 0.5 --seconds 0.04", 0, writes="v.mp4"),
    "video-scale-nan": case("video rec.npz -o v.mp4 --scale nan", 1, "--scale", absent="v.mp4"),
    "video-max-width-tiny": case("video rec.npz -o v.mp4 --max-width 10", 1, "--max-width", absent="v.mp4"),
    "video-max-width-with-scale": case("video rec.npz -o v.mp4 --max-width 640 --scale 2", 2, "--max-width",
                                       absent="v.mp4"),
    # --- the rerun output -------------------------------------------------------------------------------------
    "video-rerun-wrong-suffix": case("video rec.npz -o v.mp4 --rerun=v.txt", 1, ("v.txt", ".rrd"),
                                     absent=("v.mp4", "v.txt")),
    "video-rerun-is-the-input": case("video rec.npz -o v.mp4 --rerun=rec.npz", 1, "rec.npz", absent="v.mp4"),
    "video-rerun-is-the-video": case("video rec.npz -o v.mp4 --rerun=v.mp4", 1, "v.mp4", absent="v.mp4"),
    "match-rerun-into-a-folder": case("match rec.npz -o m2.npz --rerun=sub", 1, "sub", absent="m2.npz"),
    # --- live --rerun: refused before the boards are opened ------------------------------------------------------
    "live-rerun-wrong-suffix": case("live --simulate rec.npz --rerun=l.txt", 1, ("l.txt", ".rrd"), absent="l.txt"),
    "live-rerun-is-the-simulated-recording": case("live --simulate rec.npz --rerun=rec.npz", 1, ("--rerun", "rec.npz")),
    "live-rerun-into-a-folder": case("live --simulate rec.npz --rerun=sub", 1, "sub"),
    "live-rerun-recording-missing": case("live --simulate nope.npz --rerun=l.rrd", 1, "nope.npz", absent="l.rrd"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_view(hostile: Case, work: Path, capsys):
    check_case(hostile, work, capsys)
