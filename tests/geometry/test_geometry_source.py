"""The geometry's precedence rule (cvstereo.geometry.source), from the library side."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.geometry.calibration import StereoCalibration
from cvstereo.geometry.depth import DepthModel
from cvstereo.geometry.source import GeometryConflict, GeometryOptions, as_matched, depth_for_matches
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording

RIG = {"rig": {"focal_px": 165.0, "baseline_m": 0.1, "axis_offset_px": 3.0, "vertical_offset_px": 1.0,
               "resolution": [128, 128]}}
RES = (128, 128)


def _calibration() -> StereoCalibration:
    K = [[150.0, 0, 63.5], [0, 150.0, 63.5], [0, 0, 1]]
    return StereoCalibration.from_opencv(K, None, K, None, np.eye(3), [-0.2, 0, 0], RES, source="cal.json")


class _Report:
    """What the rig check reports, as far as the rule uses it: swap the cameras, rows -2, time 300 us."""

    def prepare(self, recording):
        return recording.swapped()

    def match_kwargs(self):
        return {"row_offset": -2, "time_offset_us": 300}

    def to_dict(self):
        return {"swap": True}


def _recording() -> Recording:
    ev = make_events([0, 10], [5, 6], [1, 1], [1, 0])
    return Recording(ev, ev[:1])


def test_a_calibration_gives_rows_depth_and_focal_length():
    g = GeometryOptions(calibration=_calibration(), point_cloud=True).resolve(RIG, RES)
    # d = f*B/Z - c of the rectified pair: f = 150 px (no distortion, same K), B = 0.2 m, c = 0.
    assert g.depth.a == pytest.approx(30.0) and g.depth.c == pytest.approx(0.0, abs=1e-9)
    assert g.intrinsics.focal_px == pytest.approx(150.0)
    assert g.sources == {"rows": "calibration", "depth": "calibration", "intrinsics": "calibration"}
    assert "rectification" in g.match_kwargs() and g.describe()["source"] == "calibration"
    assert g.summary() == ("geometry: rows rectified, depth d = 30.00/Z - 0.00, focal length 150 px from calibration "
                           "cal.json; time as recorded")


def test_options_win_over_the_recording_and_the_recording_over_the_default():
    g = GeometryOptions(depth=DepthModel(20.0, 1.0), focal_px=200.0, point_cloud=True).resolve(RIG, RES)
    assert (g.depth, g.intrinsics.focal_px) == (DepthModel(20.0, 1.0), 200.0)
    assert g.sources == {"depth": "options", "intrinsics": "options"}
    g = GeometryOptions(point_cloud=True).resolve(RIG, RES)
    # The simulator's rig: a = 165 * 0.1, c = 3; the left principal point half the offsets left of and above centre.
    assert g.depth == DepthModel(16.5, 3.0)
    assert (g.intrinsics.focal_px, g.intrinsics.cx, g.intrinsics.cy) == (165.0, 62.0, 63.0)
    assert g.describe()["source"] == "recording"
    g = GeometryOptions(point_cloud=True).resolve({}, RES)
    assert g.depth is None and g.sources == {"intrinsics": "default"} and g.describe()["source"] == "none"
    assert g.summary().endswith("rows and time as recorded; no depth model")


def test_the_rig_check_fills_what_nothing_stronger_gives():
    rec = _recording()
    g = GeometryOptions(row_offset=1, rig_check=lambda r: _Report()).resolve({}, RES, recording=rec)
    assert (g.swap, g.row_offset, g.time_offset_us) == (True, 1, 300)
    assert g.sources == {"rows": "options", "side": "rigcheck", "time": "rigcheck"}
    assert g.rigcheck["applied"] == {"swap": True, "row_offset": 1, "time_offset_us": 300}
    prepared = g.prepare(rec)
    assert prepared.left.size == 1 and prepared.right.size == 2
    assert g.match_kwargs() == {"row_offset": 1, "time_offset_us": 300}


@pytest.mark.parametrize("given", [{"depth": DepthModel(1.0)}, {"focal_px": 100.0}, {"row_offset": 0},
                                   {"time_offset_us": 5}, {"rig_check": print}])
def test_a_calibration_and_an_option_for_the_same_thing_conflict(given):
    with pytest.raises(GeometryConflict, match="--calibration gives the geometry itself"):
        GeometryOptions(calibration=_calibration(), **given)


@pytest.mark.parametrize("focal", [0.0, -1.0, float("inf"), float("nan")])
def test_the_focal_length_is_finite_and_positive(focal):
    with pytest.raises(ValueError, match="--focal-px must be a finite number > 0"):
        GeometryOptions(focal_px=focal)


def test_pictures_take_a_calibrated_depth_model_over_the_option():
    calibrated = {"depth": {"a": 30.0, "c": 0.0}, "geometry": {"depth": {"source": "calibration"}}}
    assert depth_for_matches(calibrated, RIG) == DepthModel(30.0)
    with pytest.raises(GeometryConflict, match="leave out --depth"):
        depth_for_matches(calibrated, RIG, depth=DepthModel(5.0))
    stored = {"depth": {"a": 30.0, "c": 0.0}, "geometry": {"depth": {"source": "options"}}}
    assert depth_for_matches(stored, RIG, depth=DepthModel(5.0)) == DepthModel(5.0)
    assert depth_for_matches({}, RIG) == DepthModel(16.5, 3.0)
    assert depth_for_matches(stored, RIG, metres=False) is None


def test_matches_of_exchanged_cameras_get_the_recording_exchanged():
    rec = _recording()
    assert as_matched(rec, {"geometry": {"side": {"swap": True}}}).left.size == 1
    assert as_matched(rec, {"geometry": {"side": {"swap": False}}}) is rec
    assert as_matched(rec, {}) is rec


def test_the_recording_is_read_for_the_rig_check_only():
    # A recording matched as a stream is read whole only when the rig check runs: resolve() takes a function
    # that reads it and calls it then, once.
    reads = []

    def read():
        reads.append(1)
        return _recording()

    GeometryOptions(row_offset=1).resolve({}, RES, recording=read)
    assert reads == []
    g = GeometryOptions(rig_check=lambda r: _Report()).resolve({}, RES, recording=read)
    assert reads == [1] and (g.swap, g.row_offset, g.time_offset_us) == (True, -2, 300)


def test_a_swapped_stream_is_the_swapped_recording(tmp_path):
    from cvstereo.io import open_recording, write_recording

    left = make_events([0, 10, 20], [5, 6, 7], [1, 1, 2], [1, 0, 1])
    right = make_events([5, 15], [3, 4], [1, 1], [1, 1])
    rec = Recording(left, right, np.array([2.0, 2.0, 3.0], np.float32), np.array([2.0, 2.5], np.float32))
    write_recording(tmp_path / "r.npz", rec)
    stream = open_recording(tmp_path / "r.npz")
    got, expected = stream.swapped().read(), rec.swapped()
    for a, b in ((got.left, expected.left), (got.right, expected.right),
                 (got.left_disparity, [-2.0, -2.5]), (got.right_disparity, [-2.0, -2.0, -3.0])):
        np.testing.assert_array_equal(a, b)
    assert stream.swapped().files == stream.files  # what was read, whatever the order it is matched in


def test_the_steps_record_the_geometry_the_depth_and_the_point_cloud():
    from cvstereo.geometry.steps import point_cloud_of, record_geometry
    from cvstereo.model.matches import MatchResult, make_matches

    def result():
        matches = make_matches([1000, 2000, 3000], [70, 80, 90], [64, 64, 10], [1, 1, 1], [0, 1, 0],
                               [5.5, 3.0, -3.0])
        return MatchResult(matches, {"fingerprint": {"left": "L", "right": "R"}})

    g = GeometryOptions(point_cloud=True, rig_check=lambda r: _Report()).resolve(RIG, RES, recording=_recording())
    r = record_geometry(result(), g)
    # d = 16.5/Z - 3 (the recording's rig): Z = 16.5 / (d + 3); d = -3 is at infinity.
    np.testing.assert_allclose(r.arrays["depth_m"], [16.5 / 8.5, 16.5 / 6.0, np.inf], rtol=1e-6)
    assert (r.meta["depth"]["a"], r.meta["depth"]["c"]) == (16.5, 3.0)
    assert r.meta["geometry"]["side"] == {"source": "rigcheck", "swap": True}
    assert r.meta["rigcheck"]["applied"]["swap"] is True
    assert r.meta["fingerprint"] == {"left": "R", "right": "L"}  # the files as read, not as exchanged
    points = point_cloud_of(r, g)
    # Two finite points; the right-anchored one sits at its left column 80 + 3; f 165, principal point (62, 63).
    np.testing.assert_allclose(points["z"], [16.5 / 8.5, 16.5 / 6.0], rtol=1e-6)
    np.testing.assert_allclose(points["x"], [(70 - 62) * 16.5 / 8.5 / 165, (83 - 62) * 16.5 / 6.0 / 165],
                               rtol=1e-5)
    np.testing.assert_allclose(points["y"], [(64 - 63) * 16.5 / 8.5 / 165, (64 - 63) * 16.5 / 6.0 / 165],
                               rtol=1e-5)
    with pytest.raises(ValueError, match="needs a depth model"):
        point_cloud_of(result(), GeometryOptions(point_cloud=True).resolve({}, RES))
    with pytest.raises(ValueError, match="needs the intrinsics"):
        point_cloud_of(result(), GeometryOptions().resolve(RIG, RES))
    plain = record_geometry(result(), GeometryOptions(metres=False).resolve(RIG, RES))
    assert "depth_m" not in plain.arrays and "depth" not in plain.meta and "rigcheck" not in plain.meta
    assert plain.meta["fingerprint"] == {"left": "L", "right": "R"}
