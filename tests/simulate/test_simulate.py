"""The simulator's ground truth, checked against geometry and against the events themselves.

The truth tests do not reuse the generator's projection code: expected disparities come from the formula
d = f*B/Z - c, or are measured from where the events fall in the two cameras.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from cvstereo.io.npz import read_recording_npz, write_recording_npz
from cvstereo.simulate import (
    GENERATOR_VERSION,
    PRESETS,
    ArmsScene,
    LayeredScene,
    Motion,
    MotorcycleScene,
    PlaneLayer,
    Rig,
    RotationScene,
    SensorModel,
    cached_preset,
    simulate,
    textures,
)
from cvstereo.simulate.dvs import PixelArray, reference_events

QUIET = SensorModel(noise_rate_hz=0.0)  # default pixels without background noise


@pytest.fixture(scope="session")
def preset_clip():
    """A 2 s clip of the 1-arm 50 cm preset, generated once and cached on disk (see cached_preset)."""
    return read_recording_npz(cached_preset("1arm-50cm", seconds=2))


def _plane_scene(distance_m: float, *, speed_m_s: float = 0.05) -> LayeredScene:
    """A checkerboard filling the view at ``distance_m``, sliding sideways."""
    texel = textures.texel_size(distance_m, 165.0)
    size = 2.0 * distance_m  # much wider than the view (128 / 165 * Z) plus the motion
    img, alpha = textures.checkerboard((size, size), texel, 0.02 * distance_m)
    return LayeredScene((PlaneLayer("plane", img, alpha, texel,
                                    Motion((0.0, 0.0, distance_m), velocity=(speed_m_s * distance_m, 0.0, 0.0))),))


def _dot_scene(distance_m: float) -> LayeredScene:
    """A small bright dot at ``distance_m`` gliding across the view, off-centre (where distortion acts)."""
    texel = textures.texel_size(distance_m, 165.0, texels_per_pixel=4)
    img, alpha = textures.dot(1.5 * distance_m / 165.0, texel, blur_texels=2.0)
    half = 64 / 165 * distance_m
    return LayeredScene((PlaneLayer("dot", img, alpha, texel,
                                    Motion((-0.7 * half, -0.5 * half, distance_m), velocity=(0.7 * half, 0.0, 0.0))),),
                        background=0.02)


@pytest.mark.parametrize("distance_m", [0.5, 1.0, 1.5])
@pytest.mark.parametrize("axis_offset_px", [0.0, 2.5])
def test_fronto_parallel_plane_gives_f_b_over_z_minus_c(distance_m, axis_offset_px):
    rig = Rig(distortion_k1=0.0, vertical_offset_px=0.0, axis_offset_px=axis_offset_px, left=QUIET, right=QUIET)
    rec = simulate(_plane_scene(distance_m), rig=rig, seconds=0.15, seed=0)
    expected = rig.focal_px * rig.baseline_m / distance_m - axis_offset_px
    for cam in (0, 1):
        truth = rec.truth(cam)
        assert truth.size > 500
        assert np.isfinite(truth).all()
        np.testing.assert_allclose(truth, expected, atol=0.1)


def test_dot_centroids_differ_by_the_truth_of_their_events():
    rig = Rig(left=QUIET, right=QUIET)  # distortion, axis offset and vertical offset on
    assert rig.distortion_k1 < 0 and rig.axis_offset_px > 0 and rig.vertical_offset_px > 0
    rec = simulate(_dot_scene(0.8), rig=rig, seconds=1.0, seed=0)
    window_us = 50_000
    checked = 0
    for t0 in range(0, 1_000_000, window_us):
        cams = []
        for cam in (0, 1):
            ev, truth = rec.events(cam), rec.truth(cam)
            sel = (ev["t"] >= t0) & (ev["t"] < t0 + window_us)
            cams.append((ev["x"][sel].astype(float), truth[sel]))
        (xl, tl), (xr, tr) = cams
        if xl.size < 20 or xr.size < 20:
            continue
        measured = xl.mean() - xr.mean()
        assert abs(measured - np.concatenate([tl, tr]).mean()) < 0.5, (t0, measured, tl.mean(), tr.mean())
        checked += 1
    assert checked >= 15
    # the dot glides near the top-left, where barrel distortion lowers the disparity below f*B/Z - c
    assert np.nanmean(rec.left_disparity) < rig.focal_px * rig.baseline_m / 0.8 - rig.axis_offset_px - 0.1


def test_zero_baseline_gives_zero_disparity():
    rig = Rig(baseline_m=0.0, axis_offset_px=0.0, left=QUIET, right=QUIET)  # distortion and dy stay on
    rec = simulate(ArmsScene(distance_m=0.5), rig=rig, seconds=0.3, seed=0)
    for cam in (0, 1):
        truth = rec.truth(cam)
        assert np.isfinite(truth).sum() > 1000
        np.testing.assert_allclose(truth[np.isfinite(truth)], 0.0, atol=1e-4)


def _uniform_scene(gain) -> LayeredScene:
    img = np.full((8, 8), 1.0, np.float32)
    return LayeredScene((PlaneLayer("wall", img, np.ones_like(img), 1.0, Motion((0.0, 0.0, 2.0))),),
                        illumination=gain)


@pytest.mark.parametrize("k", [1, 3, 7])
def test_brightness_step_of_k_thresholds_gives_k_events_per_pixel(k):
    sensor = SensorModel(on_threshold=0.2, off_threshold=0.25).ideal()
    rig = Rig(resolution=(6, 5), left=sensor, right=sensor)
    # light steps up by k + 1/2 ON thresholds (in log intensity) at 20 ms and back down at 60 ms
    up = np.exp((k + 0.5) * sensor.on_threshold)

    def step(t):
        return np.where((t > 0.0205) & (t < 0.0605), up, 1.0)

    rec = simulate(_uniform_scene(step), rig=rig, seconds=0.1, seed=0, render_hz=1000)
    for cam in (0, 1):
        ev = rec.events(cam)
        on, off = ev[ev["p"] == 1], ev[ev["p"] == 0]
        pix_on = np.bincount(on["y"].astype(int) * 6 + on["x"], minlength=30)
        assert (pix_on == k).all()
        assert ((on["t"] >= 20_000) & (on["t"] <= 21_000)).all()  # interpolated within the render step
        # k ON events moved the reference up by k ON thresholds; back down, it falls by whole OFF thresholds
        n_off = int(k * sensor.on_threshold // sensor.off_threshold)
        pix_off = np.bincount(off["y"].astype(int) * 6 + off["x"], minlength=30)
        assert (pix_off == n_off).all()
        assert ((off["t"] >= 60_000) & (off["t"] <= 61_000)).all()


def test_event_kernel_agrees_with_the_reference():
    rng = np.random.default_rng(0)
    t_n, h, w = 30, 4, 5
    intensity = np.exp(np.cumsum(rng.normal(0, 0.3, (t_n, h, w)), axis=0)).astype(np.float32)
    logi = np.log(intensity)
    depth = rng.uniform(0.5, 2.0, (t_n, h, w)).astype(np.float32)
    depth[5, 1, 1] = np.nan
    times = np.arange(t_n) * 1000.0
    sensor = SensorModel(refractory_us=300.0)
    px = PixelArray(sensor, (h, w), np.random.default_rng(1))
    px.start(logi[0], depth[0], times[0])
    px._capacity = 4  # force the resume-after-growing path
    t, x, y, p, z = px.feed(logi[1:], depth[1:], times[1:])
    ref = reference_events(logi, depth, times, px.thr_on, px.thr_off, sensor.refractory_us)
    assert len(ref) == t.size > 50
    rt, rx, ry, rp, rz = (np.array(col) for col in zip(*ref, strict=True))
    np.testing.assert_allclose(t, rt, rtol=0, atol=1e-3)  # float32 levels; times are rounded to 1 us later
    np.testing.assert_array_equal(x, rx)
    np.testing.assert_array_equal(y, ry)
    np.testing.assert_array_equal(p, rp)
    np.testing.assert_allclose(z, rz.astype(np.float32), equal_nan=True)


def test_same_seed_same_events_other_seed_other_events():
    scene = ArmsScene(arms=2, distance_m=1.0, seed=3)
    a = simulate(scene, seconds=0.2, seed=3)
    b = simulate(scene, seconds=0.2, seed=3)
    c = simulate(scene, seconds=0.2, seed=4)
    for cam in (0, 1):
        np.testing.assert_array_equal(a.events(cam), b.events(cam))
        np.testing.assert_array_equal(a.truth(cam), b.truth(cam))
    assert a.left.size != c.left.size or not np.array_equal(a.left, c.left)


def test_noise_only_scene_gives_poisson_noise_with_nan_truth():
    sensor = SensorModel(noise_rate_hz=5.0, jitter_us=0.0)
    rig = Rig(left=sensor, right=sensor)
    img = np.full((8, 8), 0.5, np.float32)
    static = LayeredScene((PlaneLayer("wall", img, np.ones_like(img), 1.0, Motion((0.0, 0.0, 2.0))),))
    rec = simulate(static, rig=rig, seconds=0.5, seed=0)
    expected = 5.0 * 0.5 * 128 * 128
    for cam in (0, 1):
        assert np.isnan(rec.truth(cam)).all()
        assert abs(rec.events(cam).size - expected) < 5 * np.sqrt(expected)
        assert abs(rec.events(cam)["p"].mean() - sensor.noise_on_fraction) < 0.05
        assert np.all(np.diff(rec.events(cam)["t"]) >= 0)


def test_recording_meta_is_json_and_round_trips(tmp_path):
    rec = simulate(ArmsScene(distance_m=1.5), seconds=0.1, seed=0)
    meta = json.loads(json.dumps(rec.meta))
    assert meta["rig"]["baseline_m"] == 0.1 and meta["scene"]["type"] == "arms"
    assert meta["generator_version"] == GENERATOR_VERSION
    write_recording_npz(tmp_path / "r.npz", rec)
    back = read_recording_npz(tmp_path / "r.npz")
    np.testing.assert_array_equal(back.left, rec.left)
    np.testing.assert_array_equal(back.right_disparity, rec.right_disparity)
    assert back.meta["scene"]["distance_m"] == 1.5


def test_rotation_scene_sees_several_depths():
    rec = simulate(RotationScene(), seconds=0.25, seed=0)
    truth = np.concatenate([rec.left_disparity, rec.right_disparity])
    finite = truth[np.isfinite(truth)]
    assert finite.size > 2000
    # the object at 0.8 m gives about 165*0.1/0.8 - 3 = 17.6 px, the walls (2.5-4.5 m) about 1-4 px
    near, far = (finite > 15).mean(), (finite < 5).mean()
    assert near > 0.05 and far > 0.02, (near, far)
    assert finite.max() < 165 * 0.1 / 0.75 - 3  # nothing nearer than the nearest object


def test_motorcycle_truth_is_the_scaled_map_and_nan_where_unknown():
    scene = MotorcycleScene(scale=0.5)
    rec = simulate(scene, seconds=0.15, seed=0)
    rig = Rig()
    truth = np.concatenate([rec.left_disparity, rec.right_disparity])
    finite = truth[np.isfinite(truth)]
    assert finite.size > 1000 and np.isnan(truth).any()
    # the map holds 7.2-59.9 px at full size: x 0.5, minus c, give or take the distortion
    assert finite.min() > 0.5 * 7.19 - rig.axis_offset_px - 1.5
    assert finite.max() < 0.5 * 59.91 - rig.axis_offset_px + 0.5


def test_defaults_reproduce_the_thesis_imbalances(preset_clip):
    rec = preset_clip
    assert rec.meta["preset"] == "1arm-50cm"
    for cam in (0, 1):
        ev, truth = rec.events(cam), rec.truth(cam)
        assert (ev["p"] == 1).sum() > 1.05 * (ev["p"] == 0).sum()  # ON outnumber OFF
        assert 0 < np.isnan(truth).mean() <= 0.25  # some noise, at most a quarter
        assert 27 < np.nanmean(truth) < 31  # the arm at 50 cm
    assert rec.right.size > 1.05 * rec.left.size  # the right camera (eDVS1) is the busier one


def test_cached_preset_generates_once(tmp_path):
    a = cached_preset("2arms-150cm", seconds=0.05, seed=1, cache_dir=tmp_path)
    mtime = a.stat().st_mtime_ns
    b = cached_preset("2arms-150cm", seconds=0.05, seed=1, cache_dir=tmp_path)
    assert a == b and b.stat().st_mtime_ns == mtime
    assert f"_v{GENERATOR_VERSION}_" in a.name and "seed1" in a.name
    assert cached_preset("2arms-150cm", seconds=0.05, seed=2, cache_dir=tmp_path) != a
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".part")] == []


def test_presets_are_the_six_recordings():
    assert list(PRESETS) == ["1arm-50cm", "1arm-100cm", "1arm-150cm", "2arms-50cm", "2arms-100cm", "2arms-150cm"]
    assert all(p.seconds == 11.0 for p in PRESETS.values())


@pytest.mark.parametrize("bad", [dict(baseline_m=-0.1), dict(focal_px=0.0), dict(distortion_k1=-3.0)])
def test_rig_rejects_bad_parameters(bad):
    with pytest.raises(ValueError, match="Rig"):
        Rig(**bad)


def test_sensor_rejects_bad_parameters():
    with pytest.raises(ValueError, match="on_threshold"):
        SensorModel(on_threshold=0.0)
    with pytest.raises(ValueError, match="noise_on_fraction"):
        SensorModel(noise_on_fraction=1.5)


def test_distortion_round_trips_and_is_barrel():
    cam = Rig().camera(1)
    u, v = np.meshgrid(np.arange(128.0), np.arange(128.0))
    xn, yn = cam.undistort_pixels(u, v)
    u2, v2 = cam.distort(xn, yn)
    np.testing.assert_allclose(u2, u, atol=1e-6)
    np.testing.assert_allclose(v2, v, atol=1e-6)
    # barrel: the corner's undistorted ray lies further out than the pinhole ray through it
    assert abs(xn[0, 0]) > abs((0 - cam.cx) / cam.focal_px)


def test_ideal_sensor_is_a_copy_without_imperfections():
    ideal = SensorModel().ideal()
    assert ideal.noise_rate_hz == ideal.jitter_us == ideal.refractory_us == ideal.threshold_mismatch == 0
    assert dataclasses.replace(ideal, noise_rate_hz=1.0).noise_rate_hz == 1.0
