"""The generalization suite v2 (issue 24): its definition, the two halves, the tuning guard, the sweep's halves.

Expectations come from the suite file read here on its own (``tomllib``), not from the parser under test: the
ranges every draw must respect, the photos of each half, the families' counts.
"""

from __future__ import annotations

import copy
import os
import shutil
import tomllib
from importlib import resources

import numpy as np
import pytest

from cvstereo.io.npz import read_recording_npz
from cvstereo.simulate import FAMILIES, load_suite, require_tuning, suite_recordings, tuning_recordings
from cvstereo.simulate.generalization import (
    HALVES,
    RIG_DRAWS,
    SENSOR_DRAWS,
    EvaluationRecordingError,
    FamilyRecording,
    parse_family_suite,
)
from cvstereo.simulate.rig import SENSORS
from cvstereo.simulate.surfaces import PHOTOS


@pytest.fixture(scope="module")
def text() -> dict:
    """The suite file, parsed by tomllib alone."""
    return tomllib.loads(resources.files("cvstereo.simulate").joinpath("suites", "generalization_v2.toml")
                        .read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def suite():
    return load_suite("generalization")


def test_every_family_has_eight_recordings_four_per_half_on_the_four_sensors(suite, text):
    assert set(suite.families) == set(FAMILIES) == set(text["families"])
    assert len(suite.recordings) == len(text["recording"]) >= 48
    for family in FAMILIES:
        mine = [r for r in suite.recordings if r.family == family]
        assert len(mine) >= 8, family
        for half in HALVES:
            part = [r for r in mine if r.half == half]
            assert len(part) >= 4, (family, half)
            assert {f"{w}x{h}" for w, h in (r.rig.resolution for r in part)} == set(SENSORS), (family, half)
    labels = [r.label() for r in suite.recordings]
    assert all(lab["name"] == "generalization" and lab["half"] in HALVES for lab in labels)
    assert [lab["recording"] for lab in labels] == [e["name"] for e in text["recording"]]


def test_halves_share_no_seed_and_no_photo(suite, text):
    tune_photos, eval_photos = set(text["photos"]["tune"]), set(text["photos"]["eval"])
    assert not tune_photos & eval_photos and (tune_photos | eval_photos) <= set(PHOTOS)
    assert "motorcycle" not in " ".join(tune_photos | eval_photos)
    by_half = {h: [r for r in suite.recordings if r.half == h] for h in HALVES}
    assert not {r.seed for r in by_half["tune"]} & {r.seed for r in by_half["eval"]}
    shown = {h: {p for r in by_half[h] for p in r.photos} for h in HALVES}
    assert shown["tune"] <= tune_photos and shown["eval"] <= eval_photos
    assert not shown["tune"] & shown["eval"]
    # what the scenes actually put on their planes: only the recording's own photos
    for r in suite.recordings:
        kinds = {layer["kind"] for layer in r.scene.describe()["layers"]}
        assert kinds & set(PHOTOS) <= set(r.photos), r.name


def test_draws_lie_in_the_file_ranges_and_the_cameras_differ(suite, text):
    ranges = text["draw"]
    for r in suite.recordings:
        scale = r.rig.resolution[0] / 128
        for sensor in (r.rig.left, r.rig.right):
            for name in SENSOR_DRAWS:
                lo, hi = ranges[name]
                assert lo <= getattr(sensor, name) <= hi, (r.name, name)
            assert sensor.on_threshold != sensor.off_threshold
        assert r.rig.left != r.rig.right
        for name in RIG_DRAWS:
            lo, hi = ranges[name]
            values = ([r.rig.distortion_k1, r.rig.right_distortion_k1] if name == "distortion_k1" else
                      [getattr(r.rig, name) / (scale if name.endswith("_px") else 1)])
            assert all(lo - 1e-9 <= v <= hi + 1e-9 for v in values), (r.name, name, values)
        assert r.rig.focal_px == pytest.approx(165.0 * scale)  # the thesis' optics, the view angle kept
        assert 25.0 <= r.render_hz <= 2000.0
    thresholds = np.array([r.rig.left.on_threshold for r in suite.recordings])
    assert np.ptp(thresholds) > 0.25  # spread over the range, not bunched


def test_the_suite_is_the_same_every_time(suite):
    again = load_suite("generalization")
    assert [r.cache_name() for r in again.recordings] == [r.cache_name() for r in suite.recordings]
    assert len({r.cache_name() for r in suite.recordings}) == len(suite.recordings)


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d["photos"]["eval"].append("camera"), "camera in both halves"),
    (lambda d: d["recording"][4].update(photos=["camera"]), "photos must come from the eval half's list"),
    (lambda d: d["recording"][4].update(seed=d["recording"][0]["seed"]), "objects-tune-128x128 has 1101"),
    (lambda d: d["recording"][1].update(name=d["recording"][0]["name"]), "unique name"),
    (lambda d: d["recording"][0].update(family="sky"), "family must be one of"),
    (lambda d: d["recording"][0].update(half="test"), "half must be one of tune, eval"),
    (lambda d: d["recording"][0].update(sensor="100x100"), "sensor must be one of"),
    (lambda d: d["recording"][0].update(colour=1), "unknown key(s) colour"),
    (lambda d: d["draw"].pop("roll_deg"), "missing roll_deg"),
    (lambda d: d["draw"].update(on_threshold=[0.5, 0.1]), "on_threshold must be a range"),
    (lambda d: d["draw"].update(on_threshold=[-0.5, -0.1]), "on_threshold must be positive"),
    (lambda d: d["photos"]["tune"].append("selfie"), "unknown photo(s) selfie"),
])
def test_a_broken_suite_file_is_refused_at_its_place(text, change, message):
    data = copy.deepcopy(text)
    change(data)
    with pytest.raises(ValueError) as info:
        parse_family_suite(data, where="g.toml")
    assert "g.toml" in str(info.value) and message in str(info.value)


