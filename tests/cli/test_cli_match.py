"""``cvstereo match``: the same matches and parameters as ``calibration_free.match``; errors exit 1."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from calibration_free import METHODS, match
from cvstereo.cli import main
from cvstereo.io import read_matches, write_recording
from tests._io_helpers import textured_blobs

W = 40_000


@pytest.fixture(scope="module")
def recording_file(tmp_path_factory):
    rec = textured_blobs(0, 4, disparity=13, window_us=W)  # four windows of textured blobs
    path = tmp_path_factory.mktemp("rec") / "blobs.npz"
    write_recording(path, rec)
    return path


@pytest.mark.parametrize(("method", "variant", "params"), [
    ("frame", "separate", {"threshold": 1.5}),
    ("frame-area", "no-gaussian", {"reference_camera": 0, "threshold": 3}),
    ("stereobm", None, {"num_disparities": 32}),
])
def test_cli_equals_match(tmp_path, recording_file, method, variant, params):
    out = tmp_path / "m.npz"
    argv = ["match", str(recording_file), "--method", method, "-o", str(out)]
    argv += ["--variant", variant] if variant else []
    for k, v in params.items():
        argv += ["--param", f"{k}={v}"]
    assert main(argv) == 0
    got = read_matches(out)
    expected = match(recording_file, method=method, variant=variant, **params)
    assert got.matches.size > 0
    np.testing.assert_array_equal(got.matches, expected.matches)
    for key in ("method", "variant", "params", "anchor", "window_us", "input_events", "version"):
        assert got.meta[key] == expected.meta[key], key
    assert got.meta["elapsed_s"] >= 0 and got.meta["input"] == [str(recording_file)]


def test_cli_as_a_subprocess(tmp_path, recording_file):
    out = tmp_path / "m.npz"
    proc = subprocess.run([sys.executable, "-m", "cvstereo", "match", str(recording_file), "-o", str(out),
                           "--no-progress"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "matches" in proc.stdout
    np.testing.assert_array_equal(read_matches(out).matches, match(recording_file).matches)


def test_list_methods(capsys):
    assert main(["match", "--list-methods"]) == 0
    text = capsys.readouterr().out
    for name in METHODS:
        assert f"{name}:" in text
    # adaptive (the default set) picks its own default variant, the thesis' default is marked beside it
    for expected in ("shared (thesis default), separate (default), on, off", "gaussian (default), no-gaussian",
                     "adaptive set (default): variant separate, because ON and OFF events in one frame cancel",
                     "thesis set (--param-set thesis): variant shared",
                     "width_tolerance = 0.3", "threshold = 1.2", "reference_camera = 1", "max_disparity = 63",
                     "no-gaussian: gaussian=false, threshold=4.0",
                     # sgbm's 0 = automatic, with OpenCV's usual values at its default block of 5: 8 * 25, 32 * 25
                     "p1 = 0  (int; 0 = automatic: 8 * block_size**2 = 200 at block_size 5)",
                     "p2 = 0  (int; 0 = automatic: 32 * block_size**2 = 800 at block_size 5)"):
        assert expected in text


@pytest.mark.parametrize(("args", "message"), [
    (["--method", "frames"], "choose one of: frame, frame-area"),
    (["--variant", "both"], "shared, separate, on, off"),
    (["--param", "treshold=2"], "allowed: anchor_camera"),
    (["--param", "threshold=high"], "needs a float"),
    (["--param", "threshold=-1"], "--param 'threshold' must be > 0 (the thesis uses 1.2), got -1.0"),
    (["--param", "polarity=both"], "must be one of shared, separate, on, off"),
    (["--method", "stereobm", "--param", "num_disparities=40"], "multiple of 16"),
])
def test_invalid_input_exits_1_listing_the_allowed(tmp_path, recording_file, capsys, args, message):
    out = tmp_path / "m.npz"
    assert main(["match", str(recording_file), "-o", str(out), *args]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_missing_output_is_a_usage_error(recording_file):
    with pytest.raises(SystemExit) as exc:
        main(["match", str(recording_file)])
    assert exc.value.code == 2
