"""Stereo calibrations for users who have one: OpenCV-style K, D, R, T, DSEC's ``cam_to_cam.yaml``, Kalibr camchains.

cvstereo needs no calibration; with one, :mod:`cvstereo.geometry.rectify` maps events onto rectified rows. A
:class:`StereoCalibration` holds, per camera, the raw intrinsics and distortion and the rectifying rotation and
camera matrix, plus the baseline. Conventions (OpenCV's): ``R, T`` map a point of the left camera's frame into the
right camera's, ``x_right = R @ x_left + T``; the rectified cameras share one focal length and row centre.

Sources:

- :meth:`StereoCalibration.from_opencv`: ``K1, D1, K2, D2, R, T`` (``cv2.stereoCalibrate``'s output); the
  rectification is computed with ``cv2.stereoRectify`` (``cv2.fisheye.stereoRectify`` for equidistant lenses);
- DSEC ``cam_to_cam.yaml``: the event cameras ``cam0`` (left) and ``cam3`` (right) with DSEC's own rectification
  (``R_rect0``/``R_rect3``, ``camRect0``/``camRect3``), so that disparities agree with DSEC's ground truth;
- Kalibr camchain (MVSEC's ``camchain-*.yaml``): ``cam0`` left, ``cam1`` right, ``T_cn_cnm1``; its
  ``rectification_matrix``/``projection_matrix`` when given (MVSEC ships them), else computed;
- ``.json`` / ``.npz`` with keys ``K1, D1, K2, D2, R, T, resolution`` (optional ``model``).

YAML is read with PyYAML's safe loader (:func:`parse_calibration_yaml`), files of at most
:data:`MAX_YAML_BYTES`.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
import yaml

from cvstereo.geometry.depth import DepthModel

__all__ = ["MAX_YAML_BYTES", "MODELS", "CameraCalibration", "StereoCalibration", "load_calibration",
           "parse_calibration_yaml"]

#: The largest calibration YAML file read. Calibration files are a few kB; the cap keeps a wrong path (a
#: recording named .yaml) from being parsed whole into memory.
MAX_YAML_BYTES = 1 << 20

#: Distortion models: OpenCV's polynomial (Kalibr's "radtan", ROS "plumb_bob") and the fisheye "equidistant".
MODELS = ("radtan", "equidistant")


@dataclass(frozen=True, eq=False)
class CameraCalibration:
    """One camera: raw intrinsics and distortion, and its rectified view.

    Attributes
    ----------
    K : (3, 3) ndarray
        Raw camera matrix.
    D : (n,) ndarray
        Distortion coefficients of ``model`` (OpenCV order: k1, k2, p1, p2[, k3, ...]; fisheye: k1..k4).
    model : {"radtan", "equidistant"}
    R_rect : (3, 3) ndarray
        Rotation from the camera's frame to its rectified frame.
    P_rect : (3, 3) ndarray
        Camera matrix of the rectified view.
    """

    K: np.ndarray
    D: np.ndarray
    model: str
    R_rect: np.ndarray
    P_rect: np.ndarray


@dataclass(frozen=True, eq=False)
class StereoCalibration:
    """A calibrated stereo pair (see the module doc for the conventions).

    Attributes
    ----------
    left, right : CameraCalibration
    resolution : (width, height)
        Of both the raw and the rectified images.
    baseline_m : float
    source : str
        Where it came from (file name or ``"opencv"``), for meta and file headers.
    """

    left: CameraCalibration
    right: CameraCalibration
    resolution: tuple[int, int]
    baseline_m: float
    source: str = "opencv"

    @property
    def focal_px(self) -> float:
        """Focal length of the rectified views, px."""
        return float(self.left.P_rect[0, 0])

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) of the rectified left view, px."""
        return float(self.left.P_rect[0, 2]), float(self.left.P_rect[1, 2])

    def depth_model(self) -> DepthModel:
        """``d = f*B/Z - c`` of the rectified pair (c from the rectified principal points: 0 for most rigs)."""
        return DepthModel(a=self.focal_px * self.baseline_m,
                          c=float(self.right.P_rect[0, 2] - self.left.P_rect[0, 2]))

    def describe(self) -> dict:
        """JSON-serialisable summary for a matches file's meta."""
        return {"source": self.source, "resolution": list(self.resolution), "baseline_m": self.baseline_m,
                "focal_px": self.focal_px, "principal_point": list(self.principal_point),
                "models": [self.left.model, self.right.model]}

    @classmethod
    def from_opencv(cls, K1, D1, K2, D2, R, T, resolution, *, model: str = "radtan",
                    source: str = "opencv") -> StereoCalibration:
        """A calibration from OpenCV's stereo parameters; the rectification is computed here.

        Parameters
        ----------
        K1, K2 : (3, 3) array_like
            Raw camera matrices of the left and right camera.
        D1, D2 : array_like
            Distortion coefficients (empty or zeros: none).
        R : (3, 3) array_like
            Rotation, left camera frame to right camera frame (or a Rodrigues vector of 3).
        T : (3,) array_like
            Translation, metres: ``x_right = R @ x_left + T`` (the right camera at +B on x gives T = (-B, 0, 0)).
        resolution : (width, height)
        model : {"radtan", "equidistant"}, keyword-only

        Raises
        ------
        ValueError
            Wrong shapes, an unknown model, or a zero baseline.
        """
        K1, K2 = (_matrix(k, (3, 3), name) for k, name in ((K1, "K1"), (K2, "K2")))
        R = np.asarray(R, np.float64)
        if R.size == 3:
            R = cv2.Rodrigues(R.reshape(3, 1))[0]
        R = _matrix(R, (3, 3), "R")
        T = _matrix(T, (3,), "T")
        D1, D2 = (_distortion(d, model, name) for d, name in ((D1, "D1"), (D2, "D2")))
        size = (int(resolution[0]), int(resolution[1]))
        baseline = float(np.linalg.norm(T))
        if not baseline > 0:
            raise ValueError("T is zero: a stereo calibration needs the cameras apart (T = -R @ position of "
                             "the right camera in the left camera's frame).")
        if model == "equidistant":
            R1, R2, P1, P2, _ = cv2.fisheye.stereoRectify(K1, D1, K2, D2, size, R, T.reshape(3, 1),
                                                          flags=cv2.CALIB_ZERO_DISPARITY, balance=0.0)
        else:
            R1, R2, P1, P2, *_ = cv2.stereoRectify(K1, D1, K2, D2, size, R, T.reshape(3, 1),
                                                   flags=cv2.CALIB_ZERO_DISPARITY, alpha=-1)
        return cls(CameraCalibration(K1, D1, model, R1, P1[:, :3]), CameraCalibration(K2, D2, model, R2, P2[:, :3]),
                   size, baseline, source)


