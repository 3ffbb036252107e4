"""HDF5 event datasets (the ``hdf5`` extra: h5py, and hdf5plugin for DSEC's compression): DSEC, MVSEC and M3ED.

DSEC (``dsec``; one file per camera, ``events/left/events.h5`` and ``events/right/events.h5``, 640x480):

- ``/events/x``, ``/events/y`` (uint16), ``/events/t`` (uint32 us, relative), ``/events/p`` (0/1, 1 = ON);
- ``/t_offset``: int64 us added to every ``t`` (the absolute time);
- ``/ms_to_idx``: ``ms_to_idx[k]`` is the index of the first event with ``t >= 1000 k`` (relative time).

MVSEC (``mvsec``; both cameras in one ``*_data.hdf5`` file, 346x260): ``/davis/left/events`` and
``/davis/right/events``, (N, 4) float64 rows ``x, y, t, p`` with t in seconds and p in -1/+1. Times become
whole microseconds (``round(t * 1e6)``: the float64 seconds of a ROS clock resolve 0.25 us).

M3ED (``m3ed``; both Prophesee cameras in one ``*_data.h5``, 1280x720): ``/prophesee/{left,right}/{x,y,t,p}``
with ``ms_map_idx`` beside them, read as DSEC's (:func:`open_m3ed`).

Both are streamed: DSEC by time slices of ``chunk_ms`` milliseconds cut with ``ms_to_idx`` (files are
gigabytes), never more than :data:`CHUNK_ROWS` events at once; MVSEC by blocks of rows.
:func:`read_time_slice` reads only the events of one time window.

Values are checked as stored, chunk by chunk, before any cast (:mod:`cvstereo.model.columns`): a float ``t`` (whose
unit cannot be told), coordinates beyond the sensor or int16 (65541 is not read as 5, 65535 not as -1),
polarities other than 0/1 or -1/+1 (256 is not read as OFF), times beyond int64 (a uint64 2**63, MVSEC's 1e300 s)
and an index table that decreases or points outside the data are refused with the file, the dataset and the
first bad index named, so that no event is silently moved or dropped.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io._hdf5_datasets import check_index_block, h5py_module, integer_scalar, numeric_dataset, read_rows
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.columns import check_times, times_to_us, whole_numbers
from cvstereo.model.recording import CAMERAS

__all__ = ["CHUNK_MS", "CHUNK_ROWS", "DSEC_GROUP", "DSEC_RESOLUTION", "INDEX_BLOCK", "M3ED_GROUPS", "M3ED_RESOLUTION",
           "MVSEC_RESOLUTION", "dsec_time_range", "hdf5_layout", "open_dsec", "open_m3ed", "open_mvsec",
           "read_time_slice"]

DSEC_RESOLUTION = (640, 480)
MVSEC_RESOLUTION = (346, 260)
#: DSEC chunk length, milliseconds.
CHUNK_MS = 50
#: The most events read at once (MVSEC's blocks, and the cap on a DSEC time slice: a sparse or damaged index
#: must not make one slice the whole file).
CHUNK_ROWS = 1 << 18
#: Entries of DSEC's /ms_to_idx read and checked at once (an hour of recording has 3.6 million).
INDEX_BLOCK = 1 << 16
_DSEC_FIELDS = ("x", "y", "t", "p")
#: What each DSEC dataset holds, for the messages that refuse another kind.
_DSEC_HOLDS = {"x": "pixel columns (uint16)", "y": "pixel rows (uint16)", "p": "polarities 0/1",
               "t": "integer microseconds (uint32) relative to /t_offset"}


class _Group(NamedTuple):
    """Where one camera's DSEC-style datasets are: ``PREFIX/{x,y,t,p}``, the millisecond index, the time offset."""

    prefix: str
    index: str
    offset: str | None

    @property
    def labels(self) -> dict[str, str]:
        return {f: f"/{self.prefix}/{f}" for f in _DSEC_FIELDS}


DSEC_GROUP = _Group("events", "ms_to_idx", "t_offset")
#: M3ED (m3ed.io; the daniilidis-group/m3ed README and loaders): both Prophesee cameras in one ``*_data.h5``,
#: ``/prophesee/{left,right}/{x,y,t,p}`` (t int64 us) with ``ms_map_idx`` as DSEC's ``ms_to_idx``, no offset.
M3ED_GROUPS = {cam: _Group(f"prophesee/{cam}", f"prophesee/{cam}/ms_map_idx", None) for cam in CAMERAS}
M3ED_RESOLUTION = (1280, 720)
_DSEC_LABELS = DSEC_GROUP.labels
#: MVSEC's column order in /davis/CAMERA/events.
_MVSEC_COLUMNS = {"x": 0, "y": 1, "t": 2, "p": 3}


