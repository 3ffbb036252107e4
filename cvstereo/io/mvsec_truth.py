"""MVSEC's ground-truth depth as disparity maps, to be scored as DSEC's are (:mod:`cvstereo.evaluation.dense_truth`).

MVSEC (Zhu et al. 2018; its public description on daniilidis-group.github.io/mvsec) ships, beside each
``NAME_data.hdf5``, a ``NAME_gt.hdf5`` holding

- ``/davis/left/depth_image_rect``: (N, 260, 346) float depth maps in metres in the *rectified* left DAVIS frame,
  NaN (or inf, or 0) where there is no depth;
- ``/davis/left/depth_image_rect_ts``: (N,) float64 times in seconds, the events' clock.

A depth Z becomes the disparity of the rectified pair, ``d = a / Z - c`` (the calibration's depth model:
``a`` = rectified focal length x baseline; :meth:`~cvstereo.geometry.calibration.StereoCalibration.depth_model`),
so that MVSEC is scored with DSEC's metrics in pixels. The calibration is MVSEC's Kalibr camchain file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.model.columns import times_to_us

__all__ = ["DEPTH_KEY", "DEPTH_TIMES_KEY", "mvsec_disparity_maps", "mvsec_map_count", "mvsec_truth_file"]

DEPTH_KEY = "davis/left/depth_image_rect"
DEPTH_TIMES_KEY = "davis/left/depth_image_rect_ts"


def mvsec_truth_file(data_file: str | os.PathLike) -> Path:
    """The ground-truth file MVSEC ships beside a data file: ``NAME_data.hdf5`` -> ``NAME_gt.hdf5``."""
    data_file = Path(data_file)
    stem = data_file.stem[:-len("_data")] if data_file.stem.endswith("_data") else data_file.stem
    return data_file.with_name(f"{stem}_gt{data_file.suffix}")


def _datasets(f, path, resolution: tuple[int, int]):
    """The depth maps and their times, checked: datasets of numbers, one (height, width) map per time."""
    from cvstereo.io._hdf5_datasets import numeric_dataset

    w, h = resolution
    depth = numeric_dataset(f, path, DEPTH_KEY, ndim=3, holds="depth maps in metres, (N, height, width)")
    times = numeric_dataset(f, path, DEPTH_TIMES_KEY, ndim=1, holds="the depth maps' times in seconds")
    if depth.shape[0] != times.shape[0] or depth.shape[1:] != (h, w):
        raise CorruptFileError(f"{path}: /{DEPTH_KEY} has shape {depth.shape} and /{DEPTH_TIMES_KEY} "
                               f"{times.shape}; one {h}x{w} map per time is expected (the calibration's sensor).")
    return depth, times


def mvsec_map_count(path: str | os.PathLike, resolution: tuple[int, int]) -> int:
    """How many depth maps an MVSEC ``*_gt.hdf5`` holds, its datasets checked (as :func:`mvsec_disparity_maps`
    checks them) before any event is read."""
    from cvstereo.io.hdf5 import _open

    with _open(path) as f:
        return _datasets(f, path, resolution)[1].shape[0]


def mvsec_disparity_maps(path: str | os.PathLike, calibration) -> Iterator[tuple[int, np.ndarray]]:
    """Each ground-truth depth map of an MVSEC ``*_gt.hdf5`` as ``(time us, disparity float32 (H, W))``, NaN
    where there is no depth; read one map at a time.

    Raises
    ------
    CorruptFileError
        The datasets are missing or of another shape; times that are not increasing.
    """
    from cvstereo.io._hdf5_datasets import read_rows
    from cvstereo.io.hdf5 import _open

    model = calibration.depth_model()
    with _open(path) as f:
        depth, times = _datasets(f, path, calibration.resolution)
        t_us = times_to_us(read_rows(times, path, DEPTH_TIMES_KEY, 0, times.shape[0]), "s",
                           label=f"/{DEPTH_TIMES_KEY}", source=os.fspath(path))
        back = np.flatnonzero(np.diff(t_us) <= 0)
        if back.size:
            raise CorruptFileError(f"{path}: /{DEPTH_TIMES_KEY} at index {back[0] + 1} is not after the time before "
                                   "it; the maps' times increase.")
        for i, ts in enumerate(t_us.tolist()):
            z = read_rows(depth, path, DEPTH_KEY, i, i + 1)[0].astype(np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                d = np.where(np.isfinite(z) & (z > 0), model.a / z - model.c, np.nan)
            yield int(ts), d.astype(np.float32)
