"""Depth as data: per-match metres, point clouds in PLY, the depth-model file, dense disparity images per window."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvstereo.geometry.depth import DepthModel
from cvstereo.geometry.depth_file import load_depth_model, save_depth_model
from cvstereo.geometry.disparity_maps import window_disparity_images
from cvstereo.geometry.pointcloud import THESIS_FOCAL_PX, Intrinsics, depth_per_match, point_cloud, write_ply
from cvstereo.model.matches import make_matches

MODEL = DepthModel(a=16.5, c=2.0)


def _matches():
    # Disparities 14.5 and 3.5 px: Z = 16.5 / (d + 2) = 1 m and 3 m; -2.5 px is beyond infinity.
    return make_matches([10, 20, 30, 40], [80, 50, 60, 5], [70, 30, 64, 5], [1, 0, 1, 1], [0, 0, 1, 0],
                        [14.5, 3.5, 14.5, -2.5])


def test_depth_per_match_inverts_the_model():
    z = depth_per_match(_matches(), MODEL)
    assert z.dtype == np.float32
    np.testing.assert_allclose(z[:3], [1.0, 3.0, 1.0], rtol=1e-6)
    assert np.isinf(z[3])
    np.testing.assert_allclose(MODEL.disparity(z[:3]), [14.5, 3.5, 14.5], rtol=1e-5)


def test_point_cloud_geometry_by_hand():
    intr = Intrinsics(100.0, 60.0, 50.0, "test")
    pts = point_cloud(_matches(), MODEL, intr)
    assert pts.size == 3  # the point at infinity is left out
    # X = (x_left - cx) Z / f, Y = (y - cy) Z / f; the right-anchored match sits at x_left = 60 + 14.5.
    np.testing.assert_allclose(pts["x"], [(80 - 60) * 1 / 100, (50 - 60) * 3 / 100, (74.5 - 60) * 1 / 100], rtol=1e-6)
    np.testing.assert_allclose(pts["y"], [(70 - 50) / 100, (30 - 50) * 3 / 100, (64 - 50) / 100], rtol=1e-6)
    np.testing.assert_allclose(pts["z"], [1, 3, 1], rtol=1e-6)


def test_intrinsics_say_where_they_came_from():
    from cvstereo.simulate.rig import Rig

    assert THESIS_FOCAL_PX == Rig().focal_px
    default = Intrinsics.from_options((128, 128))
    assert (default.focal_px, default.cx, default.cy) == (165.0, 63.5, 63.5) and "thesis rig" in default.source
    assert "--focal-px" in Intrinsics.from_options((346, 260), focal_px=200).source
    from cvstereo.geometry.calibration import StereoCalibration

    K = [[200, 0, 170], [0, 200, 130], [0, 0, 1]]
    cal = StereoCalibration.from_opencv(K, None, K, None, np.eye(3), [-0.1, 0, 0], (346, 260), source="c.json")
    got = Intrinsics.from_options((346, 260), calibration=cal)
    assert (got.focal_px, got.cx, got.cy) == (200.0, 170.0, 130.0) and "c.json" in got.source
    with pytest.raises(ValueError, match="not both"):
        Intrinsics.from_options((346, 260), calibration=cal, focal_px=100)


def test_ply_reads_back_with_its_header(tmp_path):
    plyfile = pytest.importorskip("plyfile")
    intr = Intrinsics.from_options((128, 128), focal_px=150)
    pts = point_cloud(_matches(), MODEL, intr)
    path = tmp_path / "cloud.ply"
    write_ply(path, pts, model=MODEL, intrinsics=intr, comments=("input rec.npz",))
    data = plyfile.PlyData.read(str(path))
    v = data["vertex"]
    for name in ("x", "y", "z", "disparity"):
        np.testing.assert_array_equal(v[name], pts[name])
    np.testing.assert_array_equal(v["t"].astype(np.int64), pts["t"])
    assert not data.text and data.byte_order == "<"
    text = "\n".join(data.comments)
    assert "a = 16.5 px*m, c = 2 px" in text and "f = 150 px" in text and "--focal-px" in text
    assert "input rec.npz" in text


def test_depth_model_file_round_trip_and_old_files(tmp_path):
    path = tmp_path / "model.json"
    save_depth_model(path, MODEL, points=[{"file": "a.npz", "distance_m": 0.5}])
    assert load_depth_model(path) == MODEL
    assert json.loads(path.read_text())["points"][0]["file"] == "a.npz"
    # depth-fit's files from before the format had a name: {"a", "c", "points"}.
    path.write_text(json.dumps({"a": 15.75, "c": 2.5, "points": []}))
    assert load_depth_model(path) == DepthModel(15.75, 2.5)
    for bad, msg in (({"c": 1}, "'a' must be a finite number"), ({"a": "x"}, "'a' must be"),
                     ({"a": 1, "format": "other"}, "is not 'cvstereo-depth-model'"), ([1, 2], "JSON object")):
        path.write_text(json.dumps(bad))
        with pytest.raises(ValueError, match=msg):
            load_depth_model(path)
    path.write_text("{nope")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_depth_model(path)


def test_window_disparity_images_for_window_anchors():
    # Window anchors carry the window's end: t = 40000 closes [0, 40000).
    m = make_matches([40_000, 40_000, 80_000], [1, 1, 0], [0, 0, 1], 1, 0, [2.0, 4.0, 7.0])
    got = list(window_disparity_images(m, 0, resolution=(2, 2), window_us=40_000, anchor="window"))
    assert [t for t, _ in got] == [0, 40_000]
    np.testing.assert_array_equal(got[0][1], [[np.nan, 3.0], [np.nan, np.nan]])
    np.testing.assert_array_equal(got[1][1], [[np.nan, np.nan], [7.0, np.nan]])
    assert list(window_disparity_images(m, 1, resolution=(2, 2))) == []


def test_matches_file_carries_depth_m_beside_the_unchanged_matches(tmp_path):
    from cvstereo.io import read_matches, write_matches
    from cvstereo.model.matches import MATCH_DTYPE

    m = _matches()
    meta = {"method": "x", "variant": "y", "params": {}, "anchor": "event", "window_us": 0}
    write_matches(tmp_path / "m.npz", m, meta, arrays={"depth_m": depth_per_match(m, MODEL)})
    back = read_matches(tmp_path / "m.npz")
    assert back.matches.dtype == MATCH_DTYPE
    np.testing.assert_array_equal(back.matches, m)
    np.testing.assert_array_equal(back.arrays["depth_m"], depth_per_match(m, MODEL))
    with np.load(tmp_path / "m.npz") as raw:  # plain numpy sees the documented keys
        assert sorted(raw.files) == ["depth_m", "matches", "meta"] and raw["depth_m"].dtype == np.float32
    with pytest.raises(ValueError, match="one value per match"):
        write_matches(tmp_path / "bad.npz", m, meta, arrays={"depth_m": np.zeros(2)})


def test_window_point_clouds_split_the_recording_cloud():
    from cvstereo.geometry.pointcloud import window_point_clouds

    m = make_matches([10, 39_999, 40_000, 95_000], [80, 50, 60, 70], [70, 30, 64, 64], 1, 0, [14.5, 3.5, 14.5, 3.5])
    intr = Intrinsics(100.0, 60.0, 50.0, "test")
    parts = list(window_point_clouds(m, MODEL, intr, window_us=40_000))
    assert [t for t, _ in parts] == [0, 40_000, 80_000] and [p.size for _, p in parts] == [2, 1, 1]
    np.testing.assert_array_equal(np.concatenate([p for _, p in parts]), point_cloud(m, MODEL, intr))
