"""``cvstereo simulate`` run as a user would: a subprocess, exit codes, files."""

from __future__ import annotations

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
