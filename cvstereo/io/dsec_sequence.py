"""A DSEC sequence folder as one stereo input, its ground-truth disparity maps, and DSEC's disparity PNGs.

The layout follows DSEC's public description (dsec.ifi.uzh.ch "Data Format" and "Disparity Submission
Format", and the README of the uzh-rpg/DSEC repository); a sequence folder ``NAME/`` holds

- ``events/left/events.h5`` and ``events/right/events.h5``: the event files (:mod:`cvstereo.io.hdf5`);
- ``calibration/cam_to_cam.yaml`` (optional): the calibration, with DSEC's rectification
  (:func:`cvstereo.geometry.calibration.load_calibration`);
- ``disparity/event/*.png`` and ``disparity/timestamps.txt`` (training sequences only): the ground-truth
  disparity maps in the *rectified* left event camera's frame, 16-bit PNGs holding ``disparity * 256`` (0: no
  ground truth at that pixel), one per line of ``timestamps.txt`` (microseconds, the events' clock), the
  files in name order matching the lines in order.

The sequence's name is the folder's name. :func:`write_disparity_png` writes DSEC's submission format (the same
16-bit encoding); :func:`read_disparity_png` reads either.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io.files import printable

__all__ = ["CALIBRATION_FILE", "DISPARITY_FOLDER", "DISPARITY_SCALE", "EVENT_FILES", "MAX_PNG_DISPARITY",
           "TIMESTAMPS_FILE", "DsecSequence", "find_dsec_sequence", "is_dsec_sequence", "read_disparity_png",
           "read_timestamps", "recording_name", "write_disparity_png"]

#: The event files of a sequence, left then right, relative to its folder.
EVENT_FILES = ("events/left/events.h5", "events/right/events.h5")
CALIBRATION_FILE = "calibration/cam_to_cam.yaml"
DISPARITY_FOLDER = "disparity/event"
TIMESTAMPS_FILE = "disparity/timestamps.txt"
#: A PNG value is the disparity times this (DSEC's and KITTI's encoding); 0 means "no disparity here".
DISPARITY_SCALE = 256
#: The largest disparity a 16-bit PNG holds, px.
MAX_PNG_DISPARITY = 65535 / DISPARITY_SCALE


@dataclass(frozen=True)
class DsecSequence:
    """The files of one DSEC sequence folder (see the module doc).

    Attributes
    ----------
    root : Path
    name : str
        The folder's name (``zurich_city_01_a``).
    left, right : Path
        The event files.
    calibration : Path or None
        ``calibration/cam_to_cam.yaml`` where present.
    disparity : list of (int, Path)
        The ground-truth maps with their timestamps (us), in time order; empty for a test sequence.
    """

    root: Path
    name: str
    left: Path
    right: Path
    calibration: Path | None
    disparity: list[tuple[int, Path]]

    def files(self) -> list[Path]:
        """Every file the sequence's readers open (the inputs an output plan checks)."""
        extra = [self.calibration] if self.calibration is not None else []
        truth = [self.root / TIMESTAMPS_FILE, *(p for _, p in self.disparity)] if self.disparity else []
        return [self.left, self.right, *extra, *truth]


def recording_name(path: str | os.PathLike) -> str:
    """The name to show for a recording: a folder's name; for a DSEC ``NAME/events/left/events.h5`` the
    sequence's ``NAME`` (every DSEC event file is called ``events``); else the file name without extension.

    >>> recording_name("zurich_city_01_a/events/left/events.h5"), recording_name("arm50.npz")
    ('zurich_city_01_a', 'arm50')
    """
    path = Path(path)
    if path.is_dir():
        return path.resolve().name
    parts = path.parts
    if len(parts) >= 4 and parts[-3] == "events" and os.path.join(*parts[-3:]) in EVENT_FILES:
        return parts[-4]
    return path.stem


def is_dsec_sequence(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder holding a DSEC sequence's ``events/left`` or ``events/right`` folder."""
    path = Path(path)
    return path.is_dir() and any((path / f).parent.is_dir() for f in EVENT_FILES)


def find_dsec_sequence(path: str | os.PathLike) -> DsecSequence:
    """The files of the DSEC sequence folder ``path``, checked to be there and to agree with each other.

    Raises
    ------
    FileNotFoundError
        An event file is missing (named, with the layout expected).
    CorruptFileError
        ``disparity/`` is there but its PNGs and ``timestamps.txt`` do not pair up (one of them missing, counts
        that differ, timestamps that are not increasing integers).
    """
    root = Path(path)
    left, right = (root / f for f in EVENT_FILES)
    for f in (left, right):
        if not f.is_file():
            raise FileNotFoundError(f"{root}: no {f.relative_to(root)}; a DSEC sequence folder holds "
                                    f"{' and '.join(EVENT_FILES)} (as DSEC's downloads unpack).")
    calibration = root / CALIBRATION_FILE
    return DsecSequence(root, root.resolve().name, left, right, calibration if calibration.is_file() else None,
                        _ground_truth(root))


def _ground_truth(root: Path) -> list[tuple[int, Path]]:
    folder, stamps = root / DISPARITY_FOLDER, root / TIMESTAMPS_FILE
    if not folder.exists() and not stamps.exists():
        return []
    if not folder.is_dir():
        raise CorruptFileError(f"{root}: has {TIMESTAMPS_FILE} but no {DISPARITY_FOLDER}/ folder of PNGs; restore "
                               "it from DSEC's train_disparity download, or remove disparity/ (no ground truth).")
    pngs = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".png")
    if not stamps.is_file():
        raise CorruptFileError(f"{root}: {DISPARITY_FOLDER}/ has {len(pngs)} PNGs but there is no {TIMESTAMPS_FILE} "
                               "(one timestamp per PNG); restore it from DSEC's train_disparity download.")
    times, _ = read_timestamps(stamps)
    if times.size != len(pngs):
        raise CorruptFileError(f"{stamps}: {times.size} timestamps for {len(pngs)} PNGs in {DISPARITY_FOLDER}/; "
                               "DSEC pairs them one to one, in order: restore the missing files.")
    return list(zip(times.tolist(), pngs, strict=True))


