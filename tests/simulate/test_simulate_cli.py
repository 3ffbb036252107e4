"""``cvstereo simulate`` run as a user would: a subprocess, exit codes, files."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from cvstereo.io.npz import read_recording_npz


def _run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "cvstereo", "simulate", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_list_presets():
    out = _run("--list-presets")
    assert out.returncode == 0, out.stderr
    names = [line.split()[0] for line in out.stdout.splitlines()]
    assert names == ["1arm-50cm", "1arm-100cm", "1arm-150cm", "2arms-50cm", "2arms-100cm", "2arms-150cm"]


def test_preset_writes_a_recording_with_truth_and_meta(tmp_path):
    out = _run("--preset", "1arm-100cm", "--seconds", "0.1", "-o", str(tmp_path / "r.npz"), "--no-progress")
    assert out.returncode == 0, out.stderr
    rec = read_recording_npz(tmp_path / "r.npz")
    assert rec.has_truth and rec.left.size > 0 and rec.right.size > 0
    assert rec.meta["preset"] == "1arm-100cm"
    assert rec.meta["rig"]["focal_px"] > 0 and rec.meta["scene"]["distance_m"] == 1.0


def test_scene_is_deterministic_for_a_seed(tmp_path):
    args = ("--scene", "arms", "--arms", "2", "--distance", "1.2", "--seconds", "0.05", "--seed", "5")
    for name in ("a.npz", "b.npz"):
        out = _run(*args, "-o", str(tmp_path / name))
        assert out.returncode == 0, out.stderr
    a, b = read_recording_npz(tmp_path / "a.npz"), read_recording_npz(tmp_path / "b.npz")
    np.testing.assert_array_equal(a.left, b.left)
    np.testing.assert_array_equal(a.right_disparity, b.right_disparity)
    assert a.meta["scene"] == b.meta["scene"] and a.meta["scene"]["arms"] == 2 and a.meta["seed"] == 5


def test_bad_preset_is_one_line_and_exit_1(tmp_path):
    out = _run("--preset", "3arms-20cm", "-o", str(tmp_path / "x.npz"))
    assert out.returncode == 1
    assert len(out.stderr.strip().splitlines()) == 1 and "1arm-50cm" in out.stderr
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("args", [(), ("--preset", "1arm-50cm"), ("--scene", "rotation", "--arms", "2", "-o", "x.npz")])
def test_usage_errors_exit_2(args, tmp_path):
    out = _run(*args, cwd=tmp_path)
    assert out.returncode == 2
    assert "usage" in out.stderr and "Traceback" not in out.stderr


def test_seconds_beyond_the_limit_is_one_line_naming_the_option(tmp_path):
    out = _run("--preset", "1arm-50cm", "--seconds", "1e12", "-o", str(tmp_path / "x.npz"))
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--seconds" in lines[0] and "600" in lines[0] and "Traceback" not in out.stderr
    assert not (tmp_path / "x.npz").exists()


def test_fan_scene_writes_a_fan_recording(tmp_path):
    out = _run("--scene", "fan", "--distance", "1.5", "--seconds", "0.05", "-o", str(tmp_path / "f.npz"),
               "--no-progress")
    assert out.returncode == 0, out.stderr
    rec = read_recording_npz(tmp_path / "f.npz")
    assert rec.meta["scene"]["type"] == "fan" and rec.meta["scene"]["blade_period_s"] == 0.018
    assert rec.meta["render_hz"] == 5000.0
    truth = rec.left_disparity[np.isfinite(rec.left_disparity)]
    assert truth.size > 100 and abs(np.median(truth) - 8.0) < 0.5  # 1.5 m on the thesis' rig


def test_list_suites_names_every_recording():
    out = _run("--list-suites")
    assert out.returncode == 0, out.stderr
    suites: dict[str, list[str]] = {}  # header line -> the recordings' names below it (indented)
    for line in out.stdout.splitlines():
        if line.startswith("  "):
            suites[next(reversed(suites))].append(line.split()[0])
        else:
            suites[line] = []
    (v1, names), (v2, names2) = suites.items()
    assert v1.startswith("robustness (v1): 29 recordings")
    assert names[0] == "base" and "fan-right-3ms-early" in names and len(names) == 29
    assert v2.startswith("generalization (v2): 48 recordings of 1.5 s;")
    assert names2[0] == "objects-tune-128x128" and names2[-1] == "thin-eval-640x480" and len(names2) == 48


def test_suite_output_must_be_a_folder(tmp_path):
    (tmp_path / "file.npz").write_bytes(b"keep")
    out = _run("--suite", "robustness", "-o", str(tmp_path / "file.npz"))
    assert out.returncode == 1 and "folder" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert (tmp_path / "file.npz").read_bytes() == b"keep"


@pytest.mark.slow
def test_suite_fills_the_cache_and_copies_each_recording(tmp_path):
    env = {**os.environ, "CVSTEREO_CACHE": str(tmp_path / "cache")}
    out = subprocess.run([sys.executable, "-m", "cvstereo", "simulate", "--suite", "robustness", "--seconds", "0.05",
                          "-o", str(tmp_path / "suite"), "--no-progress"], capture_output=True, text=True,
                         timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    rows = out.stdout.splitlines()
    assert len(rows) == 29 and "29 recordings ready" in out.stderr
    rec = read_recording_npz(tmp_path / "suite" / "sensor-640x480.npz")
    assert rec.resolution == (640, 480) and rec.meta["suite"]["factor"] == "sensor"
    assert rec.meta["suite"]["max_disparity"] == 320
    assert len(list((tmp_path / "cache").glob("robustness_*.npz"))) == 29
    again = subprocess.run([sys.executable, "-m", "cvstereo", "simulate", "--suite", "robustness", "--seconds", "0.05"],
                           capture_output=True, text=True, timeout=600, env=env)
    assert again.returncode == 0 and "generated" not in again.stderr  # all from the cache
