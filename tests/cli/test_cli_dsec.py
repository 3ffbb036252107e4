"""DSEC end to end (issue 26 item 5): a sequence folder as input, `cvstereo evaluate SEQUENCE m.npz` with DSEC's
metrics, `cvstereo export-dsec` writing DSEC's 16-bit PNGs; on a simulated sequence written as DSEC's public
description says (tests/_dsec_scene.py), checked against a computation written here with OpenCV and PyYAML only."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from cvstereo.cli import main
from cvstereo.io import read_matches, read_recording

pytest.importorskip("h5py")
pytest.importorskip("hdf5plugin")

from tests._dsec_scene import write_dsec_sequence

WINDOW_US = 50_000  # DSEC: the matches of (ts - 50 ms, ts] belong to the map at ts
NAME = "zurich_city_99_a"


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """A sequence with ground truth, and two matches files: event-time (anchored on the right camera, events) and
    sgbm (the left camera, windows), both computed with the sequence's calibration."""
    d = tmp_path_factory.mktemp("dsec")
    seq = write_dsec_sequence(d / NAME, seconds=0.2, seed=4, truth=True)
    for method in ("event-time", "sgbm"):
        assert main(["match", str(seq), "-m", method, "--calibration", str(seq / "calibration" / "cam_to_cam.yaml"),
                     "-o", str(d / f"{method}.npz"), "--no-progress"]) == 0
    return d


def _rectifier(seq: Path):
    """Raw pixel -> rectified pixel of cam0 / cam3, from cam_to_cam.yaml read with PyYAML and OpenCV alone."""
    data = yaml.safe_load((seq / "calibration" / "cam_to_cam.yaml").read_text())

    def k(v):
        return np.array([[v[0], 0, v[2]], [0, v[1], v[3]], [0, 0, 1]], float)

    cams = []
    for raw, rect, rot in (("cam0", "camRect0", "R_rect0"), ("cam3", "camRect3", "R_rect3")):
        intr = data["intrinsics"]
        cams.append((k(intr[raw]["camera_matrix"]), np.array(intr[raw]["distortion_coeffs"], float),
                     np.array(data["extrinsics"][rot], float), k(intr[rect]["camera_matrix"])))

    def rectify(x, y, camera):
        K, D, Rr, P = cams[camera]
        pts = np.stack([x, y], axis=1).astype(np.float64).reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)
        out = cv2.undistortPoints(pts, K, D, R=Rr, P=P, criteria=criteria).reshape(-1, 2)
        return np.rint(out[:, 0]).astype(int), np.rint(out[:, 1]).astype(int)

    return rectify


def _expected(seq: Path, matches_file: Path) -> tuple[dict, dict]:
    """DSEC's metrics and the predicted maps, computed here: per map, the matches of its 50 ms at their rectified
    left pixels (right-anchored ones d px to the right), per pixel the mean, compared where the PNG is not 0."""
    m = read_matches(matches_file).matches
    m = m[np.isfinite(m["disparity"])]
    rectify = _rectifier(seq)
    lx, ly = np.zeros(m.size, int), np.zeros(m.size, int)
    for cam in (0, 1):
        sel = m["camera"] == cam
        lx[sel], ly[sel] = rectify(m["x"][sel], m["y"][sel], cam)
    lx = np.where(m["camera"] == 1, np.rint(lx + m["disparity"]).astype(int), lx)
    stamps = [int(v) for v in (seq / "disparity" / "timestamps.txt").read_text().split()]
    pngs = sorted((seq / "disparity" / "event").glob("*.png"))
    errors, truth_pixels, maps = [], 0, {}
    for ts, png in zip(stamps, pngs, strict=True):
        raw = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        sums, counts = {}, {}
        for i in np.flatnonzero((m["t"] > ts - WINDOW_US) & (m["t"] <= ts)):
            if 0 <= lx[i] < 640 and 0 <= ly[i] < 480:
                key = (ly[i], lx[i])
                sums[key] = sums.get(key, 0.0) + float(m["disparity"][i])
                counts[key] = counts.get(key, 0) + 1
        pred = np.full(raw.shape, np.nan)
        for key, s in sums.items():
            pred[key] = s / counts[key]
        maps[png.name] = pred
        truth_pixels += int((raw > 0).sum())
        both = (raw > 0) & np.isfinite(pred)
        errors.append(np.abs(pred[both] - raw[both] / 256.0))
    e = np.concatenate(errors)
    return {"1PE": np.mean(e > 1), "2PE": np.mean(e > 2), "MAE": e.mean(), "RMSE": np.sqrt(np.mean(e**2)),
            "coverage": e.size / truth_pixels, "maps": len(stamps), "pixels_scored": e.size}, maps