def read_timestamps(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray | None]:
    """The integer microseconds of a DSEC timestamps file, one per line, checked to increase; and the file
    indices where the lines have them.

    ``disparity/timestamps.txt`` has one column; the CSV files of DSEC's test timestamps
    (``test_disparity_timestamps``) have two, ``timestamp_us, file_index``. ``#`` lines are comments.

    Returns
    -------
    times : (N,) int64 ndarray
    file_index : (N,) int64 ndarray or None
        None for a one-column file.

    Raises
    ------
    CorruptFileError
        A line that is not integers, a column count that changes, or a timestamp not after the one before (the
        line named).
    """
    rows, width = [], None
    for number, line in enumerate(Path(path).read_text(errors="replace").splitlines(), start=1):
        cells = [c.strip() for c in line.split(",")]
        if not cells[0] or cells[0].startswith("#"):
            continue
        try:
            row = [int(c) for c in cells]
        except ValueError:
            raise CorruptFileError(f"{path}: line {number} is {printable(line[:60])!r}, not a timestamp in integer "
                                   "microseconds (and a file index).") from None
        if width is not None and len(row) != width:
            raise CorruptFileError(f"{path}: line {number} has {len(row)} columns, the lines before {width}.")
        width = len(row)
        if rows and row[0] <= rows[-1][0]:
            raise CorruptFileError(f"{path}: line {number}: timestamp {row[0]} is not after the one before "
                                   f"({rows[-1][0]}); the timestamps increase, one per disparity map.")
        rows.append(row)
    table = np.asarray(rows, dtype=np.int64).reshape(len(rows), width or 1)
    return table[:, 0], (table[:, 1] if table.shape[1] > 1 else None)


def read_disparity_png(path: str | os.PathLike, *, resolution: tuple[int, int] | None = None) -> np.ndarray:
    """A DSEC (KITTI) disparity PNG as float32 disparities, px: ``value / 256``, NaN where the value is 0.

    Raises
    ------
    CorruptFileError
        Not a readable PNG, not one 16-bit channel, or (given ``resolution``) another size.
    """
    import cv2

    image = cv2.imread(os.fspath(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise CorruptFileError(f"{path}: not a readable PNG image; DSEC's disparity maps are 16-bit PNGs.")
    if image.dtype != np.uint16 or image.ndim != 2:
        raise CorruptFileError(f"{path}: a {image.dtype} image of shape {image.shape}; DSEC's disparity maps are "
                               "one-channel 16-bit PNGs (disparity x 256).")
    if resolution is not None and image.shape != (resolution[1], resolution[0]):
        raise CorruptFileError(f"{path}: {image.shape[1]}x{image.shape[0]} pixels; the sequence's sensor is "
                               f"{resolution[0]}x{resolution[1]}.")
    out = image.astype(np.float32) / DISPARITY_SCALE
    out[image == 0] = np.nan
    return out


def write_disparity_png(path: str | os.PathLike, disparity: np.ndarray) -> None:
    """Write a disparity image in DSEC's format: a 16-bit PNG of ``round(d * 256)``, 0 where ``d`` is NaN.

    Written atomically (inside an output plan, into its temporary file). A disparity of 0 or below cannot be
    told from "no answer" in this format and is written as 0, as DSEC's own maps have none.

    Raises
    ------
    ValueError
        A disparity above :data:`MAX_PNG_DISPARITY` (it would wrap or clip): the first such pixel named.
    """
    import cv2

    from cvstereo.io.atomic import atomic_path

    d = np.asarray(disparity, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"{path}: a disparity image is 2-D (height, width), got shape {d.shape}.")
    too_big = np.isfinite(d) & (d > MAX_PNG_DISPARITY) | np.isposinf(d)
    if too_big.any():
        y, x = (int(v[0]) for v in np.nonzero(too_big))
        raise ValueError(f"{path}: disparity {d[y, x]:g} px at pixel ({x}, {y}) exceeds {MAX_PNG_DISPARITY:g}, the "
                         "most a 16-bit PNG of disparity x 256 holds.")
    values = np.where(np.isfinite(d) & (d > 0), np.rint(np.nan_to_num(d) * DISPARITY_SCALE), 0).astype(np.uint16)
    ok, encoded = cv2.imencode(".png", values)  # encoded here: the temporary file's name need not end in .png
    if not ok:
        raise OSError(f"{path}: OpenCV could not encode the PNG.")
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(encoded.tobytes())
