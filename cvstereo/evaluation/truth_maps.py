"""Where a recording's ground-truth disparity maps are: a DSEC sequence folder's, or the ``*_gt.hdf5`` beside an
MVSEC data file; with the calibration that maps the matches onto their rectified left frame.

:func:`truth_maps_for` finds them for `cvstereo evaluate` (scored by :func:`cvstereo.evaluation.dense_truth.score_maps`)
and `cvstereo export-dsec` (their times and names).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["TruthMaps", "truth_maps_for"]


@dataclass(frozen=True)
class TruthMaps:
    """A sequence's ground-truth disparity maps, read lazily.

    Attributes
    ----------
    what : str
        For the output: ``DSEC ground truth of zurich_city_01_a: 12 disparity maps``.
    times : list of int or None
        The maps' times, us (the events' clock); for a DSEC test sequence empty; None: not listed (MVSEC).
    names : list of str
        The maps' file names (DSEC: ``000020.png``), one per time.
    read : callable
        ``read() -> iterator of (time us, float32 (H, W) disparities, NaN where none)``.
    resolution : (width, height)
    rectification : cvstereo.geometry.rectify.Rectification
        Maps the matches' raw pixels to the rectified left frame of the maps.
    files : list of Path
        The files read (inputs of the command's output plan).
    """

    what: str
    times: list[int] | None
    names: list[str]
    read: Callable[[], Iterator]
    resolution: tuple[int, int]
    rectification: object
    files: list[Path]


def truth_maps_for(recording: str | os.PathLike, *, truth: str | os.PathLike | None = None,
                   calibration: str | os.PathLike | None = None) -> TruthMaps | None:
    """The ground-truth maps of ``recording`` (a DSEC sequence folder or an MVSEC data file), or None for other
    inputs.

    Parameters
    ----------
    recording : path-like
    truth : path-like, optional, keyword-only
        MVSEC's ground-truth file; default ``NAME_gt.hdf5`` beside ``NAME_data.hdf5``.
    calibration : path-like, optional, keyword-only
        Default: a DSEC sequence's ``calibration/cam_to_cam.yaml``; MVSEC needs one (its camchain file).

    Raises
    ------
    FileNotFoundError
        No calibration, or MVSEC's ground-truth file missing (said with what to give).
    ValueError
        ``truth`` given for a DSEC sequence (its maps are inside it); the files disagree (see the readers).
    """
    from cvstereo.io.dsec_sequence import is_dsec_sequence

    if is_dsec_sequence(recording):
        if truth is not None:
            raise ValueError(f"--truth {truth}: a DSEC sequence's ground truth is its disparity/ folder; give no "
                             "--truth for it.")
        return _dsec(recording, calibration)
    if Path(recording).suffix.lower() in (".h5", ".hdf5") and os.path.isfile(recording):
        from cvstereo.io.hdf5 import hdf5_layout

        if hdf5_layout(recording) == "mvsec":
            return _mvsec(recording, truth, calibration)
    if truth is not None:
        raise ValueError(f"--truth {truth}: only MVSEC data files take a ground-truth file; {recording} is not one.")
    return None


def _rectification(path, source: str):
    from cvstereo.geometry.calibration import load_calibration
    from cvstereo.geometry.rectify import Rectification

    if path is None:
        raise FileNotFoundError(f"{source}: no calibration to bring the matches into the ground truth's rectified "
                                "left frame; give --calibration FILE (DSEC cam_to_cam.yaml, MVSEC's Kalibr camchain).")
    return Rectification(load_calibration(path))


def _dsec(folder, calibration) -> TruthMaps:
    from cvstereo.io.dsec_sequence import find_dsec_sequence, read_disparity_png

    seq = find_dsec_sequence(folder)
    cal = calibration if calibration is not None else seq.calibration
    rect = _rectification(cal, os.fspath(folder))
    resolution = rect.resolution

    def read() -> Iterator:
        return ((ts, read_disparity_png(p, resolution=resolution)) for ts, p in seq.disparity)

    files = [Path(cal), *(f for f in seq.files() if f not in (seq.left, seq.right, seq.calibration))]
    return TruthMaps(f"DSEC ground truth of {seq.name}: {len(seq.disparity)} disparity maps",
                     [ts for ts, _ in seq.disparity], [p.name for _, p in seq.disparity], read, resolution, rect,
                     files)


def _mvsec(data_file, truth, calibration) -> TruthMaps:
    from cvstereo.io.mvsec_truth import mvsec_disparity_maps, mvsec_map_count, mvsec_truth_file

    gt = Path(truth) if truth is not None else mvsec_truth_file(data_file)
    if not gt.is_file():
        raise FileNotFoundError(f"{gt}: no such MVSEC ground-truth file (MVSEC ships NAME_gt.hdf5 beside "
                                "NAME_data.hdf5); give it with --truth FILE.")
    rect = _rectification(calibration, os.fspath(data_file))
    n = mvsec_map_count(gt, rect.resolution)

    def read() -> Iterator:
        return mvsec_disparity_maps(gt, rect.calibration)

    return TruthMaps(f"MVSEC ground truth {gt.name}: {n} depth maps as disparities", None, [], read, rect.resolution,
                     rect, [gt, Path(calibration)])
