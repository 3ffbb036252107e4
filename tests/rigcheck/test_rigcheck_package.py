"""The rig check's parts: RigCheckParams, the report's n/a / null for NaN, the shared overlay primitive, and the
left/right detection of the eDVS merged reader pinned on the three real files."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from cvstereo.geometry.overlay import overlay_scores, overlay_shift, row_correlation, side_of_profile
from cvstereo.model.recording import Recording
from cvstereo.rigcheck import RigCheckParams, RigReport, check_rig
from tests.rigcheck.test_rigcheck import textured_patches


@pytest.fixture(scope="module")
def patches() -> Recording:
    return textured_patches(seconds=0.6)


# ---------------------------------------------------------------------------------------------------------------
# RigCheckParams


def test_params_are_frozen_and_overrides_equal_an_explicit_params(patches):
    params = RigCheckParams(max_disparity=40, max_row_offset=4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.max_disparity = 3
    a = check_rig(patches, params)
    b = check_rig(patches, max_disparity=40, max_row_offset=4)
    assert a.to_dict() == b.to_dict()              # (NaN fields make == on the reports False)
    assert a.settings["max_disparity"] == 40 and a.settings["max_row_offset"] == 4
    # The resolved window is recorded, not None.
    assert isinstance(a.settings["window_us"], int) and a.settings["window_us"] >= 10_000


@pytest.mark.parametrize(("field", "value"), [("max_disparity", 0), ("time_bin_us", -5), ("max_row_offset", -1),
                                              ("window_us", 0), ("max_seconds", 0.0), ("reg_window_us", 0)])
def test_out_of_range_option_is_a_value_error_naming_it(field, value):
    with pytest.raises(ValueError, match=f"{field}={value}"):
        RigCheckParams(**{field: value})


def test_unknown_option_names_the_fields(patches):
    with pytest.raises(TypeError, match=r"max_disparty.*max_disparity"):
        check_rig(patches, max_disparty=10)


def test_time_apply_confidence_decides_what_match_kwargs_applies(patches):
    report = check_rig(patches)
    conf = report.time_offset_confidence
    assert 0 < conf < 1
    loose = dataclasses.replace(report, time_offset_us=1234.4,
                                settings={**report.settings, "time_apply_confidence": conf - 0.01})
    strict = dataclasses.replace(loose, settings={**report.settings, "time_apply_confidence": conf + 0.01})
    assert loose.match_kwargs()["time_offset_us"] == 1234
    assert strict.match_kwargs()["time_offset_us"] == 0
    assert strict.match_kwargs(min_time_confidence=0.0)["time_offset_us"] == 1234


# ---------------------------------------------------------------------------------------------------------------
# NaN is never shown


def _with_nan(report: RigReport) -> RigReport:
    nan = float("nan")
    return dataclasses.replace(report, burst_ratio_p95=nan, disparity_range=(nan, nan),
                               disparity_percentiles={q: nan for q in report.disparity_percentiles})


def test_summary_says_n_a_and_json_has_null_for_nan(patches):
    report = _with_nan(check_rig(patches))
    text = report.summary()
    assert "nan" not in text.lower()
    assert "5-95 % n/a..n/a px, median n/a px" in text and "up to n/a" in text
    data = report.to_dict()
    assert data["burst_ratio_p95"] is None and data["disparity_range"] == [None, None]
    assert set(data["disparity_percentiles"].values()) == {None}
    json.dumps(data, allow_nan=False)                       # strict JSON: raises on NaN
    assert data["rate_ratio"] == pytest.approx(report.rate_ratio)


def test_no_local_overlay_reports_nan_percentiles_as_n_a():
    # No local overlay can reach an NCC above 1, so none is kept: the percentiles cannot be estimated.
    from cvstereo.model.events import make_events

    rng = np.random.default_rng(3)
    cams = []
    for _ in range(2):
        n = 3000
        cams.append(make_events(np.sort(rng.integers(0, 1_000_000, n)), rng.integers(0, 128, n),
                                rng.integers(0, 128, n), rng.integers(0, 2, n)))
    report = check_rig(Recording(*cams), min_ncc=1.5)
    assert all(math.isnan(v) for v in report.disparity_percentiles.values())
    assert "n/a" in report.summary() and "nan" not in report.summary().lower()
    assert report.to_dict()["disparity_range"] == [None, None]


# ---------------------------------------------------------------------------------------------------------------
# The overlay primitive (cvstereo.geometry.overlay)


def _ncc_brute(a, b, s):
    """Hand-written NCC of log counts over the overlap at shift s (x_a = x_b + s)."""
    la, lb = np.log1p(a.astype(float)), np.log1p(b.astype(float))
    w = a.shape[1]
    xs = [x for x in range(w) if 0 <= x - s < w]
    pa = np.array([[la[y, x] for x in xs] for y in range(a.shape[0])])
    pb = np.array([[lb[y, x - s] for x in xs] for y in range(a.shape[0])])
    pa, pb = pa - pa.mean(), pb - pb.mean()
    return float((pa * pb).sum() / np.sqrt((pa * pa).sum() * (pb * pb).sum()))


def test_overlay_scores_equal_a_brute_force_ncc(rng):
    b = rng.poisson(2.0, (12, 30))
    a = np.roll(b, 5, axis=1)
    scores = overlay_scores(a, b, max_shift=7)
    for s in range(-7, 8):
        assert scores[s + 7] == pytest.approx(_ncc_brute(a, b, s), abs=1e-12)
    assert overlay_shift(a, b, max_shift=7) == (5, pytest.approx(scores.max()))


def test_row_correlation_and_side_follow_the_left_is_larger_x_convention(rng):
    right = rng.normal(size=(16, 40)).astype(np.float32)
    left = np.zeros_like(right)
    left[:, 6:] = right[:, :-6]                                 # x_left = x_right + 6: left is left
    prof = row_correlation(left, right, max_shift=10, nfft=64)
    assert int(np.argmax(prof)) - 10 == 6
    direct = sum(float((left[:, s:] * right[:, :40 - s]).sum()) for s in [6])
    norm = np.sqrt(float((left ** 2).sum()) * float((right ** 2).sum()))
    assert prof[16] == pytest.approx(direct / norm, rel=1e-5)
    assert side_of_profile(prof)[0] is False                    # the first camera is not the right one
    assert side_of_profile(row_correlation(right, left, max_shift=10, nfft=64))[0] is True
    assert row_correlation(np.zeros_like(left), right, max_shift=10, nfft=64) is None


# ---------------------------------------------------------------------------------------------------------------
# The eDVS merged reader's left/right detection on the real files (shift = the file's nominal disparity;
# left retina as the data's README says). Scores measured from the code before it moved to cvstereo.geometry.overlay.


@pytest.mark.shared_data
@pytest.mark.parametrize(("name", "left_retina", "shift", "score"), [
    ("Fan_disp8.dat", 1, 8, 0.8717), ("NSTlogo_disp12-8-3.dat", 1, 12, 0.5552), ("movingPersons.dat", 0, 13, 0.8604)])
def test_real_files_detected_retina_and_shift_are_pinned(tum_dir, name, left_retina, shift, score):
    from cvstereo.io import read_recording

    meta = read_recording(tum_dir / name).meta
    assert meta["left_retina_from"] == "detected"
    assert meta["left_retina"] == left_retina
    assert meta["overlay_shift_px"] == shift
    assert meta["overlay_score"] == pytest.approx(score, abs=1e-4)


# ---------------------------------------------------------------------------------------------------------------
# The estimators' constants are RigCheckParams fields, and the estimators follow them


def test_burst_ratio_follows_its_minimum_count():
    from cvstereo.model.events import make_events
    from cvstereo.rigcheck.stats import burst_ratio

    def camera(counts):  # counts[k] events in window k of 1000 us
        t = np.concatenate([np.full(c, 1000 * k + 10) for k, c in enumerate(counts)])
        return make_events(t, np.zeros(t.size, int), np.zeros(t.size, int), np.ones(t.size, int))

    left, right = camera([5, 10, 2]), camera([10, 5, 9])
    # Windows with >= 5 in both: ratios 2 and 2. With >= 2: 2, 2, 4.5, whose 95th percentile is 2 + 0.9 * 2.5.
    assert burst_ratio(left, right, window_us=1000, min_events=5) == pytest.approx(2.0)
    assert burst_ratio(left, right, window_us=1000, min_events=2) == pytest.approx(4.25)
    assert math.isnan(burst_ratio(left, right, window_us=1000, min_events=11))


def test_shortest_recording_is_min_window_us(patches):
    longer_ms = (patches.t_end - patches.t_start) // 1000 + 100
    with pytest.raises(ValueError, match=f"at least {longer_ms} ms"):
        check_rig(patches, min_window_us=longer_ms * 1000, max_window_us=10_000_000)
    with pytest.raises(ValueError, match="max_window_us=5000 is below min_window_us=10000"):
        RigCheckParams(max_window_us=5000)
