"""samples/dsec_point_cloud.py on a small DSEC-style sequence of a known scene: the cloud lies on its planes."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("h5py")
plyfile = pytest.importorskip("plyfile")

from tests._dsec_scene import DEPTHS, write_dsec_sequence  # noqa: E402
from tests._paths import REPO  # noqa: E402

SAMPLE = REPO / "samples" / "dsec_point_cloud.py"


def _relative_error_to_nearest_plane(z: np.ndarray) -> np.ndarray:
    planes = np.asarray(DEPTHS)
    nearest = planes[np.argmin(np.abs(z[:, None] - planes[None]), axis=1)]
    return np.abs(z - nearest) / nearest


def test_dsec_point_cloud_sample(tmp_path):
    seq = write_dsec_sequence(tmp_path / "seq", seconds=0.2)
    out = tmp_path / "cloud.ply"
    proc = subprocess.run([sys.executable, str(SAMPLE), str(seq), "--seconds", "0.2", "-o", str(out)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "points" in proc.stdout and str(out) in proc.stdout
    data = plyfile.PlyData.read(str(out))
    z = np.asarray(data["vertex"]["z"], np.float64)
    assert z.size > 1000
    # The scene's dots lie at 2 m and 4 m: nearly every point within 10 % of one of them (unrectified: ~10 %).
    assert (_relative_error_to_nearest_plane(z) < 0.1).mean() > 0.9
    both = [np.mean(np.abs(z - d) / d < 0.1) for d in DEPTHS]
    assert min(both) > 0.05  # the box and the wall both appear
    assert any("calibration cam_to_cam.yaml" in c for c in data.comments)


def test_match_cli_with_calibration_and_point_cloud(tmp_path):
    seq = write_dsec_sequence(tmp_path / "seq", seconds=0.1, seed=1)
    ev = seq / "events"
    proc = subprocess.run([sys.executable, "-m", "cvstereo", "match", str(ev / "left" / "events.h5"),
                           str(ev / "right" / "events.h5"), "--method", "sgbm", "--calibration",
                           str(seq / "calibration" / "cam_to_cam.yaml"), "--point-cloud", "c.ply", "-o", "m.npz"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    from cvstereo.io import read_matches

    result = read_matches(tmp_path / "m.npz")
    assert result.meta["rectification"]["source"] == "cam_to_cam.yaml"
    depth = result.arrays["depth_m"]
    assert depth.dtype == np.float32 and depth.shape == result.matches.shape
    assert (_relative_error_to_nearest_plane(depth[np.isfinite(depth)].astype(float)) < 0.1).mean() > 0.9
    z = np.asarray(plyfile.PlyData.read(str(tmp_path / "c.ply"))["vertex"]["z"])
    assert z.size == np.isfinite(depth).sum()


def test_dsec_point_cloud_sample_per_window(tmp_path):
    seq = write_dsec_sequence(tmp_path / "seq", seconds=0.1, seed=2)
    proc = subprocess.run([sys.executable, str(SAMPLE), str(seq), "--window-ms", "40", "-o", "w.ply"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    files = sorted(tmp_path.glob("w_*.ply"))
    starts = [int(f.stem.split("_")[1]) for f in files]
    assert len(files) >= 2 and all(s % 40_000 == 0 for s in starts)
    total = sum(plyfile.PlyData.read(str(f))["vertex"].count for f in files)
    assert f"{total} points" in proc.stdout


def test_dsec_point_cloud_sample_takes_left_right_like_the_cli(tmp_path):
    seq = write_dsec_sequence(tmp_path / "seq", seconds=0.1, seed=3)
    ev, cal = seq / "events", str(seq / "calibration" / "cam_to_cam.yaml")
    left, right = str(ev / "left" / "events.h5"), str(ev / "right" / "events.h5")
    forms = {"pos.ply": [left, right], "opt.ply": ["--left", left, "--right", right],
             "mixed.ply": [left, "--right", right]}
    z = {}
    for name, inputs in forms.items():
        proc = subprocess.run([sys.executable, str(SAMPLE), *inputs, "--calibration", cal, "-m", "event-time",
                               "--seconds", "0.1", "-o", name], cwd=tmp_path, capture_output=True, text=True,
                              timeout=600)
        assert proc.returncode == 0, proc.stderr
        z[name] = np.asarray(plyfile.PlyData.read(str(tmp_path / name))["vertex"]["z"], np.float64)
    assert z["pos.ply"].size > 1000
    assert all(np.array_equal(v, z["pos.ply"]) for v in z.values())
    assert (_relative_error_to_nearest_plane(z["pos.ply"]) < 0.1).mean() > 0.9  # event-time, on the planes
    proc = subprocess.run([sys.executable, str(SAMPLE), left, right], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 2 and "--calibration" in proc.stderr
