"""The two parameter sets: ``thesis`` reproduces the matches of the thesis' constants bit for bit."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from calibration_free import match
from cvstereo.io.npz import read_recording_npz
from tests._paths import DATA

HASHES = json.loads((DATA / "thesis_hashes.json").read_text())["hashes"]


@pytest.fixture(scope="module")
def clip():
    return read_recording_npz(DATA / "thesis_clip.npz")


@pytest.mark.parametrize("key", sorted(HASHES))
def test_thesis_set_reproduces_the_committed_matches(clip, key):
    method, variant = key.split("/")
    result = match(clip, method=method, variant=variant, param_set="thesis")
    assert result.meta["param_set"] == "thesis"
    assert len(result) == HASHES[key]["matches"]
    assert hashlib.sha256(result.matches.tobytes()).hexdigest() == HASHES[key]["sha256"]


def test_sets_choose_variant_and_values_and_overrides_win(clip):
    from calibration_free import create_matcher

    adaptive = create_matcher("frame")
    assert adaptive.params.polarity == "separate" and adaptive.params.threshold_mode == "relative"
    thesis = create_matcher("frame", param_set="thesis")
    assert thesis.params.polarity == "shared" and thesis.params.threshold_mode == "absolute"
    explicit = create_matcher("frame", "on", threshold_scale=0.9)  # explicit variant and --param win
    assert explicit.params.polarity == "on" and explicit.params.threshold_scale == 0.9
    # An explicit variant gets the set's values of the method: no-gaussian keeps the relative scale of 0.6.
    ng = create_matcher("frame-area", "no-gaussian").params
    assert ng.threshold_scale == 0.6 and not ng.gaussian and ng.threshold_mode == "relative"
    with pytest.raises(ValueError, match="unknown parameter set 'thesys'; choose one of: adaptive, thesis"):
        create_matcher("frame", param_set="thesys")


def test_match_meta_records_the_set_and_the_diagnostics(clip):
    result = match(clip, method="event-area")
    meta = result.meta
    assert meta["param_set"] == "adaptive" and meta["variant"] == "gaussian"
    d = meta["diagnostics"]
    assert d["windows_with_events"] == 25 and 0 < d["windows_with_matches"] <= 25
    assert d["windows_seen"] == 25 and d["threshold_mode"] == "relative"
    # the first window runs on the absolute threshold (warm-up), later ones on the relative one
    assert d["threshold_trace"][0] == [40_000, [1.2, 1.2]] and d["threshold_trace"][1][1] != [1.2, 1.2]


def test_cli_param_set_variant_and_warning(tmp_path, capsys):
    from cvstereo.cli import main
    from cvstereo.io import read_matches, write_recording
    from cvstereo.model.events import make_events
    from cvstereo.model.recording import Recording

    # Sparse edges: two events per pixel on a vertical line each window, 5 px apart; the thesis threshold (1.2
    # on the filtered sum, about 3 events a pixel along a line) is never reached.
    t, x, y = [], [], []
    for k in range(50):
        for row in range(30, 90):
            for rep in range(2):
                t.append(k * 40_000 + 100 * row + rep)
                x.append(40 + k % 20)
                y.append(row)
    ev = make_events(t, x, y, 1)
    rec = Recording(ev, make_events(t, np.asarray(x) - 5, y, 1))
    path = tmp_path / "sparse.npz"
    write_recording(path, rec)
    out = tmp_path / "m.npz"
    assert main(["match", str(path), "-o", str(out), "--param-set", "thesis"]) == 0
    captured = capsys.readouterr()
    assert "0 matches" in captured.out and "(frame, shared, thesis)" in captured.out
    lines = [line for line in captured.err.splitlines() if line]
    assert len(lines) == 1 and lines[0].startswith("warning: no window reached the threshold: highest filtered "
                                                   "value 0.") and "< 1.2" in lines[0]
    assert "--param-set adaptive" in lines[0]
    assert read_matches(out).meta["param_set"] == "thesis"
    assert main(["match", str(path), "-o", str(out)]) == 0  # adaptive answers, without a warning
    captured = capsys.readouterr()
    assert captured.err == "" and "(frame, separate, adaptive)" in captured.out
    got = read_matches(out)
    assert len(got) > 0 and set(got.disparity.tolist()) == {5.0}
    np.testing.assert_array_equal(got.matches, match(path).matches)
    assert main(["match", str(path), "-o", str(out), "--variant", "shared", "--param", "threshold_scale=0.4"]) == 0
    got = read_matches(out)
    assert got.meta["variant"] == "shared" and got.meta["params"]["threshold_scale"] == 0.4