# --- the tuning guard ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """One tuning and one evaluation recording of 50 ms, generated into a cache of their own."""
    cache = tmp_path_factory.mktemp("cache")
    names = ["objects-tune-128x128", "objects-eval-128x128"]
    return dict(suite_recordings("generalization", seconds=0.05, cache_dir=cache, only=names)), cache


def test_require_tuning_refuses_evaluation_recordings_in_every_form(suite, tiny, tmp_path):
    paths, _ = tiny
    eval_spec, tune_spec = suite["objects-eval-128x128"], suite["objects-tune-128x128"]
    copy_path = tmp_path / "renamed.npz"  # a copy under another name still says where it comes from
    shutil.copyfile(paths["objects-eval-128x128"], copy_path)
    for what in (eval_spec, read_recording_npz(paths["objects-eval-128x128"]), paths["objects-eval-128x128"],
                 os.fspath(copy_path)):
        with pytest.raises(EvaluationRecordingError, match=r"objects-eval-128x128.*eval half.*tuning_recordings"):
            require_tuning(what)
    for what in (tune_spec, read_recording_npz(paths["objects-tune-128x128"]), paths["objects-tune-128x128"]):
        assert require_tuning(what) is None
    assert issubclass(EvaluationRecordingError, ValueError)


def test_recordings_without_halves_pass_the_guard():
    v1 = load_suite("robustness")["base"]
    assert require_tuning(v1) is None


def test_tuning_recordings_are_the_tuning_half_only(tiny):
    _, cache = tiny
    got = tuning_recordings(seconds=0.05, cache_dir=cache, only=["objects-tune-128x128"])
    assert [name for name, _ in got] == ["objects-tune-128x128"]
    with pytest.raises(ValueError, match=r"\(tune half\) has no recording objects-eval-128x128"):
        tuning_recordings(seconds=0.05, cache_dir=cache, only=["objects-eval-128x128"])
    meta = read_recording_npz(got[0][1]).meta["suite"]
    assert meta["half"] == "tune" and meta["family"] == "objects" and meta["drawn"]["left"]["on_threshold"] > 0


@pytest.mark.parametrize(("name", "half", "message"), [
    ("generalization", "test", "half must be one of tune, eval"),
    ("robustness", "tune", "suite 'robustness' has no tuning and evaluation halves"),
])
def test_halves_that_do_not_exist_are_refused(name, half, message):
    with pytest.raises(ValueError, match=message):
        suite_recordings(name, half=half)


def test_sweep_takes_either_half_of_the_suite(monkeypatch, tiny):
    """``suite:generalization:tune`` resolves to the tuning half's files (generation shortened to two clips)."""
    import cvstereo.simulate as simulate
    from cvstereo.sweep import resolve_recordings

    _, cache = tiny
    real = simulate.suite_recordings
    asked = []

    def short(name, *, half=None, progress=False, only=None):
        if only == []:  # the sweep's check of the spec before anything is generated: nothing to shorten
            return real(name, half=half, only=[])
        asked.append((name, half))
        first = [r.name for r in load_suite(name).recordings if half is None or r.half == half][:1]
        return real(name, half=half, seconds=0.05, cache_dir=cache, only=first, progress=progress)

    monkeypatch.setattr(simulate, "suite_recordings", short)
    for half in HALVES:
        (path,) = resolve_recordings([f"suite:generalization:{half}"])
        assert read_recording_npz(path).meta["suite"]["half"] == half
    resolve_recordings(["suite:generalization"])
    assert asked == [("generalization", "tune"), ("generalization", "eval"), ("generalization", None)]


def test_every_recording_is_a_family_recording_with_its_truth_defined(suite):
    for r in suite.recordings:
        assert isinstance(r, FamilyRecording)
        label = r.label()
        assert "x_left - x_right" in label["truth"] and "row" in label["truth"]
        assert label["max_disparity"] == round(64 * r.rig.resolution[0] / 128)