def _open(path):
    h5py = h5py_module()
    try:
        return h5py.File(path, "r")
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file.") from None
    except OSError as exc:
        raise CorruptFileError(f"{path}: not a readable HDF5 file ({exc}).") from None


def _is_dsec(f, g: _Group = DSEC_GROUP) -> bool:
    events = f.get(g.prefix)
    return isinstance(events, h5py_module().Group) and all(k in events for k in _DSEC_FIELDS)


def hdf5_layout(path: str | os.PathLike) -> str:
    """``"dsec"``, ``"mvsec"`` or ``"m3ed"``: which layout an HDF5 file has.

    Raises
    ------
    CorruptFileError
        None of ``/events/{x,y,t,p}``, ``/davis/{left,right}/events``, ``/prophesee/{left,right}/{x,y,t,p}``.
    """
    with _open(path) as f:
        if _is_dsec(f):
            return "dsec"
        davis = f.get("davis")
        if isinstance(davis, h5py_module().Group) and any(f"{cam}/events" in davis for cam in CAMERAS):
            return "mvsec"
        if any(_is_dsec(f, g) for g in M3ED_GROUPS.values()):
            return "m3ed"
        raise CorruptFileError(f"{path}: neither the DSEC layout (/events/x, y, t, p) nor MVSEC's "
                               f"(/davis/left/events) nor M3ED's (/prophesee/left/x, y, t, p); top-level keys: "
                               f"{', '.join(f.keys()) or 'none'}.")


def _dsec_header(path, g: _Group = DSEC_GROUP) -> tuple[int, int, int | None]:
    """(events, t_offset, length of the ms index or None), after checking every dataset's kind and shape."""
    labels = g.labels
    with _open(path) as f:
        if not _is_dsec(f, g):
            raise CorruptFileError(f"{path}: not a DSEC event file (needs {', '.join(labels.values())}).")
        datasets = {k: numeric_dataset(f, path, f"{g.prefix}/{k}", ndim=1, holds=_DSEC_HOLDS[k]) for k in _DSEC_FIELDS}
        if datasets["t"].dtype.kind == "f":
            raise CorruptFileError(
                f"{path}: {labels['t']} has dtype {datasets['t'].dtype}; DSEC stores t as {_DSEC_HOLDS['t']}, and "
                "the unit of float times (seconds? microseconds?) cannot be told from them: convert them to integer "
                "microseconds, e.g. np.round(t_seconds * 1e6).astype('uint32').")
        sizes = {k: ds.shape[0] for k, ds in datasets.items()}
        if len(set(sizes.values())) != 1:
            raise CorruptFileError(f"{path}: {', '.join(labels.values())} have different lengths {sizes}.")
        t_offset = 0
        if g.offset is not None and g.offset in f:
            t_offset = integer_scalar(f, path, g.offset, holds="the int64 microseconds added to every t")
        index = None
        if g.index in f:
            index = numeric_dataset(f, path, g.index, ndim=1, holds="event indices (integers)", integers=True)
            index = index.shape[0]
    return sizes["x"], t_offset, index


def _index_cuts(f, path, n: int, size: int, chunk_ms: int, g: _Group) -> Iterator[int]:
    """Every ``chunk_ms``-th entry of /ms_to_idx but zeros (the row ranges start at 0 anyway), each block of the
    table checked before it is used."""
    index, previous = f[g.index], None
    for lo in range(0, size, INDEX_BLOCK):
        block = read_rows(index, path, g.index, lo, lo + INDEX_BLOCK)
        previous = check_index_block(block, previous, n, path=path, key=g.index, index_offset=lo)
        first = -lo % chunk_ms  # the block's first entry at a multiple of chunk_ms
        yield from (int(v) for v in block[first::chunk_ms] if v > 0)


def _dsec_bounds(f, path, n: int, index_size: int | None, chunk_ms: int,
                 g: _Group = DSEC_GROUP) -> Iterator[tuple[int, int]]:
    """Row ranges that tile ``0..n`` in order: cut where the index says a slice begins, at most CHUNK_ROWS long.

    The ranges start at 0 and end at n whatever the index says, so that an index that is not DSEC's (its
    first entry not 0, entries missing at the end) still reads every event once; one that decreases or points
    outside the data is refused by :func:`check_index_block`.
    """
    cuts = _index_cuts(f, path, n, index_size, chunk_ms, g) if index_size else iter(())
    lo = 0
    for cut in itertools.chain(cuts, (n,)):
        while cut - lo > CHUNK_ROWS:
            yield lo, lo + CHUNK_ROWS
            lo += CHUNK_ROWS
        if cut > lo:
            yield lo, cut
            lo = cut


