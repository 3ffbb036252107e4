"""Calibration files: the YAML subset reader, DSEC and Kalibr layouts, OpenCV-style keys, and what is refused."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvstereo.geometry.calibration import MAX_YAML_BYTES, StereoCalibration, load_calibration, parse_calibration_yaml
from tests._calibration_fixtures import dsec_cam_to_cam, dump_yaml

RES = (640, 480)
K0 = np.array([[556.7, 0, 342.4], [0, 556.6, 215.1], [0, 0, 1]])
K3 = np.array([[555.6, 0, 321.0], [0, 555.7, 224.7], [0, 0, 1]])
D0, D3 = [-0.098, 0.21, -0.00036, 6.7e-05], [-0.109, 0.268, 0.00042, -0.0081]
R = np.array([[0.99981, -0.00298, 0.01918], [0.00326, 0.99989, -0.01432], [-0.01913, 0.01438, 0.99971]])
R = np.linalg.svd(R)[0] @ np.linalg.svd(R)[2]  # exactly orthonormal
T = np.array([-0.599, 0.002, 0.011])


def test_yaml_subset_reads_what_our_dumper_writes():
    data = {"a": {"b": [[1.0, -0.0], [2.5e-05, 3]], "name": "/davis/left/image_raw", "on": True, "none": None},
            "list": [{"k": 1, "v": [1, 2]}, {"k": 2}], "empty": []}
    assert parse_calibration_yaml(dump_yaml(data)) == data


def test_yaml_flow_style_comments_and_opencv_tags():
    text = """%YAML:1.0
---
cam0:  # Kalibr style
  intrinsics: [226.38, 226.15, 173.64, 133.73]
  T_cn_cnm1:
  - [0.9999, -0.0011, 0.0123, -0.0998]
  - [0.0011, 1.0, 1.0e-05, .inf]
  label: "a # not a comment"
M: !!opencv-matrix
   rows: 1
   data: [ 1., 2. ]
