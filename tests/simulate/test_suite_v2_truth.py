"""Suite v2's per-event truth under every rig imperfection, and the sensor effects it added, by hand or by OpenCV.

The truth of an event is ``x_left - x_right`` of where its scene point lands in the two recorded images. The
expected values here come from OpenCV's own camera model (``cv2.projectPoints`` / ``cv2.undistortPoints``,
which share the simulator's pinhole + radial ``k1`` model and take a roll as a rotation about the optical axis),
from the plane's geometry (``d = f*B/Z - c``, ``d = B * (y - cy) / h`` on a ground plane), or from the pixel
model's definition worked out by hand (crossing times, event counts, Poisson rates).
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from cvstereo.simulate import (
    FamilyScene,
    LayeredScene,
    Motion,
    PlaneLayer,
    Rig,
    SensorModel,
    load_suite,
    simulate,
    textures,
)
from cvstereo.simulate.dvs import DARK_LEVEL, PixelArray

QUIET = SensorModel(on_threshold=0.2, off_threshold=0.3).ideal()

#: A rig with every imperfection suite v2 draws, at the ends of its ranges or beyond.
CROOKED = Rig(resolution=(128, 96), axis_offset_px=3.0, vertical_offset_px=1.7, distortion_k1=-0.12,
              right_distortion_k1=-0.03, roll_deg=1.5, focal_ratio=1.025, left=QUIET, right=QUIET)


def _plane(distance_m: float, *, speed_widths_s: float = 0.3) -> LayeredScene:
    """A noise texture filling the view at ``distance_m``, sliding sideways."""
    texel = textures.texel_size(distance_m, 165.0)
    rng = np.random.default_rng(3)
    img = (0.4 * np.exp(0.5 * textures.smooth_noise(rng, (600, 600), 2.0))).astype(np.float32)
    speed = speed_widths_s * 128 / 165 * distance_m
    return LayeredScene((PlaneLayer("plane", img, np.ones_like(img), texel,
                                    Motion((0.0, 0.0, distance_m), velocity=(speed, 0.0, 0.0))),))


def _opencv_camera(rig: Rig, index: int):
    """K, distortion, roll vector and optical centre of one camera, read from the rig's parameters."""
    w, h = rig.resolution
    side = -1 if index == 0 else 1
    f = rig.focal_px * (rig.focal_ratio if index else 1.0)
    k1 = rig.distortion_k1 if index == 0 or rig.right_distortion_k1 is None else rig.right_distortion_k1
    k = np.array([[f, 0, (w - 1) / 2 + side * rig.axis_offset_px / 2],
                  [0, f, (h - 1) / 2 + side * rig.vertical_offset_px / 2], [0, 0, 1]], np.float64)
    roll = np.array([0.0, 0.0, np.deg2rad(side * rig.roll_deg / 2)])
    return k, np.array([k1, 0, 0, 0], np.float64), roll, side * rig.baseline_m / 2


def _expected_truth(rig: Rig, cam: int, x, y, z) -> np.ndarray:
    """x_left - x_right by OpenCV: the pixel's ray to depth z in camera ``cam``, into the other camera."""
    k, d, roll, pos = _opencv_camera(rig, cam)
    unrolled = cv2.Rodrigues(-roll)[0]  # undistortPoints applies R after undistorting: back to the rig's axes
    pts = np.stack([x, y], axis=1).astype(np.float64).reshape(-1, 1, 2)
    norm = cv2.undistortPoints(pts, k, d, R=unrolled,
                               criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)).reshape(-1, 2)
    points = np.stack([pos + norm[:, 0] * z, norm[:, 1] * z, z], axis=1)
    k2, d2, roll2, pos2 = _opencv_camera(rig, 1 - cam)
    other, _ = cv2.projectPoints(points - [pos2, 0, 0], roll2, np.zeros(3), k2, d2)
    u_other = other.reshape(-1, 2)[:, 0]
    return x - u_other if cam == 0 else u_other - x


