"""Rectification with a calibration: lookup tables against projected 3D points, the stage's bookkeeping, and a
rotated simulated rig that gives the aligned rig's disparities once rectified."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calibration_free import match
from cvstereo.geometry.calibration import StereoCalibration
from cvstereo.geometry.rectify import NONE, Rectification
from cvstereo.model.events import StereoPacket, make_events
from cvstereo.model.matches import make_matches
from cvstereo.model.recording import Recording
from tests._io_helpers import random_events

RES = (128, 128)
F, B = 165.0, 0.10
K = np.array([[F, 0, 63.5], [0, F, 63.5], [0, 0, 1.0]])


def _rotation(degrees: float, axis=(0.2, 0.3, 1.0)) -> np.ndarray:
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    return cv2.Rodrigues(axis * np.deg2rad(degrees))[0]


def _rotated_rig(degrees: float = 2.0, rows: float = 3.0):
    """The right camera rotated by `degrees` and its principal point `rows` lower: (K_right, R, T)."""
    R_rot = _rotation(degrees)
    K_right = K.copy()
    K_right[1, 2] += rows
    # Right camera frame: x_right = R_rot @ (x_left - (B, 0, 0)).
    return K_right, R_rot, -R_rot @ np.array([B, 0.0, 0.0])


@pytest.mark.parametrize("model, D", [("radtan", [-0.12, 0.03, 0.001, -0.002]), ("equidistant", [0.05, -0.01, 0, 0])])
def test_rectified_pixels_of_a_scene_point_share_a_row_and_give_fB_over_Z(model, D):
    K_right, R, T = _rotated_rig()
    cal = StereoCalibration.from_opencv(K, D, K_right, D, R, T, RES, model=model)
    rect = Rectification(cal)
    rng = np.random.default_rng(1)
    Z = rng.uniform(0.5, 3.0, 400)
    pts = np.column_stack([rng.uniform(-0.25, 0.25, 400) * Z, rng.uniform(-0.25, 0.25, 400) * Z, Z])
    project = cv2.fisheye.projectPoints if model == "equidistant" else cv2.projectPoints
    rvec = cv2.Rodrigues(R)[0]
    raw = [project(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, np.array(D))[0].reshape(-1, 2),
           project(pts.reshape(-1, 1, 3), rvec, T, K_right, np.array(D))[0].reshape(-1, 2)]
    px = [np.rint(r).astype(int) for r in raw]
    inside = np.all([(p >= 0).all(axis=1) & (p < 128).all(axis=1) for p in px], axis=0)
    got = [rect.lut[c][px[c][inside, 1], px[c][inside, 0]] for c in (0, 1)]
    ok = (got[0][:, 0] != NONE) & (got[1][:, 0] != NONE)
    assert ok.mean() > 0.9
    rows = got[0][ok, 1].astype(float) - got[1][ok, 1]
    disparity = got[0][ok, 0].astype(float) - got[1][ok, 0]
    # Whole-pixel rounding twice (projection, table): within 1.5 px; on average within half a pixel.
    assert np.abs(rows).max() <= 1.5 and np.abs(rows).mean() < 0.5
    expected = cal.depth_model().disparity(Z[inside][ok])
    assert np.abs(disparity - expected).max() <= 2.0 and np.median(np.abs(disparity - expected)) <= 0.75
    # The inverse map sends each rectified pixel back near the raw pixel it came from.
    back = rect.inverse[0][got[0][ok, 1], got[0][ok, 0]]
    assert np.abs(back.astype(float) - px[0][inside][ok]).max() <= 2


def test_aligned_calibration_changes_nothing(rng):
    K_ = K.copy()
    cal = StereoCalibration.from_opencv(K_, None, K_, None, np.eye(3), [-B, 0, 0], RES)
    rect = Rectification(cal)
    left, right = random_events(rng, 300, RES), random_events(rng, 200, RES)
    stream = rect.stream([StereoPacket(left, right, int(max(left["t"][-1], right["t"][-1])) + 1)])
    (packet,) = list(stream)
    np.testing.assert_array_equal(packet.left, left)
    np.testing.assert_array_equal(packet.right, right)
    assert stream.dropped == [0, 0]


def test_restore_finds_the_anchoring_raw_event(rng):
    K_right, R, T = _rotated_rig(4.0, 5.0)
    rect = Rectification(StereoCalibration.from_opencv(K, None, K_right, None, R, T, RES))
    left, right = random_events(rng, 2000, RES), random_events(rng, 2000, RES)
    cut = int(left["t"][1000])
    packets = [StereoPacket(ev_l, ev_r, until) for ev_l, ev_r, until in
               ((left[left["t"] < cut], right[right["t"] < cut], cut),
                (left[left["t"] >= cut], right[right["t"] >= cut], 10**9))]
    stream = rect.stream(packets)
    restored_l, kept_l = [], []
    for raw_left, packet in zip((p.left for p in packets), stream, strict=True):
        # A "matcher" that anchors one match on every rectified left event.
        found = make_matches(packet.left["t"], packet.left["x"], packet.left["y"], packet.left["p"], 0, 1.0)
        restored_l.append(stream.restore(found))
        kept_l.append(raw_left[rect.rectify(raw_left, 0)[1]])
    got, want = np.concatenate(restored_l), np.concatenate(kept_l)
    # Several raw pixels can share a rectified pixel; the restored match names the one that fired, at that time.
    same_key = (got["t"] == want["t"]) & (got["p"] == want["p"])
    assert same_key.all()
    exact = (got["x"] == want["x"]) & (got["y"] == want["y"])
    assert exact.mean() > 0.99  # the rest: two raw events with the same t, p and rectified pixel
    assert sum(stream.dropped) > 0  # a 4 degree turn and 5 rows push some pixels off the sensor
    assert stream.dropped[0] + want.size == left.size


def _rotate_right_camera(rec: Recording, K_right, R_rot) -> Recording:
    """The recording as the rotated right camera would have seen it: each pixel through K_right R_rot K^-1."""
    H = K_right @ R_rot @ np.linalg.inv(K)
    ev = rec.right
    p = H @ np.vstack([ev["x"], ev["y"], np.ones(ev.size)])
    x, y = np.rint(p[0] / p[2]), np.rint(p[1] / p[2])
    inside = (x >= 0) & (x < RES[0]) & (y >= 0) & (y < RES[1])
    right = make_events(ev["t"][inside], x[inside], y[inside], ev["p"][inside])
    return Recording(rec.left, right, None, None, RES, {})


def _left_disparities(result) -> dict:
    m = result.matches[result.matches["camera"] == 0]
    return {(int(t), int(x), int(y), int(p)): float(d) for t, x, y, p, d in
            zip(m["t"], m["x"], m["y"], m["p"], m["disparity"], strict=True)}


@pytest.fixture(scope="module")
def aligned():
    from cvstereo.simulate import MotorcycleScene, Rig, simulate

    rig = Rig().ideal()
    assert rig.focal_px == F and rig.baseline_m == B
    # Real texture in every direction (an arm's vertical edges would match even on the wrong rows).
    return simulate(MotorcycleScene(), rig=rig, seconds=0.25, seed=3)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["event-area", "sgbm"])
def test_rotated_rig_rectified_gives_the_aligned_disparities(aligned, method):
    K_right, R_rot, T = _rotated_rig(2.0, 3.0)
    turned = _rotate_right_camera(aligned, K_right, R_rot)
    rect = Rectification(StereoCalibration.from_opencv(K, None, K_right, None, R_rot, T, RES))
    reference = _left_disparities(match(aligned, method=method))
    fixed = match(turned, method=method, rectification=rect)
    assert fixed.meta["rectification"]["dropped_events"] >= 0
    shared = sorted(set(reference) & set(_left_disparities(fixed)))
    assert len(shared) > 0.5 * len(reference)
    got = _left_disparities(fixed)
    diff = np.array([got[k] - reference[k] for k in shared])
    assert np.median(np.abs(diff)) <= 0.5
    # The same rig without rectification is off by more than the rectified one may be: the test can tell.
    raw = _left_disparities(match(turned, method=method))
    common = sorted(set(reference) & set(raw))
    off = np.array([raw[k] - reference[k] for k in common])
    assert len(common) < 0.5 * len(reference) or np.median(np.abs(off)) > 0.5


def test_truth_follows_the_kept_events_and_resolution_must_match(rng):
    K_right, R, T = _rotated_rig(4.0, 5.0)
    rect = Rectification(StereoCalibration.from_opencv(K, None, K_right, None, R, T, RES))
    left, right = random_events(rng, 500, RES), random_events(rng, 500, RES)
    lt, rt = rng.uniform(0, 30, 500).astype(np.float32), rng.uniform(0, 30, 500).astype(np.float32)
    (packet,) = list(rect.stream([StereoPacket(left, right, 10**9, lt, rt)]))
    for raw, truth, cam, got, got_truth in ((left, lt, 0, packet.left, packet.left_disparity),
                                            (right, rt, 1, packet.right, packet.right_disparity)):
        kept = rect.rectify(raw, cam)[1]
        np.testing.assert_array_equal(got_truth, truth[kept])
        np.testing.assert_array_equal(got["t"], raw["t"][kept])
    rec = Recording(left[left["x"] < 64], right[right["x"] < 64], resolution=(64, 128))
    with pytest.raises(ValueError, match="calibration is for 128x128, the recording is 64x128"):
        match(rec, method="sgbm", rectification=rect)
    with pytest.raises(ValueError, match="not both"):
        match(Recording(left, right), method="sgbm", rectification=rect, row_offset=2)