@pytest.mark.parametrize("method", ["event-time", "sgbm"])
def test_evaluate_prints_dsecs_metrics_within_001_px_of_an_independent_computation(base, method, capsys):
    seq = base / NAME
    want, _ = _expected(seq, base / f"{method}.npz")
    assert want["pixels_scored"] > 500 and want["maps"] == 4
    assert main(["evaluate", str(seq), str(base / f"{method}.npz"), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)["figures"]
    for key in ("MAE", "RMSE"):
        assert abs(got[key] - want[key]) < 0.01, (key, got[key], want[key])
    for key in ("1PE", "2PE", "coverage"):
        assert abs(got[key] - want[key]) < 1e-3, (key, got[key], want[key])
    assert (got["maps"], got["pixels_scored"]) == (want["maps"], want["pixels_scored"])
    # The table: DSEC's four metrics and the coverage beside them, as percentages where DSEC prints them so.
    assert main(["evaluate", str(seq), str(base / f"{method}.npz")]) == 0
    out = capsys.readouterr().out
    assert "| 1PE | 2PE | MAE | RMSE | coverage |" in out and f"{100 * want['1PE']:.2f}%" in out
    assert f"DSEC ground truth of {NAME}: 4 disparity maps" in out


def test_export_writes_dsec_pngs_that_read_back_to_the_disparities_within_1_256_px(base, tmp_path, capsys):
    seq = base / NAME
    _, maps = _expected(seq, base / "sgbm.npz")
    assert main(["export-dsec", str(seq), str(base / "sgbm.npz"), "-o", str(tmp_path / "sub")]) == 0
    written = sorted((tmp_path / "sub" / NAME).iterdir())
    assert [p.name for p in written] == sorted(maps) == ["000002.png", "000004.png", "000006.png", "000008.png"]
    answered = 0
    for png in written:
        raw = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        assert raw.dtype == np.uint16 and raw.shape == (480, 640)
        want = maps[png.name]
        # 0 = no answer (DSEC's invalid); beyond the 16-bit range there is none here, and no answer <= 0 px
        storable = np.isfinite(want) & (want > 0) & (want <= 65535 / 256)
        np.testing.assert_array_equal(raw > 0, storable)
        assert np.max(np.abs(raw[storable] / 256.0 - want[storable]), initial=0) <= 1 / 256
        answered += int(storable.sum())
    assert answered > 500


def test_export_at_dsecs_test_timestamps_names_the_pngs_by_file_index(base, tmp_path, capsys):
    seq = base / NAME
    csv = tmp_path / f"{NAME}.csv"
    csv.write_text("# timestamp_us, file_index\n52000100000, 20\n52000150000, 30\n")
    assert main(["export-dsec", str(seq), str(base / "sgbm.npz"), "-o", str(tmp_path / "sub"), "--timestamps",
                 str(csv)]) == 0
    _, maps = _expected(seq, base / "sgbm.npz")  # the maps at 100 and 150 ms are the ground truth's 000004, 000006
    for name, same in (("000020.png", "000004.png"), ("000030.png", "000006.png")):
        raw = cv2.imread(str(tmp_path / "sub" / NAME / name), cv2.IMREAD_UNCHANGED)
        want = np.where(np.isfinite(maps[same]) & (maps[same] <= 255), maps[same], 0)
        assert np.max(np.abs(raw / 256.0 - want)) <= 1 / 256


def test_a_sequence_folder_is_one_stereo_recording_named_by_its_folder(base, tmp_path, capsys):
    seq = base / NAME
    rec = read_recording(seq)
    left = read_recording(seq / "events" / "left" / "events.h5", seq / "events" / "right" / "events.h5")
    np.testing.assert_array_equal(rec.left, left.left)
    np.testing.assert_array_equal(rec.right, left.right)
    assert rec.meta["sequence"] == NAME and rec.resolution == (640, 480)
    assert main(["info", str(seq)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{seq}: DSEC sequence {NAME}, 640x480") and "one camera" not in out
    assert "ground-truth disparity maps: 4" in out and "\n  left " in out and "\n  right " in out
    # The matches name the folder as their input
    assert read_matches(base / "sgbm.npz").meta["input"] in (str(seq), [str(seq)])


def test_a_test_sequence_without_ground_truth_is_read_and_its_folder_named(base, tmp_path, capsys):
    seq = tmp_path / "interlaken_00_a"
    shutil.copytree(base / NAME, seq)
    shutil.rmtree(seq / "disparity")
    assert main(["info", str(seq)]) == 0
    assert "ground-truth disparity maps: none (a test sequence)" in capsys.readouterr().out


def test_evaluate_and_export_check_the_matches_without_holding_the_sequence(base, tmp_path, monkeypatch, capsys):
    """A DSEC sequence may be larger than memory: scoring and export need its events only for the check that the
    matches were computed on them, which streams its fingerprint; the recording is read whole only to say what
    differs when it is another."""
    import cvstereo.io

    seq = base / NAME

    def refuse(*args, **kwargs):
        raise AssertionError("the whole recording was read")

    monkeypatch.setattr(cvstereo.io, "read_recording", refuse)
    assert main(["evaluate", str(seq), str(base / "sgbm.npz"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figures"]["maps"] == 4
    assert main(["export-dsec", str(seq), str(base / "sgbm.npz"), "-o", str(tmp_path / "sub")]) == 0
    assert len(list((tmp_path / "sub" / NAME).iterdir())) == 4
    monkeypatch.undo()
    # Another sequence (other seed, same layout): refused, saying what differs, as before.
    other = write_dsec_sequence(tmp_path / "other" / NAME, seconds=0.2, seed=5, truth=True)
    assert main(["evaluate", str(other), str(base / "sgbm.npz")]) == 1
    err = capsys.readouterr().err
    assert "computed on another recording" in err and err.count("\n") == 1
