"""Calibration files in the layouts of DSEC and Kalibr, written by a small block-style YAML dumper of our own
(as PyYAML writes them: lists at their key's indentation, nested lists as ``- - ``), for the loader tests."""

from __future__ import annotations

import cv2
import numpy as np


def dump_yaml(value, indent: int = 0) -> str:
    """Block-style YAML of dicts, lists and scalars (PyYAML's default_flow_style=False layout)."""
    pad = " " * indent
    if isinstance(value, dict):
        out = []
        for key, v in value.items():
            if isinstance(v, (dict, list)) and v:
                child = indent + 2 if isinstance(v, dict) else indent
                out.append(f"{pad}{key}:\n{dump_yaml(v, child)}")
            else:
                out.append(f"{pad}{key}: {_scalar(v)}\n")
        return "".join(out)
    out = []
    for item in value:
        if isinstance(item, (dict, list)) and item:
            inner = dump_yaml(item, indent + 2)
            out.append(f"{pad}- {inner[indent + 2:]}")
        else:
            out.append(f"{pad}- {_scalar(item)}\n")
    return "".join(out)


def _scalar(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float, np.integer, np.floating)):
        return repr(float(v)) if isinstance(v, (float, np.floating)) else str(int(v))
    if v is None:
        return "null"
    return "[]" if isinstance(v, list) else str(v)


def rigid(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def dsec_cam_to_cam(K0, D0, K3, D3, R, T, resolution) -> dict:
    """DSEC's cam_to_cam.yaml content for event cameras cam0 (left) and cam3 (right) with x3 = R x0 + T.

    The frame cameras cam1, cam2 sit between them (T_10, T_21 arbitrary rigid motions, T_32 closes the chain),
    and the rectification is OpenCV's, as DSEC computed it.
    """
    R1, R2, P1, P2, *_ = cv2.stereoRectify(np.asarray(K0, float), np.asarray(D0, float), np.asarray(K3, float),
                                           np.asarray(D3, float), tuple(resolution), np.asarray(R, float),
                                           np.asarray(T, float).reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY,
                                           alpha=-1)
    T_10 = rigid(cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0], [-0.04, 0.001, -0.012])
    T_21 = rigid(cv2.Rodrigues(np.array([0.003, 0.01, -0.017]))[0], [-0.51, -0.002, 0.006])
    T_32 = rigid(R, T) @ np.linalg.inv(T_21 @ T_10)

    def k4(K):
        return [float(K[0][0]), float(K[1][1]), float(K[0][2]), float(K[1][2])]

    def cam(K, D, kind):
        return {"camera_type": kind, "is_rectified": False, "camera_model": "pinhole",
                "distortion_coeffs": [float(d) for d in D], "distortion_model": "radtan",
                "resolution": list(resolution), "camera_matrix": k4(K)}

    rect = {"camera_type": "event", "is_rectified": True, "camera_model": "pinhole", "resolution": list(resolution)}
    frame_K = np.array([[1150.0, 0, 720], [0, 1150.0, 540], [0, 0, 1]])
    return {
        "intrinsics": {
            "cam0": cam(K0, D0, "event"), "camRect0": {**rect, "camera_matrix": k4(P1)},
            "cam1": cam(frame_K, [-0.4, 0.18, 0.001, -0.001], "frame"),
            "cam3": cam(K3, D3, "event"), "camRect3": {**rect, "camera_matrix": k4(P2)},
        },
        "extrinsics": {"T_10": T_10.tolist(), "T_21": T_21.tolist(), "T_32": T_32.tolist(),
                       "R_rect0": np.asarray(R1).tolist(), "R_rect3": np.asarray(R2).tolist()},
        "disparity_to_depth": {"cams_03": np.eye(4).tolist()},
    }
