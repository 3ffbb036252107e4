"""MVSEC's ground-truth depth scored with DSEC's metrics (issue 26 item 5): `cvstereo evaluate NAME_data.hdf5 m.npz
--calibration camchain.yaml` finds NAME_gt.hdf5 beside the data file, turns depth into disparity d = f*B/Z and
scores the matches of the 50 ms before each map; the figures are computed here by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvstereo.cli import main
from cvstereo.model.events import make_events
from cvstereo.model.matches import make_matches

h5py = pytest.importorskip("h5py")

from tests._calibration_fixtures import dump_yaml  # noqa: E402
from tests._hdf5_fixtures import write_mvsec_events  # noqa: E402

W, H = 346, 260
F, B = 226.4, 0.1  # rectified focal length (px) and baseline (m) of the camchain below: d = F*B/Z
T0 = 1_504_645_177_000_000  # us: MVSEC's clock is ROS time in seconds


def _camchain() -> dict:
    """A Kalibr camchain as MVSEC ships one, rectified (identity rotations, equal projections: rectified = raw)."""
    K = [F, F, 173.0, 130.0]
    P = [[F, 0, 173.0, 0], [0, F, 130.0, 0], [0, 0, 1, 0]]
    cam = {"camera_model": "pinhole", "intrinsics": K, "distortion_model": "radtan",
           "distortion_coeffs": [0.0, 0.0, 0.0, 0.0], "resolution": [W, H], "rectification_matrix": np.eye(3).tolist(),
           "projection_matrix": P}
    T = np.eye(4)
    T[0, 3] = -B
    return {"cam0": cam, "cam1": {**cam, "T_cn_cnm1": T.tolist()}}


def _write_truth(path, times_s, depths) -> None:
    with h5py.File(path, "w") as f:
        f.create_dataset("davis/left/depth_image_rect", data=np.asarray(depths, np.float32))
        f.create_dataset("davis/left/depth_image_rect_ts", data=np.asarray(times_s, np.float64))


def test_mvsec_depth_is_scored_as_disparity_with_dsecs_metrics(tmp_path, capsys):
    import cvstereo as cvs

    rng = np.random.default_rng(2)
    n = 4000
    t = np.sort(rng.integers(0, 120_000, n)) + T0
    left = make_events(t, rng.integers(20, 300, n), rng.integers(0, H, n), rng.integers(0, 2, n))
    right = left.copy()
    right["x"] -= 11
    data = tmp_path / "indoor_flying9_data.hdf5"
    write_mvsec_events(data, left, right)
    (tmp_path / "camchain.yaml").write_text(dump_yaml(_camchain()))
    # Two maps, at 50 ms and 100 ms: depth 2 m in rows 10..19 (d = 11.32 px), NaN elsewhere; the second also 4 m.
    depth = np.full((2, H, W), np.nan)
    depth[:, 10:20, :] = 2.0
    depth[1, 100:110, :] = 4.0
    _write_truth(tmp_path / "indoor_flying9_gt.hdf5", [(T0 + 50_000) / 1e6, (T0 + 100_000) / 1e6], depth)

    # Matches with known errors: on the 2 m rows at 40 ms (map 1) and 90 ms (map 2), on the 4 m rows at 80 ms; a
    # right-anchored one lands d px to its right; one outside any window and one where there is no depth count not.
    d2, d4 = F * B / 2.0, F * B / 4.0
    rows = [  # t (us after T0), x, y, camera, disparity, counted error
        (40_000, 50, 12, 0, d2 + 0.5, 0.5), (40_000, 60, 12, 0, d2 - 2.5, 2.5), (90_000, 70, 15, 0, d2 + 1.5, 1.5),
        (80_000, 80, 105, 0, d4 - 0.25, 0.25), (90_000, 100 - 6, 105, 1, 6.0, abs(6.0 - d4)),
        (110_000, 50, 12, 0, 99.0, None), (40_000, 50, 50, 0, 3.0, None)]
    m = make_matches(*(np.array([r[k] for r in rows]) for k in range(3)), 0, np.array([r[3] for r in rows]),
                     np.array([r[4] for r in rows], float))
    m["t"] += T0
    m = m[np.argsort(m["t"], kind="stable")]  # matches files are time-ordered
    meta = cvs.match(cvs.read_recording(data), method="event-time").meta
    cvs.write_matches(tmp_path / "m.npz", m, meta)

    assert main(["evaluate", str(data), str(tmp_path / "m.npz"), "--calibration", str(tmp_path / "camchain.yaml"),
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["figures"]
    e = np.array([r[5] for r in rows if r[5] is not None])
    truth_pixels = 10 * W + 10 * W + 10 * W
    want = {"MAE": e.mean(), "RMSE": np.sqrt(np.mean(e**2)), "1PE": np.mean(e > 1), "2PE": np.mean(e > 2),
            "coverage": e.size / truth_pixels, "maps": 2, "pixels_scored": e.size}
    for key, value in want.items():
        assert got[key] == pytest.approx(value, abs=1e-6), key
    # Without a calibration there is no way into the rectified frame: said in one line.
    assert main(["evaluate", str(data), str(tmp_path / "m.npz")]) == 1
    assert "--calibration" in capsys.readouterr().err
    cal = ["--calibration", str(tmp_path / "camchain.yaml")]
    # A ground-truth file missing, or holding maps of another size: one line naming it.
    assert main(["evaluate", str(data), str(tmp_path / "m.npz"), *cal, "--truth", str(tmp_path / "none.hdf5")]) == 1
    err = capsys.readouterr().err
    assert "none.hdf5: no such MVSEC ground-truth file" in err and len(err.strip().splitlines()) == 1
    _write_truth(tmp_path / "small_gt.hdf5", [(T0 + 50_000) / 1e6], np.ones((1, 10, 10)))
    assert main(["evaluate", str(data), str(tmp_path / "m.npz"), *cal, "--truth", str(tmp_path / "small_gt.hdf5")]) == 1
    err = capsys.readouterr().err
    assert "small_gt.hdf5" in err and "(1, 10, 10)" in err and len(err.strip().splitlines()) == 1