def _matrix(value, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.array(value, np.float64)  # a contiguous copy: OpenCV refuses strided views
    if arr.size != int(np.prod(shape)) or not np.isfinite(arr).all():
        raise ValueError(f"calibration: {name} must be {' x '.join(map(str, shape))} finite numbers, got "
                         f"shape {arr.shape}.")
    return arr.reshape(shape)


def _distortion(value, model: str, name: str) -> np.ndarray:
    if model not in MODELS:
        raise ValueError(f"calibration: distortion model '{model}' is not supported; use one of "
                         f"{', '.join(MODELS)} (Kalibr: radtan or equidistant; ROS: plumb_bob).")
    arr = np.zeros(4) if value is None else np.asarray(value, np.float64).ravel()
    if model == "equidistant" and arr.size != 4:
        raise ValueError(f"calibration: {name} of an equidistant lens has 4 coefficients, got {arr.size}.")
    if model == "radtan" and arr.size not in (0, 4, 5, 8, 12, 14):
        raise ValueError(f"calibration: {name} has {arr.size} coefficients; OpenCV takes 4, 5, 8, 12 or 14.")
    return arr if arr.size else np.zeros(4)


def _k4(values, name: str) -> np.ndarray:
    fx, fy, cx, cy = _matrix(values, (4,), name)
    return np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])