def test_rig_projection_is_opencvs_camera_model():
    rng = np.random.default_rng(0)
    points = np.stack([rng.uniform(-0.4, 0.4, 500), rng.uniform(-0.3, 0.3, 500), rng.uniform(0.6, 3.0, 500)], 1)
    for cam in (0, 1):
        k, d, roll, pos = _opencv_camera(CROOKED, cam)
        ref, _ = cv2.projectPoints(points - [pos, 0, 0], roll, np.zeros(3), k, d)
        u, v = CROOKED.project(cam, points)
        np.testing.assert_allclose(np.stack([u, v], 1), ref.reshape(-1, 2), atol=1e-9)
        camera = CROOKED.camera(cam)
        xn, yn = camera.undistort_pixels(u, v)  # the rays the renderer casts come back to the points
        np.testing.assert_allclose(xn, (points[:, 0] - pos) / points[:, 2], atol=1e-9)
        np.testing.assert_allclose(yn, points[:, 1] / points[:, 2], atol=1e-9)


def test_right_row_shift_is_the_left_row_of_each_right_pixels_ray():
    # By OpenCV: each right pixel's ray (undistorted, unrolled), far away, projected into the left camera.
    w, h = CROOKED.resolution
    v, u = np.mgrid[0:h:7, 0:w:5].astype(np.float64)
    k, d, roll, _ = _opencv_camera(CROOKED, 1)
    pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    norm = cv2.undistortPoints(pts, k, d, R=cv2.Rodrigues(-roll)[0],
                               criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)).reshape(-1, 2)
    far = np.stack([norm[:, 0], norm[:, 1], np.ones(len(norm))], axis=1) * 1e9
    k2, d2, roll2, _ = _opencv_camera(CROOKED, 0)
    left, _ = cv2.projectPoints(far, roll2, np.zeros(3), k2, d2)
    expected = left.reshape(-1, 2)[:, 1] - v.ravel()
    shift = CROOKED.right_row_shift()
    np.testing.assert_allclose(shift[v.astype(int), u.astype(int)].ravel(), expected, atol=1e-6)
    assert np.ptp(shift) > 1  # the crooked rig's rows do differ across the image
    plain = dataclasses.replace(Rig(), vertical_offset_px=1.5, distortion_k1=0.0)
    np.testing.assert_allclose(plain.right_row_shift(), -1.5, atol=1e-12)  # a shift alone: one row offset


@pytest.mark.parametrize("distance_m", [0.8, 2.0])
def test_fronto_parallel_plane_truth_under_every_rig_imperfection(distance_m):
    rec = simulate(_plane(distance_m), rig=CROOKED, seconds=0.06, seed=0, render_hz=500)
    w, h = CROOKED.resolution
    for cam in (0, 1):
        # f*B/Z - c near the principal point, f the other camera's: where this camera's ray is its axis, the
        # other one sees the point B/Z off its own axis, through its own focal length
        f_other = CROOKED.focal_px * (CROOKED.focal_ratio if cam == 0 else 1.0)
        ideal = f_other * CROOKED.baseline_m / distance_m - CROOKED.axis_offset_px
        ev, truth = rec.events(cam), rec.truth(cam)
        assert ev.size > 2000 and np.isfinite(truth).all()
        x, y = ev["x"].astype(float), ev["y"].astype(float)
        expected = _expected_truth(CROOKED, cam, x, y, np.full(x.size, distance_m))
        np.testing.assert_allclose(truth, expected, atol=2e-3)  # float32 truth
        centre = (np.abs(x - (w - 1) / 2) < 5) & (np.abs(y - (h - 1) / 2) < 5)
        assert centre.sum() > 20
        np.testing.assert_allclose(truth[centre], ideal, atol=0.5)
        # the imperfections matter off-centre: the ideal formula is off there by more than the tolerance
        assert np.abs(truth - ideal).max() > 1.0


