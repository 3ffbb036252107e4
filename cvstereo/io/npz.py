"""The stereo recording ``.npz`` and the matches ``.npz`` of docs/formats.md.

Recordings are read either whole (:func:`read_recording_npz`) or in chunks straight out of the zip
archive (:func:`iter_npz_chunks`), so that a recording larger than memory streams with bounded memory.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.io.atomic import atomic_path
from cvstereo.io.files import require_regular_file
from cvstereo.matchers.protocol import MAX_PARAM_INT
from cvstereo.model.events import DEFAULT_RESOLUTION, as_events, check_resolution
from cvstereo.model.matches import REQUIRED_META, MatchResult, validate_matches
from cvstereo.model.recording import Recording

__all__ = ["iter_npz_chunks", "npz_keys", "read_matches", "read_npz_header", "read_recording_npz", "write_matches",
           "write_recording_npz"]


def _meta_array(meta: dict) -> np.ndarray:
    return np.array(json.dumps(meta, sort_keys=True, default=_json_default))


def _json_default(obj):
    # numpy scalars and arrays appear in params and rig descriptions; store them as plain JSON.
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"meta value {obj!r} of type {type(obj).__name__} cannot be stored as JSON.")


def _open_npz(path: str | os.PathLike):
    path = require_regular_file(path)
    if not zipfile.is_zipfile(path):
        # Checked first because np.load leaks its file handle when the zip directory is unreadable.
        raise CorruptFileError(f"{path}: not a readable .npz archive (no zip directory: truncated or not an .npz).")
    try:
        return np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise CorruptFileError(f"{path}: not a readable .npz archive ({exc}).") from None


#: What reading a damaged member raises: zlib (bad deflate data), zipfile (bad CRC), numpy (short data).
_MEMBER_ERRORS = (zlib.error, zipfile.BadZipFile, EOFError, OSError, ValueError)
#: Deflate cannot expand more than 1032:1; a zip entry claiming more lies (or is a zip bomb).
_MAX_DEFLATE_RATIO = 1032


class _Member:
    """One ``.npy`` member of an archive, its header checked against the member's size before any read.

    A header is only a claim: one declaring 10**15 rows would make numpy allocate petabytes, one holding
    pickled objects would need unpickling. Both are refused here, as is a zip entry that claims to inflate
    beyond what deflate can; so reading allocates at most about 1000 times the file's size.
    """

    def __init__(self, zf: zipfile.ZipFile, path, key: str):
        self.path, self.key = path, key
        name = key + ".npy"
        try:
            info = zf.getinfo(name)
        except KeyError:
            raise CorruptFileError(f"{path}: no key '{key}' in the archive (found {', '.join(zf.namelist())}).") \
                from None
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise self._error(f"uses zip compression method {info.compress_type}; .npz files are stored or deflated")
        limit = info.compress_size * (1 if info.compress_type == zipfile.ZIP_STORED else _MAX_DEFLATE_RATIO) + 64
        if info.file_size > limit:
            raise self._error(f"claims to inflate to {info.file_size} bytes from {info.compress_size}, more than "
                              "its compression can give")
        self._fh = None
        try:
            self._fh = zf.open(info)
            version = np.lib.format.read_magic(self._fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(self._fh)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(self._fh)
            else:
                raise ValueError(f".npy version {version[0]}.{version[1]} is not read here")
            data_bytes = info.file_size - self._fh.tell()
        except _MEMBER_ERRORS as exc:
            self.close()
            raise self._error(f"has a broken .npy header ({_reason(exc)})") from None
        if dtype.hasobject:
            self.close()
            raise self._error("holds Python objects (a pickled object array), which are never unpickled here; "
                              "it must hold plain numbers")
        self.shape, self.fortran, self.dtype = shape, fortran, dtype
        self.rows = math.prod(shape)
        declared = self.rows * dtype.itemsize
        if declared != data_bytes:
            self.close()
            raise self._error(f"declares shape {_brief(shape)} of {dtype.str} ({declared} bytes) but holds "
                              f"{data_bytes} bytes of data")

    def _error(self, what: str) -> CorruptFileError:
        return CorruptFileError(f"{self.path}: key '{self.key}' {what}; the file is damaged or was not written "
                                "as a cvstereo .npz.")

    def read_rows(self, n: int) -> np.ndarray:
        """The next ``n`` elements (in storage order) as a writable 1-D array."""
        out = np.empty(n, self.dtype)
        raw, done = out.view(np.uint8) if out.size else np.empty(0, np.uint8), 0
        try:
            while done < raw.size:
                chunk = self._fh.read(min(1 << 22, raw.size - done))
                if not chunk:
                    raise EOFError(f"ends after {done} of {raw.size} bytes")
                raw[done: done + len(chunk)] = np.frombuffer(chunk, np.uint8)
                done += len(chunk)
        except _MEMBER_ERRORS as exc:
            raise self._error(f"is corrupt and cannot be read ({_reason(exc)})") from None
        return out

    def read(self) -> np.ndarray:
        """The whole array."""
        flat = self.read_rows(self.rows)
        if self.fortran:
            return flat.reshape(self.shape[::-1]).transpose()
        return flat.reshape(self.shape)

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _reason(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if isinstance(exc, zlib.error | zipfile.BadZipFile) else str(exc)


def _brief(shape: tuple) -> str:
    text = str(shape)
    return text if len(text) <= 40 else text[:37] + "..."


def _load(npz, path, key: str) -> np.ndarray:
    """Array ``key`` of an open archive (:func:`_open_npz`), read through the checks of :class:`_Member`."""
    with _Member(npz.zip, path, key) as member:
        return member.read()


def _read_meta(npz, path) -> dict:
    if "meta" not in npz.files:
        return {}
    try:
        meta = json.loads(str(_load(npz, path, "meta")[()]))
    except (json.JSONDecodeError, ValueError) as exc:
        if isinstance(exc, CorruptFileError):
            raise
        raise CorruptFileError(f"{path}: key 'meta' is not a JSON object ({exc}).") from None
    if not isinstance(meta, dict):
        raise CorruptFileError(f"{path}: key 'meta' holds JSON {type(meta).__name__}, expected an object.")
    return meta


def _read_resolution(npz, path) -> tuple[int, int]:
    if "resolution" not in npz.files:
        return DEFAULT_RESOLUTION
    res = _load(npz, path, "resolution").ravel()
    if res.size != 2 or res.dtype.kind not in "iu":
        raise CorruptFileError(f"{path}: key 'resolution' must be two positive integers [width, height], "
                               f"got {_brief(res.tolist())}.")
    return check_resolution(tuple(int(v) for v in res), source=f"{path}: key 'resolution'", error=CorruptFileError)


def _require_recording_keys(npz, path) -> None:
    missing = [k for k in ("left", "right") if k not in npz.files]
    if not missing:
        return
    if "matches" in npz.files:
        raise CorruptFileError(f"{path}: is a matches file (written by `cvstereo match`), not a recording; "
                               "give the recording the matches were computed on.")
    raise CorruptFileError(
        f"{path}: missing key(s) {', '.join(missing)}; a stereo recording holds 'left' and 'right' "
        f"(found {', '.join(npz.files) or 'nothing'})."
    )


def write_recording_npz(path: str | os.PathLike, recording: Recording) -> None:
    """Write a :class:`~cvstereo.model.recording.Recording` as a stereo recording ``.npz`` (atomically).

    Parameters
    ----------
    path : path-like
        Output file; replaced only once it is complete.
    recording : Recording
    """
    arrays = {
        "left": recording.left,
        "right": recording.right,
        "resolution": np.asarray(recording.resolution, dtype=np.int64),
        "meta": _meta_array(recording.meta),
    }
    if recording.has_truth:
        arrays["left_disparity"] = recording.left_disparity.astype(np.float32)
        arrays["right_disparity"] = recording.right_disparity.astype(np.float32)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def read_recording_npz(path: str | os.PathLike) -> Recording:
    """Read a stereo recording ``.npz`` whole.

    Raises
    ------
    FileNotFoundError, CorruptFileError, EventFormatError
    """
    with _open_npz(path) as npz:
        _require_recording_keys(npz, path)
        resolution = _read_resolution(npz, path)
        meta = _read_meta(npz, path)
        cams = {}
        for cam in ("left", "right"):
            events = _load(npz, path, cam)
            try:
                cams[cam] = as_events(events, resolution=resolution, source=f"{path} [{cam}]")
            except ValueError as exc:
                if isinstance(exc, EventFormatError):
                    raise
                raise CorruptFileError(f"{path}: key '{cam}' cannot be read ({exc}).") from None
            truth_key = f"{cam}_disparity"
            cams[truth_key] = _read_truth(npz, path, truth_key) if truth_key in npz.files else None
        try:
            return Recording(resolution=resolution, meta=meta, **cams)
        except EventFormatError as exc:
            raise EventFormatError(f"{path}: {exc}") from None


def _read_truth(npz, path, key: str) -> np.ndarray:
    truth = _load(npz, path, key)
    if truth.dtype.kind not in "fiu":
        raise CorruptFileError(f"{path}: key '{key}' has dtype {truth.dtype}; ground truth is float disparities.")
    return truth.astype(np.float32, copy=False)


def iter_npz_chunks(path: str | os.PathLike, key: str, chunk_rows: int = 1 << 16) -> Iterator[np.ndarray]:
    """Stream one array of an ``.npz`` in chunks of rows, without loading it whole.

    Parameters
    ----------
    path : path-like
    key : str
        Array name inside the archive (``"left"``, ``"right_disparity"``, ...).
    chunk_rows : int
        Rows per chunk.

    Yields
    ------
    ndarray
        Consecutive slices of the stored 1-D array.
    """
    path = require_regular_file(path)
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise CorruptFileError(f"{path}: not a readable .npz archive ({exc}).") from None
    with zf, _Member(zf, path, key) as member:
        if len(member.shape) != 1:
            raise CorruptFileError(f"{path}: key '{key}' must be a 1-D array of plain values, "
                                   f"got shape {_brief(member.shape)}.")
        total, done = member.rows, 0
        while done < total:
            n = min(chunk_rows, total - done)
            yield member.read_rows(n)
            done += n


def npz_keys(path: str | os.PathLike) -> list[str]:
    """Array names in an ``.npz`` without reading them."""
    with _open_npz(path) as npz:
        return list(npz.files)


def read_npz_header(path: str | os.PathLike) -> tuple[tuple[int, int], dict, bool]:
    """Resolution, meta and whether ground truth is present, without reading the event arrays."""
    with _open_npz(path) as npz:
        _require_recording_keys(npz, path)
        has_truth = "left_disparity" in npz.files and "right_disparity" in npz.files
        return _read_resolution(npz, path), _read_meta(npz, path), has_truth


def write_matches(path: str | os.PathLike, matches: np.ndarray, meta: dict, *, arrays: dict | None = None) -> None:
    """Write a matches ``.npz`` (docs/formats.md), atomically.

    Parameters
    ----------
    path : path-like
    matches : (N,) ndarray of MATCH_DTYPE
        Time-ordered.
    meta : dict
        Must hold at least method, variant, params, anchor, window_us.
    arrays : dict of str to array_like, optional, keyword-only
        Optional per-match arrays (e.g. ``depth_m``), one value per match; stored as float32 under their name.
    """
    validate_matches(matches, source=str(path))
    missing = [k for k in REQUIRED_META if k not in meta]
    if missing:
        raise ValueError(f"matches meta lacks {', '.join(missing)} (docs/formats.md lists the required keys).")
    extra = {}
    for name, values in (arrays or {}).items():
        values = np.asarray(values, np.float32)
        if name in ("matches", "meta") or not name.isidentifier():
            raise ValueError(f"per-match array name {name!r} is reserved or not an identifier; use e.g. 'depth_m'.")
        if values.shape != matches.shape:
            raise ValueError(f"per-match array '{name}' has shape {values.shape}; it needs one value per match "
                             f"({matches.size}).")
        extra[name] = values
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, matches=matches, meta=_meta_array(meta), **extra)


def read_matches(path: str | os.PathLike) -> MatchResult:
    """Read a matches ``.npz``.

    Returns
    -------
    MatchResult

    Raises
    ------
    FileNotFoundError, CorruptFileError, EventFormatError
    """
    with _open_npz(path) as npz:
        if "matches" not in npz.files:
            raise CorruptFileError(
                f"{path}: no key 'matches'; is this a recording? Matches files are written by `cvstereo match`."
            )
        matches = _load(npz, path, "matches")
        meta = _read_meta(npz, path)
        # Optional per-match arrays (docs/formats.md); keys of another shape are not ours to interpret: ignored.
        arrays = {k: npz[k] for k in npz.files if k not in ("matches", "meta")}
    validate_matches(matches, source=str(path))
    arrays = {k: v.astype(np.float32) for k, v in arrays.items() if v.shape == matches.shape and v.dtype.kind == "f"}
    _check_window_us(meta.get("window_us"), path)
    return MatchResult(matches, meta, arrays)


def _check_window_us(value, path) -> None:
    # Every reader of matches does integer arithmetic with it (t // window_us): refuse what no matcher writes.
    if value is None:
        return
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not (ok and value == int(value) and 0 <= value <= MAX_PARAM_INT):
        raise CorruptFileError(f"{path}: meta 'window_us' is {_brief(repr(value))}; it must be a whole number of "
                               f"microseconds in 0..{MAX_PARAM_INT} (0 for event anchors).")