_MODEL_NAMES = {"radtan": "radtan", "plumb_bob": "radtan", "none": "radtan", "equidistant": "equidistant",
                "fisheye": "equidistant"}


def _model(name, where: str) -> str:
    model = _MODEL_NAMES.get(str(name or "radtan").lower())
    if model is None:
        raise ValueError(f"calibration {where}: distortion model '{name}' is not supported "
                         f"(use {', '.join(sorted(_MODEL_NAMES))}).")
    return model


def _dsec(data: dict, source: str) -> StereoCalibration:
    intr, extr = data["intrinsics"], data["extrinsics"]
    try:
        cams = []
        for raw, rect in (("cam0", "camRect0"), ("cam3", "camRect3")):
            c = intr[raw]
            model = _model(c.get("distortion_model"), f"{source} [{raw}]")
            cams.append(CameraCalibration(_k4(c["camera_matrix"], f"{raw}.camera_matrix"),
                                          _distortion(c.get("distortion_coeffs"), model, f"{raw}.distortion_coeffs"),
                                          model, _matrix(extr[f"R_rect{raw[-1]}"], (3, 3), f"R_rect{raw[-1]}"),
                                          _k4(intr[rect]["camera_matrix"], f"{rect}.camera_matrix")))
        # T_XY maps camY into camX: cam0 -> cam1 -> cam2 -> cam3.
        chain = [_matrix(extr[k], (4, 4), k) for k in ("T_32", "T_21", "T_10")]
        T_30 = chain[0] @ chain[1] @ chain[2]
        resolution = tuple(int(v) for v in intr["cam0"]["resolution"])
    except KeyError as exc:
        raise ValueError(f"{source}: DSEC cam_to_cam.yaml without {exc}; it needs intrinsics cam0, cam3, camRect0, "
                         "camRect3 and extrinsics R_rect0, R_rect3, T_10, T_21, T_32.") from None
    return StereoCalibration(cams[0], cams[1], resolution, float(np.linalg.norm(T_30[:3, 3])), source)


def _kalibr(data: dict, source: str) -> StereoCalibration:
    try:
        c0, c1 = data["cam0"], data["cam1"]
        T = _matrix(c1["T_cn_cnm1"], (4, 4), "cam1.T_cn_cnm1")
        models = [_model(c.get("distortion_model"), f"{source} [cam{i}]") for i, c in enumerate((c0, c1))]
        Ks = [_k4(c["intrinsics"], f"cam{i}.intrinsics") for i, c in enumerate((c0, c1))]
        Ds = [_distortion(c.get("distortion_coeffs"), m, f"cam{i}.distortion_coeffs")
              for i, (c, m) in enumerate(zip((c0, c1), models, strict=True))]
        resolution = tuple(int(v) for v in c0["resolution"])
    except KeyError as exc:
        raise ValueError(f"{source}: Kalibr camchain without {exc}; it needs cam0 and cam1 with intrinsics, "
                         "resolution, distortion, and cam1.T_cn_cnm1.") from None
    if len(set(models)) > 1:
        raise ValueError(f"{source}: the cameras use different distortion models {models}; not supported.")
    if all("rectification_matrix" in c and "projection_matrix" in c for c in (c0, c1)):
        cams = [CameraCalibration(K, D, m, _matrix(c["rectification_matrix"], (3, 3), f"cam{i}.rectification_matrix"),
                                  _matrix(c["projection_matrix"], (3, 4), f"cam{i}.projection_matrix")[:, :3])
                for i, (c, K, D, m) in enumerate(zip((c0, c1), Ks, Ds, models, strict=True))]
        return StereoCalibration(cams[0], cams[1], resolution, float(np.linalg.norm(T[:3, 3])), source)
    return StereoCalibration.from_opencv(Ks[0], Ds[0], Ks[1], Ds[1], T[:3, :3], T[:3, 3], resolution,
                                         model=models[0], source=source)


