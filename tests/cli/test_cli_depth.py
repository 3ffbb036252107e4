"""`cvstereo depth-fit` and the distance output of `cvstereo match`."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from cvstereo.io import read_matches, write_matches, write_recording_npz
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches
from cvstereo.model.recording import Recording

META = {"method": "frame", "variant": "shared", "params": {}, "anchor": "window", "window_us": 40_000}


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "cvstereo", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


def test_depth_fit_from_matches_files_recovers_a_and_c(tmp_path):
    # Disparities of a rig with a = 16 px m and c = 2.5 px at 0.5 and 1.5 m: 29.5 and 8.1667 px.
    for z in (0.5, 1.5):
        d = np.full(11, 16.0 / z - 2.5, np.float32)
        write_matches(tmp_path / f"m{z}.npz", make_matches(np.arange(11) * 40_000 + 40_000, 5, 5, 1, 0, d), META)
    proc = _cli("depth-fit", "m0.5.npz:0.5", "m1.5.npz:1.5", "-o", "depth.json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    model = json.loads((tmp_path / "depth.json").read_text())
    assert model["a"] == pytest.approx(16.0, abs=1e-4) and model["c"] == pytest.approx(2.5, abs=1e-4)
    assert "--depth 16.0000 2.5000" in proc.stdout


@pytest.mark.parametrize(("args", "message"), [
    (["m.npz"], "is not FILE:DISTANCE"),
    (["m.npz:0.5", "m.npz:0.5"], "two or more different distances"),
    (["m.npz:-1", "m.npz:2"], "is not FILE:DISTANCE"),
])
def test_depth_fit_user_errors(tmp_path, args, message):
    proc = _cli("depth-fit", *args, cwd=tmp_path)
    assert proc.returncode == 1 and message in proc.stderr and "Traceback" not in proc.stderr


def test_match_prints_distance_and_stores_the_model(tmp_path):
    # A vertical bar pattern seen 10 px further left by the right camera, in two 40 ms windows.
    rng = np.random.default_rng(0)
    n = 4000
    x, y, p = rng.integers(20, 100, n), rng.integers(0, 128, n), (rng.integers(0, 128, n) % 2)
    x = x - x % 4  # bars every 4 px, so the frame matcher finds clusters
    t = np.sort(rng.integers(0, 80_000, n))
    rec = Recording(make_events(t, x, y, p), make_events(t, x - 10, y, p))
    write_recording_npz(tmp_path / "rec.npz", rec)
    proc = _cli("match", "rec.npz", "--method", "stereobm", "--depth", "16", "2.5", "-o", "m.npz", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    meta = read_matches(tmp_path / "m.npz").meta
    assert meta["depth"] == {"a": 16.0, "c": 2.5}
    # Median disparity 10 px -> Z = 16 / (10 + 2.5) = 1.28 m.
    assert "median 10.00 px" in proc.stdout and "distance: median 1.28 m" in proc.stdout


def test_depth_fit_file_is_read_by_depth_option(tmp_path):
    for z in (0.5, 1.5):
        d = np.full(11, 16.0 / z - 2.5, np.float32)
        write_matches(tmp_path / f"m{z}.npz", make_matches(np.arange(11) * 40_000 + 40_000, 5, 5, 1, 0, d), META)
    assert _cli("depth-fit", "m0.5.npz:0.5", "m1.5.npz:1.5", "-o", "model.json", cwd=tmp_path).returncode == 0
    rng = np.random.default_rng(0)
    n = 4000
    x, y, p = rng.integers(20, 100, n), rng.integers(0, 128, n), (rng.integers(0, 128, n) % 2)
    x = x - x % 4
    t = np.sort(rng.integers(0, 80_000, n))
    write_recording_npz(tmp_path / "rec.npz", Recording(make_events(t, x, y, p), make_events(t, x - 10, y, p)))
    proc = _cli("match", "rec.npz", "--method", "stereobm", "--depth", "model.json", "-o", "m.npz", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    meta = read_matches(tmp_path / "m.npz").meta
    assert meta["depth"]["a"] == pytest.approx(16.0, abs=1e-4) and meta["depth"]["c"] == pytest.approx(2.5, abs=1e-4)
    assert "distance: median 1.28 m" in proc.stdout
    bad = _cli("match", "rec.npz", "--method", "stereobm", "--depth", "nope.json", "-o", "m.npz", cwd=tmp_path)
    assert bad.returncode == 1 and "no such depth-model file" in bad.stderr and "Traceback" not in bad.stderr
    bad = _cli("match", "rec.npz", "--method", "stereobm", "--depth", "1", "x", "-o", "m.npz", cwd=tmp_path)
    assert bad.returncode == 1 and "two numbers A C or one depth-model file" in bad.stderr