def _dsec_rows(f, path, lo: int, hi: int, t_offset: int, check: ChunkChecker,
               g: _Group = DSEC_GROUP) -> np.ndarray:
    """Rows ``lo:hi`` of a DSEC file as EVENT_DTYPE, every value checked as stored before the cast."""
    ev = f[g.prefix]
    raw = {k: read_rows(ev[k], path, f"{g.prefix}/{k}", lo, hi) for k in _DSEC_FIELDS}
    x, y, p = (whole_numbers(raw[k], label=g.labels[k], source=str(path), index_offset=lo) for k in "xyp")
    return check.columns(raw["t"], x, y, p, t_offset=t_offset)


def _dsec_chunks(path, resolution, chunk_ms: int, g: _Group = DSEC_GROUP) -> Iterator[Chunk]:
    n, t_offset, index_size = _dsec_header(path, g)
    check = ChunkChecker(resolution=resolution, source=str(path), labels=g.labels)
    with _open(path) as f:
        for lo, hi in _dsec_bounds(f, path, n, index_size, chunk_ms, g):
            yield _dsec_rows(f, path, lo, hi, t_offset, check, g), None


def _mvsec_dataset(f, path, camera: str):
    key = f"davis/{camera}/events"
    if key not in f:
        raise CorruptFileError(f"{path}: no /{key} in this MVSEC file.")
    ds = numeric_dataset(f, path, key, ndim=2, holds="rows of numbers x, y, t (s), p")
    if ds.shape[1] < 4:
        raise CorruptFileError(f"{path}: /{key} has shape {ds.shape}; MVSEC events are (N, 4): x, y, t, p.")
    return ds


def _mvsec_labels(camera: str) -> dict[str, str]:
    return {f: f"/davis/{camera}/events column {f}" for f in _MVSEC_COLUMNS}


def _mvsec_rows(data: np.ndarray, path, camera: str, lo: int, check: ChunkChecker) -> np.ndarray:
    """MVSEC rows (x, y, t in seconds, p) as EVENT_DTYPE: whole-pixel coordinates, times that fit int64 us."""
    labels = _mvsec_labels(camera)
    t = times_to_us(data[:, _MVSEC_COLUMNS["t"]], "s", label=labels["t"], source=str(path), index_offset=lo)
    x, y, p = (whole_numbers(data[:, _MVSEC_COLUMNS[k]], label=labels[k], source=str(path), index_offset=lo)
               for k in "xyp")
    return check.columns(t, x, y, p)