def test_ground_plane_truth_grows_down_the_rows_as_b_times_rows_over_height():
    rig = Rig().ideal()
    rig = dataclasses.replace(rig, left=QUIET, right=QUIET)
    scene = FamilyScene("ground", 1401, rig.resolution, rig.focal_px, 0.2)
    plan = scene.plan
    ground = [s for s in plan.layers if s.name.startswith("ground")]
    things = [s for s in plan.layers if s.name.startswith("thing")]
    height = ground[0].center[1]
    assert all(s.center[1] == height for s in ground) and 0.25 <= height <= 0.6
    speed = -ground[0].velocity[2]
    # below the foot of the nearest thing (as near as it comes in the clip) only the ground is in view
    nearest = min(s.center[2] for s in things) - speed * 0.2
    cy = (rig.resolution[1] - 1) / 2
    first_row = cy + rig.focal_px * height / nearest + 1
    rec = simulate(scene, rig=rig, seconds=0.2, seed=0, render_hz=400)
    for cam in (0, 1):
        ev, truth = rec.events(cam), rec.truth(cam)
        rows = ev["y"].astype(float)
        low = rows > first_row
        assert low.sum() > 500
        np.testing.assert_allclose(truth[low], rig.baseline_m * (rows[low] - cy) / height, atol=1e-3)
    per_row = [np.median(rec.left_disparity[(rec.left["y"] == r)]) for r in range(int(first_row) + 1, 128)]
    assert np.all(np.diff(per_row) > 0)


def test_every_family_keeps_its_disparities_within_a_quarter_of_the_width():
    suite = load_suite("generalization", seconds=0.1)
    for family in ("objects", "translate", "turn", "ground", "repetitive", "thin"):
        spec = suite[f"{family}-tune-128x128"]
        rec = spec.simulate()
        for cam in (0, 1):
            truth = rec.truth(cam)
            finite = truth[np.isfinite(truth)]
            assert finite.size > 0.5 * truth.size, family
            assert finite.max() <= 128 / 4, (family, finite.max())
            assert np.mean(finite < 0) < 0.01, (family, np.mean(finite < 0))


# --- the sensor effects ----------------------------------------------------------------------------------------

def _uniform(gain=None) -> LayeredScene:
    img = np.full((8, 8), 0.5, np.float32)
    return LayeredScene((PlaneLayer("wall", img, np.ones_like(img), 1.0, Motion((0.0, 0.0, 2.0))),),
                        illumination=gain)


def test_hot_pixels_fire_at_their_rate_wherever_they_are():
    w, h, seconds, rate = 64, 48, 1.0, 200.0
    hot = dataclasses.replace(QUIET, hot_pixel_fraction=12 / (w * h), hot_pixel_rate_hz=rate)
    rig = Rig(resolution=(w, h), left=hot, right=QUIET)
    rec = simulate(_uniform(), rig=rig, seconds=seconds, seed=4, render_hz=100)  # a still, uniform scene
    assert rec.right.size == 0  # the right sensor has none, and nothing moves
    ev = rec.left
    pixels, counts = np.unique(ev["y"].astype(int) * w + ev["x"], return_counts=True)
    assert pixels.size == 12  # round(fraction * W * H) pixels
    expected = rate * seconds
    assert abs(counts.sum() - 12 * expected) < 5 * np.sqrt(12 * expected)  # Poisson
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected))
    assert np.isnan(rec.left_disparity).all()
    on = np.mean(ev["p"] == 1)
    assert abs(on - hot.noise_on_fraction) < 0.08  # leakage: mostly ON, as the background activity


