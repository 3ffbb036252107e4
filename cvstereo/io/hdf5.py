"""HDF5 event datasets (the ``hdf5`` extra: h5py, and hdf5plugin for DSEC's compression): DSEC and MVSEC.

DSEC (``dsec``; one file per camera, ``events/left/events.h5`` and ``events/right/events.h5``, 640x480):

- ``/events/x``, ``/events/y`` (uint16), ``/events/t`` (uint32 us, relative), ``/events/p`` (0/1, 1 = ON);
- ``/t_offset``: int64 us added to every ``t`` (the absolute time);
- ``/ms_to_idx``: ``ms_to_idx[k]`` is the index of the first event with ``t >= 1000 k`` (relative time).

MVSEC (``mvsec``; both cameras in one ``*_data.hdf5`` file, 346x260): ``/davis/left/events`` and
``/davis/right/events``, (N, 4) float64 rows ``x, y, t, p`` with t in seconds and p in -1/+1. Times become
whole microseconds (``round(t * 1e6)``: the float64 seconds of a ROS clock resolve 0.25 us).

Both are streamed: DSEC by time slices of ``chunk_ms`` milliseconds cut with ``ms_to_idx`` (files are
gigabytes); MVSEC by blocks of rows. :func:`read_time_slice` reads only the events of one time window.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.events import make_events
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.recording import CAMERAS

DSEC_RESOLUTION = (640, 480)
MVSEC_RESOLUTION = (346, 260)
#: DSEC chunk length, milliseconds.
CHUNK_MS = 50
#: MVSEC chunk length, rows.
CHUNK_ROWS = 1 << 18
_DSEC_FIELDS = ("x", "y", "t", "p")


def _h5py():
    try:
        import h5py
        import hdf5plugin  # noqa: F401 -- registers the compression filters DSEC files use (Blosc, Zstd)
    except ImportError as exc:
        raise ImportError("reading HDF5 event files needs h5py and hdf5plugin: pip install 'cvstereo[hdf5]'") from exc
    return h5py


def _open(path):
    h5py = _h5py()
    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file.") from None
    except OSError as exc:
        raise CorruptFileError(f"{path}: not a readable HDF5 file ({exc}).") from None


def hdf5_layout(path: str | os.PathLike) -> str:
    """``"dsec"`` or ``"mvsec"``: which layout an HDF5 file has.

    Raises
    ------
    CorruptFileError
        Neither ``/events/{x,y,t,p}`` nor ``/davis/{left,right}/events``.
    """
    with _open(path) as f:
        if "events" in f and all(k in f["events"] for k in _DSEC_FIELDS):
            return "dsec"
        if "davis" in f and any(f"{cam}/events" in f["davis"] for cam in CAMERAS):
            return "mvsec"
        raise CorruptFileError(f"{path}: neither the DSEC layout (/events/x, y, t, p) nor MVSEC's "
                               f"(/davis/left/events); top-level keys: {', '.join(f.keys()) or 'none'}.")


def _dsec_header(path) -> tuple[int, int, np.ndarray | None]:
    with _open(path) as f:
        if "events" not in f or not all(k in f["events"] for k in _DSEC_FIELDS):
            raise CorruptFileError(f"{path}: not a DSEC event file (needs /events/x, /events/y, /events/t, "
                                   "/events/p).")
        sizes = {k: f["events"][k].shape[0] for k in _DSEC_FIELDS}
        if len(set(sizes.values())) != 1:
            raise CorruptFileError(f"{path}: /events/x, y, t, p have different lengths {sizes}.")
        t_offset = int(f["t_offset"][()]) if "t_offset" in f else 0
        ms_to_idx = np.asarray(f["ms_to_idx"][()], np.int64) if "ms_to_idx" in f else None
    return sizes["x"], t_offset, ms_to_idx


def _dsec_bounds(path, n: int, ms_to_idx: np.ndarray | None, chunk_ms: int) -> list[int]:
    if ms_to_idx is None:  # without the index: blocks of rows (still time-ordered)
        return [*range(0, n, CHUNK_ROWS), n]
    return [*(int(i) for i in ms_to_idx[::chunk_ms] if i < n), n]


def _dsec_rows(f, lo: int, hi: int, t_offset: int) -> np.ndarray:
    ev = f["events"]
    return make_events(ev["t"][lo:hi].astype(np.int64) + t_offset, ev["x"][lo:hi], ev["y"][lo:hi],
                       ev["p"][lo:hi].astype(np.int8))


def _dsec_chunks(path, label: str, resolution, chunk_ms: int) -> Iterator[Chunk]:
    n, t_offset, ms_to_idx = _dsec_header(path)
    bounds = _dsec_bounds(path, n, ms_to_idx, chunk_ms)
    check = ChunkChecker(resolution=resolution, source=f"{path} [{label}]")
    with _open(path) as f:
        for lo, hi in itertools.pairwise(bounds):
            if hi > lo:
                yield check(_dsec_rows(f, lo, hi, t_offset)), None


def _mvsec_rows(data: np.ndarray) -> np.ndarray:
    return make_events(np.round(data[:, 2] * 1e6).astype(np.int64), data[:, 0].astype(np.int64),
                       data[:, 1].astype(np.int64), (data[:, 3] > 0).astype(np.int8))


def _mvsec_dataset(f, path, camera: str):
    key = f"davis/{camera}/events"
    if key not in f:
        raise CorruptFileError(f"{path}: no /{key} in this MVSEC file.")
    ds = f[key]
    if ds.ndim != 2 or ds.shape[1] < 4:
        raise CorruptFileError(f"{path}: /{key} has shape {ds.shape}; MVSEC events are (N, 4): x, y, t, p.")
    return ds


def _mvsec_chunks(path, camera: str, resolution) -> Iterator[Chunk]:
    check = ChunkChecker(resolution=resolution, source=f"{path} [/davis/{camera}/events]")
    with _open(path) as f:
        ds = _mvsec_dataset(f, path, camera)
        for lo in range(0, ds.shape[0], CHUNK_ROWS):
            data = ds[lo:lo + CHUNK_ROWS]
            _check_mvsec_values(data, path, camera, lo)
            yield check(_mvsec_rows(data)), None


def _check_mvsec_values(data: np.ndarray, path, camera: str, offset: int) -> None:
    whole = np.isfinite(data[:, :2]).all(axis=1) & (data[:, :2] == np.round(data[:, :2])).all(axis=1)
    whole &= np.isfinite(data[:, 2]) & np.isin(data[:, 3], (-1.0, 1.0, 0.0))
    bad = np.flatnonzero(~whole)
    if bad.size:
        i = int(bad[0])
        raise CorruptFileError(f"{path}: /davis/{camera}/events row {offset + i} is {data[i, :4].tolist()}; "
                               "MVSEC rows are whole-pixel x, y, finite t (s) and p -1/+1.")


def open_dsec(path: str | os.PathLike, right: str | os.PathLike | None = None, *,
              resolution: tuple[int, int] | None = None, chunk_ms: int = CHUNK_MS) -> RecordingStream:
    """Open DSEC event files (left and right, or one camera alone) for streaming.

    Parameters
    ----------
    path : path-like
        The left camera's ``events.h5`` (or a single camera's).
    right : path-like, optional
        The right camera's ``events.h5``.
    resolution : (width, height), optional, keyword-only
        Default 640x480.
    chunk_ms : int, keyword-only
        Length of the time slices read at once.

    Returns
    -------
    RecordingStream
        Absolute times (``t + t_offset``), us.
    """
    files = (os.fspath(path),) + (() if right is None else (os.fspath(right),))
    for f in files:
        _dsec_header(f)  # fail now, not at the first packet
    res = tuple(resolution) if resolution is not None else DSEC_RESOLUTION
    cameras = CAMERAS if right is not None else (MONO,)
    by_camera = dict(zip(cameras, files, strict=True))
    meta = {"source": list(files), "format": "dsec"}
    return RecordingStream("dsec", files, cameras, res, meta, False,
                           lambda camera: _dsec_chunks(by_camera[camera], camera, res, chunk_ms))


def open_mvsec(path: str | os.PathLike, *, resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open an MVSEC ``*_data.hdf5`` file (both DAVIS cameras) for streaming.

    Parameters
    ----------
    path : path-like
    resolution : (width, height), optional, keyword-only
        Default 346x260.

    Returns
    -------
    RecordingStream
        Microseconds, ``round(t * 1e6)`` of MVSEC's seconds.
    """
    path = os.fspath(path)
    with _open(path) as f:
        present = tuple(cam for cam in CAMERAS if f"davis/{cam}/events" in f)
        for cam in present:
            _mvsec_dataset(f, path, cam)
    if not present:
        raise CorruptFileError(f"{path}: no /davis/left/events or /davis/right/events: not an MVSEC data file.")
    res = tuple(resolution) if resolution is not None else MVSEC_RESOLUTION
    cameras = CAMERAS if present == CAMERAS else (MONO,)
    by_camera = dict(zip(cameras, present, strict=True))
    meta = {"source": [path], "format": "mvsec", "cameras": dict(by_camera)}
    return RecordingStream("mvsec", (path,), cameras, res, meta, False,
                           lambda camera: _mvsec_chunks(path, by_camera[camera], res))