"""
    assert parse_calibration_yaml(text) == {"cam0": {"intrinsics": [226.38, 226.15, 173.64, 133.73],
                                          "T_cn_cnm1": [[0.9999, -0.0011, 0.0123, -0.0998],
                                                        [0.0011, 1.0, 1e-05, float("inf")]],
                                          "label": "a # not a comment"},
                                 "M": {"rows": 1, "data": [1.0, 2.0]}}
    with pytest.raises(ValueError, match=r"^f.yaml: not valid YAML at line 3 "):
        parse_calibration_yaml("a: 1\nb: [2, 3\nc: 4\n", source="f.yaml")


def test_python_tags_are_refused_and_oversized_files_are_not_read(tmp_path):
    # The safe loader builds no Python object: a tag that would run code is an error, not a call.
    with pytest.raises(ValueError, match="not valid YAML"):
        parse_calibration_yaml("a: !!python/object/apply:os.system ['true']\n", source="f.yaml")
    big = tmp_path / "cam_to_cam.yaml"
    big.write_bytes(b"a: 1\n" + b"#" * MAX_YAML_BYTES)
    with pytest.raises(ValueError, match=rf"cam_to_cam.yaml: {MAX_YAML_BYTES + 5} bytes, more than a calibration"):
        load_calibration(big)


def test_dsec_cam_to_cam(tmp_path):
    path = tmp_path / "cam_to_cam.yaml"
    path.write_text(dump_yaml(dsec_cam_to_cam(K0, D0, K3, D3, R, T, RES)))
    cal = load_calibration(path)
    ref = StereoCalibration.from_opencv(K0, D0, K3, D3, R, T, RES)
    assert cal.resolution == RES and cal.source == "cam_to_cam.yaml"
    assert cal.baseline_m == pytest.approx(np.linalg.norm(T), rel=1e-9)
    for mine, theirs in ((cal.left, ref.left), (cal.right, ref.right)):
        np.testing.assert_allclose(mine.K, theirs.K)
        np.testing.assert_allclose(mine.D, theirs.D)
        np.testing.assert_allclose(mine.R_rect, theirs.R_rect, atol=1e-12)
        np.testing.assert_allclose(mine.P_rect, theirs.P_rect, atol=1e-9)
    assert cal.depth_model().a == pytest.approx(ref.focal_px * np.linalg.norm(T))


def _kalibr(with_rectification: bool) -> dict:
    ref = StereoCalibration.from_opencv(K0, [0.01, -0.02, 0.003, 0.001], K3, [0.012, -0.018, 0.002, 0.0], R, T,
                                        (346, 260), model="equidistant")
    out = {}
    for i, (K, D, cam) in enumerate(((K0, [0.01, -0.02, 0.003, 0.001], ref.left),
                                     (K3, [0.012, -0.018, 0.002, 0.0], ref.right))):
        c = {"camera_model": "pinhole", "distortion_coeffs": D, "distortion_model": "equidistant",
             "intrinsics": [K[0, 0], K[1, 1], K[0, 2], K[1, 2]], "resolution": [346, 260],
             "rostopic": f"/davis/{('left', 'right')[i]}/image_raw"}
        if i == 1:
            T_ = np.eye(4)
            T_[:3, :3], T_[:3, 3] = R, T
            c["T_cn_cnm1"] = T_.tolist()
        if with_rectification:
            c["rectification_matrix"] = cam.R_rect.tolist()
            c["projection_matrix"] = np.hstack([cam.P_rect, np.zeros((3, 1))]).tolist()
        out[f"cam{i}"] = c
    return out, ref


@pytest.mark.parametrize("with_rectification", [True, False])
def test_kalibr_camchain(tmp_path, with_rectification):
    data, ref = _kalibr(with_rectification)
    path = tmp_path / "camchain-imucam-indoor_flying.yaml"
    path.write_text(dump_yaml(data))
    cal = load_calibration(path)
    assert cal.left.model == "equidistant" and cal.resolution == (346, 260)
    np.testing.assert_allclose(cal.right.P_rect, ref.right.P_rect, atol=1e-9)
    np.testing.assert_allclose(cal.right.R_rect, ref.right.R_rect, atol=1e-12)


def test_opencv_keys_as_json_and_npz(tmp_path):
    ref = StereoCalibration.from_opencv(K0, D0, K3, D3, R, T, RES)
    keys = {"K1": K0.tolist(), "D1": D0, "K2": K3.tolist(), "D2": D3, "R": R.tolist(), "T": T.tolist(),
            "resolution": list(RES)}
    (tmp_path / "c.json").write_text(json.dumps(keys))
    np.savez(tmp_path / "c.npz", **{k: np.asarray(v) for k, v in keys.items()})
    for name in ("c.json", "c.npz"):
        cal = load_calibration(tmp_path / name)
        np.testing.assert_allclose(cal.left.P_rect, ref.left.P_rect)
        np.testing.assert_allclose(cal.right.R_rect, ref.right.R_rect)


def test_bad_calibrations_say_what_is_missing(tmp_path):
    (tmp_path / "c.json").write_text(json.dumps({"K1": K0.tolist()}))
    with pytest.raises(ValueError, match="missing D1, K2, D2, R, T, resolution"):
        load_calibration(tmp_path / "c.json")
    (tmp_path / "x.yaml").write_text("foo: 1\n")
    with pytest.raises(ValueError, match=r"not a known calibration layout.*foo"):
        load_calibration(tmp_path / "x.yaml")
    data = dsec_cam_to_cam(K0, D0, K3, D3, R, T, RES)
    del data["extrinsics"]["R_rect3"]
    (tmp_path / "cam_to_cam.yaml").write_text(dump_yaml(data))
    with pytest.raises(ValueError, match="without 'R_rect3'"):
        load_calibration(tmp_path / "cam_to_cam.yaml")
    with pytest.raises(FileNotFoundError):
        load_calibration(tmp_path / "none.yaml")
    with pytest.raises(ValueError, match="T is zero"):
        StereoCalibration.from_opencv(K0, None, K3, None, np.eye(3), [0, 0, 0], RES)