def test_a_sensor_without_hot_pixels_draws_nothing_for_them():
    # a rate without hot pixels (or hot pixels without a rate) draws no random number: every earlier seed keeps
    # its events, and the neutral fields stay out of the recording's meta
    rig = Rig(resolution=(32, 32))
    base = simulate(_plane(1.0), rig=rig, seconds=0.05, seed=9)
    idle = Rig(resolution=(32, 32), left=dataclasses.replace(rig.left, hot_pixel_rate_hz=300.0),
               right=dataclasses.replace(rig.right, hot_pixel_fraction=0.01))
    same = simulate(_plane(1.0), rig=idle, seconds=0.05, seed=9)
    assert base.left.size > 100
    assert np.array_equal(base.left, same.left) and np.array_equal(base.right, same.right)
    assert "hot_pixel_fraction" not in base.meta["rig"]["left_sensor"]
    assert same.meta["rig"]["left_sensor"]["hot_pixel_rate_hz"] == 300.0


def test_refractory_period_drops_the_crossings_within_it():
    # one pixel whose log intensity rises by 1.05 within one render step of 1 ms: with threshold 0.2 it crosses
    # at 0.2/1.05, 0.4/1.05, ... of the step, i.e. at 190.5, 381.0, 571.4, 761.9, 952.4 us
    sensor = SensorModel(on_threshold=0.2, off_threshold=0.2, threshold_mismatch=0.0, min_threshold=0.01)
    crossings = np.array([0.2, 0.4, 0.6, 0.8, 1.0]) / 1.05 * 1000
    for refractory_us, kept in ((0.0, [0, 1, 2, 3, 4]), (300.0, [0, 2, 4]), (500.0, [0, 3]), (1000.0, [0])):
        px = PixelArray(dataclasses.replace(sensor, refractory_us=refractory_us), (1, 1), np.random.default_rng(0))
        px.start(np.zeros((1, 1), np.float32), np.ones((1, 1), np.float32), 0.0)
        t, _, _, p, _ = px.feed(np.full((1, 1, 1), 1.05, np.float32), np.ones((1, 1, 1), np.float32),
                                np.array([1000.0]))
        np.testing.assert_allclose(t, crossings[kept], atol=1e-3)
        assert (p == 1).all()


def test_on_and_off_thresholds_of_each_camera_give_the_counts_of_a_known_step():
    # the wall brightens by C in log intensity, then darkens back: ON events floor(C / on) per pixel; the OFF
    # ones count the steps down from where the ON events left the reference, floor(floor(C / on) * on / off)
    step = 1.37
    up = (np.exp(step) * (0.5 + DARK_LEVEL) - DARK_LEVEL) / 0.5

    def gain(t):
        return np.where((t > 0.0105) & (t < 0.0305), up, 1.0)

    left = dataclasses.replace(QUIET, on_threshold=0.17, off_threshold=0.41)
    right = dataclasses.replace(QUIET, on_threshold=0.33, off_threshold=0.13)
    rig = Rig(resolution=(16, 12), left=left, right=right)
    rec = simulate(_uniform(gain), rig=rig, seconds=0.04, seed=0, render_hz=1000)
    for cam, sensor in ((0, left), (1, right)):
        ev = rec.events(cam)
        n_on = int(step // sensor.on_threshold)
        n_off = int(n_on * sensor.on_threshold // sensor.off_threshold)
        assert (ev["p"] == 1).sum() == n_on * 16 * 12, cam
        assert (ev["p"] == 0).sum() == n_off * 16 * 12, cam
    assert (rec.left["p"] == 1).sum() != (rec.right["p"] == 1).sum()  # the cameras differ, as drawn


@pytest.mark.parametrize("family", ["objects", "translate", "turn", "ground", "repetitive", "thin"])
def test_every_pixel_sees_a_surface_from_the_first_instant_to_the_last(family):
    # an uncovered pixel would show the plain background of unknown depth: events at its edge without truth
    suite = load_suite("generalization")
    for name in (f"{family}-tune-128x128", f"{family}-eval-346x260"):
        spec = suite[name]
        for cam in (0, 1):
            _, depth = spec.scene.render(spec.rig, cam, np.array([0.0, spec.seconds]))
            assert np.isfinite(depth).all(), (name, cam, np.mean(~np.isfinite(depth)))