def _opencv_keys(data, source: str) -> StereoCalibration:
    missing = [k for k in ("K1", "D1", "K2", "D2", "R", "T", "resolution") if k not in data]
    if missing:
        raise ValueError(f"{source}: an OpenCV-style calibration needs keys K1, D1, K2, D2, R, T, resolution; "
                         f"missing {', '.join(missing)}.")
    model = str(np.asarray(data["model"]).item()) if "model" in data else "radtan"
    return StereoCalibration.from_opencv(*(data[k] for k in ("K1", "D1", "K2", "D2", "R", "T")),
                                         [int(v) for v in np.asarray(data["resolution"]).ravel()],
                                         model=_model(model, source), source=source)


def load_calibration(path: str | os.PathLike) -> StereoCalibration:
    """Read a stereo calibration file (DSEC, Kalibr/MVSEC, or OpenCV-style ``.json`` / ``.npz``).

    Raises
    ------
    FileNotFoundError
    ValueError
        An unknown layout or missing keys; the message says what the file needs.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such calibration file.")
    source = path.name
    suffix = path.suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            return _opencv_keys({k: data[k] for k in data.files}, source)
    if suffix == ".json":
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not valid JSON ({exc}).") from None
        return _opencv_keys(data, source)
    if suffix not in (".yaml", ".yml"):
        raise ValueError(f"{path}: calibration files are .yaml/.yml (DSEC, Kalibr), .json or .npz (K1, D1, K2, D2, "
                         f"R, T, resolution); got '{suffix}'.")
    size = path.stat().st_size
    if size > MAX_YAML_BYTES:
        raise ValueError(f"{path}: {size} bytes, more than a calibration file holds (at most {MAX_YAML_BYTES}); "
                         "is this the calibration file?")
    data = parse_calibration_yaml(path.read_bytes().decode("utf-8", errors="replace"), source=str(path))
    if isinstance(data, dict) and "intrinsics" in data and "extrinsics" in data:
        return _dsec(data, source)
    if isinstance(data, dict) and "cam0" in data and "cam1" in data:
        return _kalibr(data, source)
    if isinstance(data, dict) and "K1" in data:
        return _opencv_keys(data, source)
    keys = ", ".join(map(str, data)) if isinstance(data, dict) else type(data).__name__
    raise ValueError(f"{path}: not a known calibration layout (DSEC: intrinsics/extrinsics; Kalibr: cam0/cam1; "
                     f"OpenCV: K1, D1, K2, D2, R, T); its top level has {keys}.")


class _CalibrationLoader(yaml.SafeLoader):
    """PyYAML's safe loader, plus OpenCV's ``!!opencv-matrix`` tag (read as the plain mapping under it), with
    YAML 1.2's booleans: only ``true``/``false`` (any case), so that ``on``, ``off``, ``yes``, ``no`` stay text
    (YAML 1.1 reads a key ``on`` as True)."""

    yaml_implicit_resolvers: ClassVar[dict] = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:bool"]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}


_CalibrationLoader.add_implicit_resolver("tag:yaml.org,2002:bool",
                                         re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF"))
_CalibrationLoader.add_constructor("tag:yaml.org,2002:opencv-matrix",
                                   lambda loader, node: loader.construct_mapping(node, deep=True))


def parse_calibration_yaml(text: str, *, source: str = "<yaml>"):
    """Parse a calibration file's YAML with PyYAML's safe loader (no Python objects are ever built).

    OpenCV's files start with ``%YAML:1.0`` (a colon where YAML wants a space) and tag matrices
    ``!!opencv-matrix``: both are accepted, the tagged mapping is returned as it is.

    Raises
    ------
    ValueError
        Not valid YAML; the message names ``source`` and the line.

    Examples
    --------
    >>> parse_calibration_yaml("%YAML:1.0\\n---\\nM: !!opencv-matrix\\n   rows: 1\\n   data: [ 1., 2. ]\\n")
    {'M': {'rows': 1, 'data': [1.0, 2.0]}}
    """
    if text.startswith("%YAML:"):
        text = "%YAML " + text[len("%YAML:"):]
    try:
        return yaml.load(text, Loader=_CalibrationLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ValueError(f"{source}: not valid YAML{where} ({problem}).") from None