def dsec_time_range(path: str | os.PathLike) -> tuple[int, int] | None:
    """Absolute time of the first and the last event of a DSEC ``events.h5`` (us), or None when it has none."""
    n, t_offset, _ = _dsec_header(path)
    if n == 0:
        return None
    with _open(path) as f:
        t = f["events"]["t"]
        return int(t[0]) + t_offset, int(t[n - 1]) + t_offset


def read_time_slice(path: str | os.PathLike, t_start: int, t_stop: int, *, camera: str = "left") -> np.ndarray:
    """The events with ``t_start <= t < t_stop`` (absolute us) of one camera, reading only that window.

    Parameters
    ----------
    path : path-like
        A DSEC ``events.h5`` (``camera`` is ignored: one camera per file) or an MVSEC data file.
    t_start, t_stop : int
        Absolute times, us.
    camera : {"left", "right"}, keyword-only
        MVSEC: which camera.

    Returns
    -------
    (N,) ndarray of EVENT_DTYPE
        Unvalidated beyond the conversion; use the streams for checked reading.
    """
    if hdf5_layout(path) == "dsec":
        n, t_offset, ms_to_idx = _dsec_header(path)
        with _open(path) as f:
            t = f["events"]["t"]
            lo, hi = (_bisect(lambda i: int(t[i]) + t_offset, n, v, ms_to_idx, t_offset) for v in (t_start, t_stop))
            return _dsec_rows(f, lo, hi, t_offset)
    with _open(path) as f:
        ds = _mvsec_dataset(f, path, camera)
        lo, hi = (_bisect(lambda i: round(float(ds[i, 2]) * 1e6), ds.shape[0], v) for v in (t_start, t_stop))
        return _mvsec_rows(ds[lo:hi])


def _bisect(time_at, n: int, target: int, ms_to_idx: np.ndarray | None = None, t_offset: int = 0) -> int:
    """First index whose time is >= target, reading O(log n) single values (narrowed by ms_to_idx)."""
    lo, hi = 0, n
    if ms_to_idx is not None and ms_to_idx.size:
        ms = (target - t_offset) // 1000
        if ms < 0:
            return 0
        lo = int(ms_to_idx[min(ms, ms_to_idx.size - 1)]) if ms < ms_to_idx.size else int(ms_to_idx[-1])
        hi = int(ms_to_idx[ms + 1]) if ms + 1 < ms_to_idx.size else n
        lo, hi = min(lo, n), min(max(hi, lo), n)
    while lo < hi:
        mid = (lo + hi) // 2
        if time_at(mid) < target:
            lo = mid + 1
        else:
            hi = mid
    return lo