def _mvsec_chunks(path, camera: str, resolution) -> Iterator[Chunk]:
    check = ChunkChecker(resolution=resolution, source=str(path), labels=_mvsec_labels(camera))
    with _open(path) as f:
        ds = _mvsec_dataset(f, path, camera)
        for lo in range(0, ds.shape[0], CHUNK_ROWS):
            data = read_rows(ds, path, f"davis/{camera}/events", lo, lo + CHUNK_ROWS)
            yield _mvsec_rows(data, path, camera, lo, check), None


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
        Absolute times (``t + t_offset``), us. Each chunk is checked before it is cast; errors name the file,
        the dataset (``/events/x``, ``/ms_to_idx``, ...) and the first bad index.
    """
    files = (os.fspath(path),) + (() if right is None else (os.fspath(right),))
    for f in files:
        _dsec_header(f)  # fail now, not at the first packet
    res = tuple(resolution) if resolution is not None else DSEC_RESOLUTION
    cameras = CAMERAS if right is not None else (MONO,)
    by_camera = dict(zip(cameras, files, strict=True))
    meta = {"source": list(files), "format": "dsec"}
    return RecordingStream("dsec", files, cameras, res, meta, False,
                           lambda camera: _dsec_chunks(by_camera[camera], res, chunk_ms))


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
        Microseconds, ``round(t * 1e6)`` of MVSEC's seconds; rows are checked before they are cast.
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


def open_m3ed(path: str | os.PathLike, *, resolution: tuple[int, int] | None = None,
              chunk_ms: int = CHUNK_MS) -> RecordingStream:
    """Open an M3ED ``*_data.h5`` file (both Prophesee cameras, ``/prophesee/{left,right}``) for streaming.

    Parameters
    ----------
    path : path-like
    resolution : (width, height), optional, keyword-only
        Default 1280x720 (M3ED's Prophesee EVK4 cameras).
    chunk_ms : int, keyword-only

    Returns
    -------
    RecordingStream
        Microseconds as stored; read and checked as DSEC's files are (one camera alone: a one-camera stream).
    """
    path = os.fspath(path)
    with _open(path) as f:
        present = tuple(cam for cam in CAMERAS if _is_dsec(f, M3ED_GROUPS[cam]))
    if not present:
        raise CorruptFileError(f"{path}: no /prophesee/left or /prophesee/right with x, y, t, p: not an M3ED file.")
    for cam in present:
        _dsec_header(path, M3ED_GROUPS[cam])  # fail now, not at the first packet
    res = tuple(resolution) if resolution is not None else M3ED_RESOLUTION
    cameras = CAMERAS if present == CAMERAS else (MONO,)
    by_camera = dict(zip(cameras, present, strict=True))
    meta = {"source": [path], "format": "m3ed", "cameras": dict(by_camera)}
    return RecordingStream("m3ed", (path,), cameras, res, meta, False,
                           lambda camera: _dsec_chunks(path, res, chunk_ms, M3ED_GROUPS[by_camera[camera]]))


def dsec_time_range(path: str | os.PathLike) -> tuple[int, int] | None:
    """Absolute time of the first and the last event of a DSEC ``events.h5`` (us), or None when it has none."""
    n, t_offset, _ = _dsec_header(path)
    if n == 0:
        return None
    with _open(path) as f:
        t = f["events"]["t"]
        ends = np.concatenate([read_rows(t, path, "events/t", 0, 1), read_rows(t, path, "events/t", n - 1, n)])
    check_times(ends, t_offset=t_offset, source=str(path), label="/events/t (first and last)")
    return int(ends[0]) + t_offset, int(ends[1]) + t_offset


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
        The window's events, checked as the streams check them except against a sensor size (coordinates
        must fit int16); a file whose times go backwards outside the window is not noticed here.
    """
    if hdf5_layout(path) == "dsec":
        n, t_offset, index_size = _dsec_header(path)
        with _open(path) as f:
            t = f["events"]["t"]
            lo, hi = (_bisect(lambda i: int(t[i]) + t_offset, n, v, _dsec_narrowed(f, n, index_size, v - t_offset))
                      for v in (t_start, t_stop))
            check = ChunkChecker(resolution=None, source=str(path), labels=_DSEC_LABELS, start=lo)
            return _dsec_rows(f, path, lo, max(lo, hi), t_offset, check)
    with _open(path) as f:
        ds = _mvsec_dataset(f, path, camera)
        lo, hi = (_bisect(lambda i: float(ds[i, 2]) * 1e6, ds.shape[0], v, (0, ds.shape[0])) for v in (t_start, t_stop))
        check = ChunkChecker(resolution=None, source=str(path), labels=_mvsec_labels(camera), start=lo)
        return _mvsec_rows(read_rows(ds, path, f"davis/{camera}/events", lo, max(lo, hi)), path, camera, lo, check)


def _dsec_narrowed(f, n: int, index_size: int | None, relative_us: int) -> tuple[int, int]:
    """The rows /ms_to_idx says hold the millisecond of ``relative_us`` (two entries read), or all rows."""
    ms = relative_us // 1000
    if not index_size or ms < 0 or ms >= index_size:
        return 0, n
    index = f["ms_to_idx"]
    lo = int(index[ms])
    hi = int(index[ms + 1]) if ms + 1 < index_size else n
    return min(max(lo, 0), n), min(max(hi, lo, 0), n)


def _bisect(time_at, n: int, target, narrowed: tuple[int, int]) -> int:
    """First index whose time is >= target, reading O(log n) single values within ``narrowed``.

    The narrowed range is used only where it brackets the target (the time before it is earlier, the time at
    its end is not), so that a damaged index cannot pick the wrong events; else the whole file is searched.
    """
    lo, hi = narrowed
    if not ((lo == 0 or time_at(lo - 1) < target) and (hi >= n or time_at(hi) >= target)):
        lo, hi = 0, n
    while lo < hi:
        mid = (lo + hi) // 2
        if time_at(mid) < target:
            lo = mid + 1
        else:
            hi = mid
    return lo
