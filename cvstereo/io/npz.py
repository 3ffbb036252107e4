"""The stereo recording ``.npz`` and the matches ``.npz`` of formats.md.

Recordings are read either whole (:func:`read_recording_npz`) or in chunks straight out of the zip
archive (:func:`iter_npz_chunks`), so that a recording larger than memory streams with bounded memory.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from cvstereo.errors import CorruptFileError, EventFormatError
from cvstereo.events import DEFAULT_RESOLUTION, as_events
from cvstereo.io._atomic import atomic_path
from cvstereo.matches import REQUIRED_META, MatchResult, validate_matches
from cvstereo.recording import Recording


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
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file.")
    if not zipfile.is_zipfile(path):
        # Checked first because np.load leaks its file handle when the zip directory is unreadable.
        raise CorruptFileError(f"{path}: not a readable .npz archive (no zip directory: truncated or not an .npz).")
    try:
        return np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise CorruptFileError(f"{path}: not a readable .npz archive ({exc}).") from None


def _read_meta(npz, path) -> dict:
    if "meta" not in npz.files:
        return {}
    try:
        meta = json.loads(str(npz["meta"][()]))
    except (json.JSONDecodeError, ValueError) as exc:
        raise CorruptFileError(f"{path}: key 'meta' is not a JSON object ({exc}).") from None
    if not isinstance(meta, dict):
        raise CorruptFileError(f"{path}: key 'meta' holds JSON {type(meta).__name__}, expected an object.")
    return meta


def _read_resolution(npz, path) -> tuple[int, int]:
    if "resolution" not in npz.files:
        return DEFAULT_RESOLUTION
    res = np.asarray(npz["resolution"]).ravel()
    if res.size != 2 or res.dtype.kind not in "iu" or (res <= 0).any():
        raise CorruptFileError(f"{path}: key 'resolution' must be two positive integers [width, height], got {res}.")
    return int(res[0]), int(res[1])


def write_recording_npz(path: str | os.PathLike, recording: Recording) -> None:
    """Write a :class:`~cvstereo.recording.Recording` as a stereo recording ``.npz`` (atomically).

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
        missing = [k for k in ("left", "right") if k not in npz.files]
        if missing:
            raise CorruptFileError(
                f"{path}: missing key(s) {', '.join(missing)}; a stereo recording holds 'left' and 'right' "
                f"(found {', '.join(npz.files) or 'nothing'})."
            )
        resolution = _read_resolution(npz, path)
        meta = _read_meta(npz, path)
        cams = {}
        for cam in ("left", "right"):
            try:
                cams[cam] = as_events(npz[cam], resolution=resolution, source=f"{path} [{cam}]")
            except ValueError as exc:
                if isinstance(exc, EventFormatError):
                    raise
                raise CorruptFileError(f"{path}: key '{cam}' cannot be read ({exc}).") from None
            truth_key = f"{cam}_disparity"
            cams[truth_key] = np.asarray(npz[truth_key], np.float32) if truth_key in npz.files else None
        try:
            return Recording(resolution=resolution, meta=meta, **cams)
        except EventFormatError as exc:
            raise EventFormatError(f"{path}: {exc}") from None


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
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file.")
    try:
        zf = zipfile.ZipFile(path)
    except zipfile.BadZipFile as exc:
        raise CorruptFileError(f"{path}: not a readable .npz archive ({exc}).") from None
    with zf, _open_member(zf, path, key) as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, _fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, _fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        except ValueError as exc:
            raise CorruptFileError(f"{path}: key '{key}' has a broken .npy header ({exc}).") from None
        if len(shape) != 1 or dtype.hasobject:
            raise CorruptFileError(f"{path}: key '{key}' must be a 1-D array of plain values, got shape {shape}.")
        total, done = shape[0], 0
        while done < total:
            n = min(chunk_rows, total - done)
            buf = fh.read(n * dtype.itemsize)
            if len(buf) != n * dtype.itemsize:
                raise CorruptFileError(
                    f"{path}: key '{key}' is truncated at row {done + len(buf) // dtype.itemsize} of {total}."
                )
            yield np.frombuffer(buf, dtype=dtype).copy()
            done += n


def _open_member(zf: zipfile.ZipFile, path, key: str):
    name = key + ".npy"
    if name not in zf.namelist():
        raise CorruptFileError(f"{path}: no key '{key}' in the archive (found {', '.join(zf.namelist())}).")
    return zf.open(name)


def npz_keys(path: str | os.PathLike) -> list[str]:
    """Array names in an ``.npz`` without reading them."""
    with _open_npz(path) as npz:
        return list(npz.files)


def read_npz_header(path: str | os.PathLike) -> tuple[tuple[int, int], dict, bool]:
    """Resolution, meta and whether ground truth is present, without reading the event arrays."""
    with _open_npz(path) as npz:
        for cam in ("left", "right"):
            if cam not in npz.files:
                raise CorruptFileError(f"{path}: missing key '{cam}'; not a stereo recording.")
        has_truth = "left_disparity" in npz.files and "right_disparity" in npz.files
        return _read_resolution(npz, path), _read_meta(npz, path), has_truth


def write_matches(path: str | os.PathLike, matches: np.ndarray, meta: dict, *, arrays: dict | None = None) -> None:
    """Write a matches ``.npz`` (formats.md), atomically.

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
        raise ValueError(f"matches meta lacks {', '.join(missing)} (formats.md lists the required keys).")
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
        matches = npz["matches"]
        meta = _read_meta(npz, path)
        # Optional per-match arrays (formats.md); keys of another shape are not ours to interpret: ignored.
        arrays = {k: npz[k] for k in npz.files if k not in ("matches", "meta")}
    validate_matches(matches, source=str(path))
    arrays = {k: v.astype(np.float32) for k, v in arrays.items() if v.shape == matches.shape and v.dtype.kind == "f"}
    return MatchResult(matches, meta, arrays)
