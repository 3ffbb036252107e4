"""The robustness suite (issue 12): its list, what each factor does to the events, the fan, determinism.

Expectations come from the sensor model's definition (a log step of C gives floor(C / threshold) events per
pixel), from Poisson statistics, from geometry (d = f*B/Z - c) or from the events' timing itself (the
cross-correlation of the two cameras' event rates), never from the generator's own code.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cvstereo.io.npz import read_recording_npz
from cvstereo.simulate import (
    EDVS1_RIGHT,
    EDVS2_LEFT,
    FACTORS,
    FAN_RENDER_HZ,
    FanScene,
    LayeredScene,
    Motion,
    PlaneLayer,
    Rig,
    load_suite,
    simulate,
    suite_recordings,
    textures,
)
from cvstereo.simulate.dvs import DARK_LEVEL
from cvstereo.simulate.suite import JOINT_FACTORS, SENSORS, draw_joint, parse_suite


@pytest.fixture(scope="module")
def suite():
    return load_suite("robustness")


def _uniform_scene(gain=None) -> LayeredScene:
    img = np.full((8, 8), 0.5, np.float32)
    return LayeredScene((PlaneLayer("wall", img, np.ones_like(img), 1.0, Motion((0.0, 0.0, 2.0))),),
                        illumination=gain)


def _ideal_rig(resolution=(16, 12)) -> Rig:
    return Rig(resolution=resolution, left=EDVS2_LEFT.ideal(), right=EDVS1_RIGHT.ideal())


# --- the list --------------------------------------------------------------------------------------------------

def test_suite_list_loads_with_every_factor_over_its_range(suite):
    names = [r.name for r in suite.recordings]
    assert len(names) == len(set(names)) == 29
    assert names[0] == "base" and suite.base == "1arm-100cm" and 2 <= suite.seconds <= 3
    one = {}
    for r in suite.recordings:
        if r.factor in FACTORS:
            one.setdefault(r.factor, []).append(r.value)
    # the ranges: both extremes and one value in between, for every factor
    expected_ranges = {"threshold_scale": (0.5, 3.0), "noise_hz": (0.05, 1.0), "jitter_ms": (0.0, 1.0),
                       "speed_scale": (0.5, 2.0), "distance_m": (0.3, 3.0)}
    for factor, (lo, hi) in expected_ranges.items():
        values = sorted(one[factor])
        assert len(values) == 3 and values[0] == lo and values[-1] == hi and lo < values[1] < hi, (factor, values)
    assert sorted(one["texture"]) == ["checker", "natural", "stripes"]
    assert sorted(one["sensor"]) == ["240x180", "346x260", "640x480"]
    assert one["time_offset_ms"] == [-3.0]
    joint = [r for r in suite.recordings if r.factor == "joint"]
    assert len(joint) == 5 and len({r.seed for r in joint}) == 5
    for k, r in enumerate(joint, start=1):
        assert set(r.value) == set(JOINT_FACTORS)
        assert r.value == draw_joint(k)  # the committed values are the seeded draws
    fans = [r for r in suite.recordings if isinstance(r.scene, FanScene)]
    assert [r.name for r in fans] == ["fan", "fan-right-3ms-early"]


def test_each_recording_is_labelled_and_scaled(suite):
    base = suite["base"]
    for r in suite.recordings:
        label = r.label()
        assert label["name"] == "robustness" and label["recording"] == r.name and label["factor"] == r.factor
        w = r.rig.resolution[0]
        assert label["max_disparity"] == round(64 * w / 128)
        assert r.rig.focal_px == pytest.approx(base.rig.focal_px * w / 128)
    x3 = suite["threshold-x3"].rig
    assert x3.left.on_threshold == pytest.approx(3 * base.rig.left.on_threshold)
    assert x3.right.off_threshold == pytest.approx(3 * base.rig.right.off_threshold)
    assert suite["speed-x2"].scene.sweep_period_s == pytest.approx(base.scene.sweep_period_s / 2)
    assert suite["distance-3m"].scene.background_m > 3.0
    assert suite["fan-right-3ms-early"].rig.time_offset_us == -3000.0
    assert suite["fan"].label()["blade_period_s"] == 0.018


@pytest.mark.parametrize(("entry", "match"), [
    ({"name": "a", "set": {"colour": 1}}, "unknown factor 'colour'"),
    ({"name": "a", "set": {"threshold_scale": 9.0}}, r"threshold_scale must be a number in \[0.5, 3\]"),
    ({"name": "a", "set": {"sensor": "100x100"}}, "sensor must be one of"),
    ({"name": "a", "scene": "fan", "set": {"speed_scale": 1.5}}, "applies to the arms scene only"),
    ({"name": "a", "scene": "pond"}, "scene must be one of"),
    ({"name": "a", "colour": 1}, "unknown key"),
    ({"name": "a", "set": "noise_hz"}, "must be a table"),
    ({"set": {}}, "unique name"),
])
def test_bad_suite_entries_are_refused_with_their_place(entry, match):
    data = {"name": "t", "version": 1, "base_preset": "1arm-100cm", "seconds": 1.0, "recording": [entry]}
    with pytest.raises(ValueError, match=match) as info:
        parse_suite(data, where="t.toml")
    assert "t.toml, recording 0" in str(info.value)


def test_unknown_suite_lists_the_known_ones():
    with pytest.raises(ValueError, match="robustness"):
        load_suite("fragility")


# --- what each factor does -------------------------------------------------------------------------------------

def test_threshold_x3_gives_a_third_of_the_events_per_edge():
    # the wall (0.5) brightens so that its log intensity (with the photoreceptor's dark level) rises by 3.1,
    # well between whole multiples of every threshold involved (0.23, 0.245 and three times those)
    log_step = 3.1
    up = (np.exp(log_step) * (0.5 + DARK_LEVEL) - DARK_LEVEL) / 0.5

    def step(t):
        return np.where(t > 0.0205, up, 1.0)

    counts = {}
    for k in (1.0, 3.0):
        _, rig = FACTORS["threshold_scale"].apply(_uniform_scene(step), _ideal_rig(), k)
        rec = simulate(_uniform_scene(step), rig=rig, seconds=0.04, seed=0)
        for cam, sensor in ((0, rig.left), (1, rig.right)):
            on = rec.events(cam)["p"] == 1
            per_pixel = on.sum() / (16 * 12)
            assert per_pixel == int(log_step // sensor.on_threshold)  # the model: floor(C / threshold)
            counts[k, cam] = per_pixel
    for cam in (0, 1):
        assert 0.25 < counts[3.0, cam] / counts[1.0, cam] < 0.4  # about a third


def test_noise_rate_on_a_static_scene_matches_the_set_rate(suite):
    rig = dataclasses.replace(suite["noise-1hz"].rig, resolution=(64, 64))
    seconds = 0.5
    rec = simulate(_uniform_scene(), rig=rig, seconds=seconds, seed=0)
    expected = 1.0 * seconds * 64 * 64
    for cam in (0, 1):
        n = rec.events(cam).size
        assert abs(n - expected) < 5 * np.sqrt(expected), (cam, n, expected)
        assert np.isnan(rec.truth(cam)).all()


@pytest.mark.parametrize("jitter_ms", [0.0, 1.0])
def test_jitter_spreads_simultaneous_events_by_the_set_deviation(jitter_ms):
    # a brightness step of 1.5 ON thresholds between two render instants: every ideal pixel fires one ON event
    # at the same interpolated instant, so the spread of the stamps is the jitter alone
    up = np.exp(1.5 * EDVS2_LEFT.on_threshold)
    scene = _uniform_scene(lambda t: np.where(t > 0.0205, up, 1.0))
    _, rig = FACTORS["jitter_ms"].apply(scene, _ideal_rig((64, 64)), jitter_ms)
    rec = simulate(scene, rig=rig, seconds=0.05, seed=0)
    t = rec.left["t"][rec.left["p"] == 1].astype(float)
    assert t.size == 64 * 64
    if jitter_ms == 0:
        assert np.ptp(t) == 0
    else:
        assert abs(t.std() - 1000.0 * jitter_ms) < 0.05 * 1000.0 * jitter_ms
        assert abs(t.mean() - np.median(rec.left["t"])) < 100


def test_sleeve_patterns_differ_but_share_the_contrast():
    yy, xx = np.mgrid[0:200, 0:60].astype(np.float32) * 0.002
    phase = np.array([1.0, 2.0])
    out = {p: textures.sleeve_pattern(p, xx, yy, phase, 0.002) for p in textures.SLEEVE_PATTERNS}
    for name, pattern in out.items():
        assert pattern.std() == pytest.approx(out["checks"].std(), rel=0.01), name
        if name != "checks":
            assert not np.allclose(pattern, out["checks"], atol=0.05), name
    assert np.ptp(out["stripes"], axis=0).max() < 1e-5  # vertical stripes: constant down each column


# --- the fan ---------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ideal_fan():
    quiet = EDVS2_LEFT.ideal()
    rig = Rig(distortion_k1=0.0, vertical_offset_px=0.0, left=quiet, right=quiet)  # axis offset c stays
    return rig, simulate(FanScene(), rig=rig, seconds=0.3, seed=0, render_hz=FAN_RENDER_HZ)


def test_fan_truth_is_f_b_over_z_minus_c(ideal_fan):
    rig, rec = ideal_fan
    expected = rig.focal_px * rig.baseline_m / FanScene().distance_m - rig.axis_offset_px
    assert expected == pytest.approx(8.0)
    for cam in (0, 1):
        truth = rec.truth(cam)
        assert truth.size > 5000 and np.isfinite(truth).all()
        np.testing.assert_allclose(truth, expected, atol=0.1)


def test_fan_blades_pass_each_pixel_once_per_blade_period(ideal_fan):
    _, rec = ideal_fan
    period_us = FanScene().blade_period_s * 1e6
    ev = rec.left
    pix = ev["y"].astype(int) * 128 + ev["x"]
    busiest = np.argsort(np.bincount(pix))[-20:]
    gaps = []
    for p in busiest:
        t = ev["t"][(pix == p) & (ev["p"] == 1)].astype(float)
        starts = t[np.r_[True, np.diff(t) > 0.25 * period_us]]  # the first ON event of each pass
        gaps.extend(np.diff(starts))
    assert len(gaps) > 100
    assert abs(np.median(gaps) - period_us) < 200


def _rate_lag_ms(rec, *, max_lag_us: float, bin_us: int = 250) -> float:
    """Lag of the peak of the cross-correlation of the two cameras' event-rate histograms (right minus left)."""
    edges = np.arange(0, int(rec.duration_s * 1e6) + bin_us, bin_us)
    hl, hr = (np.histogram(ev["t"], edges)[0].astype(float) for ev in (rec.left, rec.right))
    hl, hr = hl - hl.mean(), hr - hr.mean()
    m = int(max_lag_us // bin_us)
    lags = np.arange(-m, m + 1)
    cc = [np.dot(hl[max(0, -k):hl.size - max(0, k)], hr[max(0, k):hr.size - max(0, -k)]) for k in lags]
    return lags[int(np.argmax(cc))] * bin_us / 1000


@pytest.mark.slow
@pytest.mark.parametrize("name", ["fan", "fan-right-3ms-early"])
def test_right_camera_early_shows_in_the_event_rates(name):
    rec_spec = load_suite("robustness", seconds=0.5)[name]
    rec = rec_spec.simulate()
    half_period_us = 0.5 * rec_spec.scene.blade_period_s * 1e6  # beyond it the next blade looks the same
    lag = _rate_lag_ms(rec, max_lag_us=half_period_us - 500)
    assert abs(lag - rec_spec.rig.time_offset_us / 1000) <= 0.5, lag
    assert rec.meta["rig"]["time_offset_us"] == rec_spec.rig.time_offset_us


def test_right_camera_offset_keeps_events_inside_the_recording():
    rig = Rig(time_offset_us=-3000, left=EDVS2_LEFT.ideal(), right=EDVS1_RIGHT.ideal())
    rec = simulate(FanScene(), rig=rig, seconds=0.1, seed=0, render_hz=FAN_RENDER_HZ)
    assert rec.right["t"].min() >= 0 and rec.right["t"].max() < 100_000
    assert rec.right["t"].max() < 97_100  # the last 3 ms of the right clock come after the recording ended


# --- sizes, determinism, cache ---------------------------------------------------------------------------------

@pytest.mark.parametrize("sensor", [*SENSORS[1:3], pytest.param(SENSORS[3], marks=pytest.mark.slow)])
def test_larger_sensors_see_the_same_scene_with_scaled_disparity(suite, sensor):
    seconds = 0.1
    small = suite["base"]
    big = suite[f"sensor-{sensor}"]
    w, h = big.rig.resolution
    a = dataclasses.replace(small, seconds=seconds).simulate()
    b = dataclasses.replace(big, seconds=seconds).simulate()
    assert b.resolution == (w, h) and f"{w}x{h}" == sensor
    for cam in (0, 1):
        ev = b.events(cam)
        assert ev["x"].max() < w and ev["y"].max() < h and ev.size > a.events(cam).size
        ratio = np.nanmedian(b.truth(cam)) / np.nanmedian(a.truth(cam))
        assert ratio == pytest.approx(w / 128, rel=0.05)


def test_suite_recordings_are_deterministic_and_cached(tmp_path):
    only = ["threshold-x1.5", "fan-right-3ms-early"]
    first = suite_recordings("robustness", seconds=0.1, cache_dir=tmp_path / "a", only=only)
    again = suite_recordings("robustness", seconds=0.1, cache_dir=tmp_path / "a", only=only)
    other = suite_recordings("robustness", seconds=0.1, cache_dir=tmp_path / "b", only=only)
    assert [n for n, _ in first] == only
    assert [p.stat().st_mtime_ns for _, p in first] == [p.stat().st_mtime_ns for _, p in again]
    for (name, pa), (_, pb) in zip(first, other, strict=True):
        ra, rb = read_recording_npz(pa), read_recording_npz(pb)
        for cam in (0, 1):
            assert ra.events(cam).tobytes() == rb.events(cam).tobytes()
            assert ra.truth(cam).tobytes() == rb.truth(cam).tobytes()
        assert ra.meta["suite"]["recording"] == name and ra.meta["suite"] == rb.meta["suite"]
    assert read_recording_npz(first[0][1]).meta["suite"]["factor"] == "threshold_scale"
    assert read_recording_npz(first[0][1]).meta["suite"]["value"] == 1.5
    with pytest.raises(ValueError, match="no recording nope"):
        suite_recordings("robustness", seconds=0.1, cache_dir=tmp_path / "a", only=["nope"])


def test_seconds_beyond_the_limit_are_refused_before_any_allocation():
    with pytest.raises(ValueError, match=r"seconds must lie in \(0, 600\]"):
        simulate(FanScene(), seconds=1e12)
